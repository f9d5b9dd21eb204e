"""Meshes in, float32 triangle arrays out.

Anything trimesh loads (OBJ, PLY, STL, glTF/GLB, ...) is flattened into one vertex array and one
face array with every node's world transform applied.  Bad geometry is dealt with here, once,
so neither the BVH builder nor the kernels ever see a non-finite coordinate.
"""
from __future__ import annotations

import warnings
from pathlib import Path
from types import SimpleNamespace

import numpy as np

from ..device.host_memory import aligned, aligned_empty
from ..errors import UserError
from .meshops import finite_rows


class MeshError(UserError):
    pass


def load_trimesh(path):
    """``trimesh.load`` with errors turned into one-line :class:`MeshError`s; a binary PLY file
    of the common layouts is read straight into arrays instead (:func:`read_binary_ply`)."""
    p = Path(path)
    if not p.exists():
        raise MeshError(f"{path}: no such file")
    if p.is_dir():
        raise MeshError(f"{path}: is a folder, not a mesh file")
    from ..host_stages import host_stage

    with host_stage("mesh_read"):
        return _load_trimesh(p, path)


def _load_trimesh(p: Path, path):
    if p.suffix.lower() == ".ply":
        fast = read_binary_ply(p)
        if fast is not None:
            return fast
    _reject_binary_text_format(p)
    import trimesh
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
    """(vertices float32 (V,3), faces int32 (F,3)) of a trimesh mesh/scene, a :class:`PlyMesh` or a
    (vertices, faces) pair."""
    if isinstance(geometry, PlyMesh):
        return check_triangles(geometry.vertices, geometry.faces, name)
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
    if faces.dtype not in (np.int32, np.int64):
        faces = faces.astype(np.int64)
    if faces.size and (faces.min() < 0 or faces.max() >= len(vertices)):
        bad = int(np.count_nonzero((faces < 0) | (faces >= len(vertices))))
        raise MeshError(f"{name}: {bad} face indices out of range [0, {len(vertices)})")
    with np.errstate(over="ignore", invalid="ignore"):
        v32 = vertices.astype(np.float32, copy=False)  # float32 given: used as it is (nothing writes it)
    finite_vertex = finite_rows(v32)
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
    # page-aligned: a CPU device reads the scene's arrays in place (device/host_memory.py)
    return aligned(v32), aligned(np.ascontiguousarray(faces, np.int32))


def load_mesh(path) -> tuple[np.ndarray, np.ndarray]:
    """Vertices and faces of every mesh in ``path``, world transforms applied."""
    return flatten(load_trimesh(path), name=str(path))


# --------------------------------------------------------------------------------------------
# binary PLY, the common layouts, without trimesh

_PLY_TYPES = {"char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1", "short": "i2", "int16": "i2",
              "ushort": "u2", "uint16": "u2", "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
              "float": "f4", "float32": "f4", "double": "f8", "float64": "f8"}
# vertex properties that trimesh reads as texture coordinates, in pairs: one pair per vertex is
# read here as trimesh reads it (a file with more than one pair goes through trimesh)
_PLY_TEXCOORDS = ("texture_u", "texture_v", "u", "v", "s", "t")
_PLY_UV_PAIRS = (("texture_u", "texture_v"), ("u", "v"), ("s", "t"))


class PlyMesh:
    """A triangle mesh read from a binary PLY file by :func:`read_binary_ply`, with what the
    loaders use of a trimesh mesh: ``vertices`` (V, 3) as stored, ``faces`` (F, 3) int32,
    ``metadata["_ply_raw"]["vertex"]["data"]`` (the vertex records: normals and attributes,
    meshfile.ply_extras) and ``visual.uv``, the per-vertex texture coordinates (float64, as
    trimesh gives them), or no ``visual``."""

    def __init__(self, vertices, faces, vertex_data, uv=None):
        self.vertices = vertices
        self.faces = faces
        self.metadata = {"_ply_raw": {"vertex": {"data": vertex_data}}}
        self.visual = None if uv is None else SimpleNamespace(uv=uv)


