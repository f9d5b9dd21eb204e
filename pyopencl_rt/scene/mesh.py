"""Meshes in, float32 triangle arrays out.

Anything trimesh loads (OBJ, PLY, STL, glTF/GLB, ...) is flattened into one vertex array and one
face array with every node's world transform applied.  Bad geometry is dealt with here, once,
so neither the BVH builder nor the kernels ever see a non-finite coordinate.
"""
from __future__ import annotations

import warnings
from pathlib import Path

import numpy as np

from ..errors import UserError


class MeshError(UserError):
    pass


def load_trimesh(path):
    """``trimesh.load`` with errors turned into one-line :class:`MeshError`s."""
    import trimesh

    p = Path(path)
    if not p.exists():
        raise MeshError(f"{path}: no such file")
    if p.is_dir():
        raise MeshError(f"{path}: is a folder, not a mesh file")
    _reject_binary_text_format(p)
    try:
        # a coordinate beyond float32 (a PLY "float" of 1e39) becomes inf here, silently: the
        # non-finite vertices are reported by check_triangles, naming the file
        with np.errstate(over="ignore", invalid="ignore"):
            loaded = trimesh.load(str(p), process=False)
    except Exception as exc:  # trimesh raises many types for malformed input
        raise MeshError(f"{path}: cannot read mesh ({type(exc).__name__}: {exc})") from None
    return loaded


_TEXT_FORMATS = {".obj", ".off", ".mtl"}


def _reject_binary_text_format(p: Path) -> None:
    """trimesh decodes any bytes as text (through charset_normalizer when installed), so a
    corrupt OBJ loads as an empty mesh instead of failing: check text formats ourselves."""
    ext = p.suffix.lower()
    if ext not in _TEXT_FORMATS and ext != ".stl":
        return
    head = p.read_bytes()[:65536]
    if ext == ".stl":
        # binary STL: 80-byte header, uint32 count, 50 bytes per triangle
        size = p.stat().st_size
        if size >= 84 and 84 + 50 * int.from_bytes(p.read_bytes()[80:84], "little") == size:
            return
        if head.lstrip().lower().startswith(b"solid"):
            return
        raise MeshError(f"{p}: not a valid STL file (neither ASCII 'solid' nor a consistent binary header)")
    if b"\0" in head:
        raise MeshError(f"{p}: not a valid {ext} file (binary data)")
    try:
        head.decode("utf-8")
    except UnicodeDecodeError as exc:
        if exc.start < len(head) - 4:  # not merely a multi-byte character cut at the end
            raise MeshError(f"{p}: not a valid {ext} file (not UTF-8 text)") from None


def flatten(geometry, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """(vertices float32 (V,3), faces int32 (F,3)) of a trimesh mesh/scene or a (vertices, faces) pair."""
    import trimesh

    if isinstance(geometry, trimesh.Scene):
        parts = []
        for node_name in geometry.graph.nodes_geometry:
            transform, geom_name = geometry.graph[node_name]
            geom = geometry.geometry[geom_name]
            if not isinstance(geom, trimesh.Trimesh) or len(geom.faces) == 0:
                continue
            v = np.asarray(geom.vertices, dtype=np.float64)
            v = v @ transform[:3, :3].T + transform[:3, 3]
            parts.append((v, np.asarray(geom.faces, dtype=np.int64)))
        return _concatenate(parts, name)
    if isinstance(geometry, trimesh.Trimesh):
        return check_triangles(geometry.vertices, geometry.faces, name)
    if isinstance(geometry, (tuple, list)) and len(geometry) == 2:
        return check_triangles(geometry[0], geometry[1], name)
    raise MeshError(f"{name}: expected a trimesh mesh or scene, or a (vertices, faces) pair, got {type(geometry).__name__}")


def _concatenate(parts, name):
    if not parts:
        return check_triangles(np.zeros((0, 3)), np.zeros((0, 3), np.int64), name)
    offsets = np.cumsum([0] + [len(v) for v, _ in parts[:-1]])
    vertices = np.concatenate([v for v, _ in parts])
    faces = np.concatenate([f + o for (_, f), o in zip(parts, offsets)])
    return check_triangles(vertices, faces, name)


def check_triangles(vertices, faces, name: str = "mesh") -> tuple[np.ndarray, np.ndarray]:
    """Validate and convert; faces touching a non-finite vertex are dropped with a warning."""
    vertices = np.asarray(vertices)
    faces = np.asarray(faces)
    if vertices.ndim != 2 or vertices.shape[1] != 3 or not np.issubdtype(vertices.dtype, np.number):
        raise MeshError(f"{name}: vertices must be an (N, 3) array of numbers, got shape {vertices.shape}")
    if faces.ndim != 2 or faces.shape[1] != 3 or (faces.size and not np.issubdtype(faces.dtype, np.integer)):
        raise MeshError(f"{name}: faces must be an (M, 3) array of integer indices, got shape {faces.shape}")
    faces = faces.astype(np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        bad = int(np.count_nonzero((faces < 0) | (faces >= len(vertices))))
        raise MeshError(f"{name}: {bad} face indices out of range [0, {len(vertices)})")
    with np.errstate(over="ignore", invalid="ignore"):
        v32 = vertices.astype(np.float32)
    finite_vertex = np.isfinite(v32).all(axis=1)
    if not finite_vertex.all():
        bad_faces = ~finite_vertex[faces].all(axis=1) if faces.size else np.zeros(0, bool)
        n_bad_v = int(np.count_nonzero(~finite_vertex))
        n_bad_f = int(np.count_nonzero(bad_faces))
        warnings.warn(
            f"{name}: {n_bad_v} vertices are NaN/Inf (or overflow float32); dropped the {n_bad_f} faces that use them",
            stacklevel=2,
        )
        faces = faces[~bad_faces]
        v32 = np.where(finite_vertex[:, None], v32, 0.0).astype(np.float32)
    return np.ascontiguousarray(v32), np.ascontiguousarray(faces.astype(np.int32))


def load_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of every mesh in ``path``, world transforms applied."""
    return flatten(load_trimesh(path), name=str(path))