def read_binary_ply(path) -> PlyMesh | None:
    """The mesh of a binary PLY file whose elements are ``vertex`` (scalar properties x, y, z, at
    most one pair of texture coordinates, any others) and ``face`` (one list property vertex_indices or
    vertex_index, every face a triangle), read with np.fromfile; None for anything else (ASCII,
    other elements or properties, polygons, a file shorter than its header says), which
    trimesh then reads.  The arrays are those trimesh gives (tests/scene/test_meshops.py)."""
    try:
        with open(path, "rb") as fh:
            if fh.read(4) != b"ply\n":
                return None
            header = [b"ply"]
            while True:
                line = fh.readline(4096)
                if not line or len(header) > 1000:
                    return None
                line = line.strip()
                header.append(line)
                if line == b"end_header":
                    break
            offset = fh.tell()
    except OSError:
        return None
    endian = None
    elements = []
    for raw in header[1:-1]:
        words = raw.decode("ascii", "replace").split()
        if not words or words[0] in ("comment", "obj_info"):
            continue
        if words[0] == "format" and len(words) == 3:
            endian = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(words[1])
        elif words[0] == "element" and len(words) == 3 and words[2].isdigit():
            elements.append((words[1], int(words[2]), []))
        elif words[0] == "property" and elements:
            elements[-1][2].append(words[1:])
        else:
            return None
    if endian is None or [e[0] for e in elements] != ["vertex", "face"]:
        return None
    (_, nv, vprops), (_, nf, fprops) = elements
    vfields = []
    for prop in vprops:
        if len(prop) != 2 or prop[0] not in _PLY_TYPES:
            return None
        vfields.append((prop[1], endian + _PLY_TYPES[prop[0]]))
    names = [n for n, _ in vfields]
    if len(set(names)) != len(names) or not {"x", "y", "z"} <= set(names):
        return None
    pairs = [pair for pair in _PLY_UV_PAIRS if set(pair) <= set(names)]
    if len(pairs) > 1 or sum(n in _PLY_TEXCOORDS for n in names) != 2 * len(pairs):
        return None
    if len(fprops) != 1 or len(fprops[0]) != 4 or fprops[0][0] != "list" \
            or fprops[0][3] not in ("vertex_indices", "vertex_index"):
        return None
    count_t, index_t = _PLY_TYPES.get(fprops[0][1]), _PLY_TYPES.get(fprops[0][2])
    if count_t is None or index_t is None or count_t[0] == "f" or index_t[0] == "f":
        return None
    vdtype = np.dtype(vfields)
    fdtype = np.dtype([("n", endian + count_t), ("i", endian + index_t, (3,))])
    size = Path(path).stat().st_size
    if size < offset + nv * vdtype.itemsize + nf * fdtype.itemsize:
        return None     # too short, or not all triangles: trimesh says what it makes of it
    vdata = np.fromfile(path, vdtype, count=nv, offset=offset)
    fdata = np.fromfile(path, fdtype, count=nf, offset=offset + nv * vdtype.itemsize)
    if len(vdata) != nv or len(fdata) != nf or (nf and not (fdata["n"] == 3).all()):
        return None
    if nf and index_t[0] == "u" and fdata["i"].max() > np.iinfo(np.int32).max:
        return None
    if vdtype["x"] == vdtype["y"] == vdtype["z"] and vdtype["x"].kind == "f":
        vertices = aligned_empty((nv, 3), vdtype["x"].newbyteorder("="))  # page-aligned: check_triangles
        for k, c in enumerate("xyz"):                                      # keeps float32 ones as they are
            vertices[:, k] = vdata[c]
    else:
        vertices = np.stack([vdata[c].astype(np.float64) for c in "xyz"], 1)
    faces = aligned_empty((nf, 3), np.int32)
    faces[...] = fdata["i"]
    del fdata
    uv = np.stack([vdata[c].astype(np.float64) for c in pairs[0]], 1) if pairs else None
    return PlyMesh(vertices, faces, vdata, uv)
