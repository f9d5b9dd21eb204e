"""Any other mesh file trimesh reads (PLY, STL, OFF, ...): one default diffuse material
(albedo 0.8) and the framing camera.  A PLY file's vertex normals (nx, ny, nz) shade it
smoothly; its vertex colours (red, green, blue or r, g, b; integers scaled by their type's
maximum) become the default material's albedo."""
from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ..mesh import flatten, load_trimesh
from ..model import Material
from .assembly import frame_scene, triangle_scene
from .values import SceneError


def load_mesh_scene(path: Path, name: str):
    loaded = load_trimesh(path)
    vertices, faces = flatten(loaded, name=name)
    if len(faces) == 0:
        raise SceneError(f"{name}: contains no triangles")
    extras = ply_extras(loaded, faces)
    colors = extras.colors()
    materials = [Material(albedo=(1.0, 1.0, 1.0), vertex_colors=True)] if colors is not None else []
    return frame_scene(triangle_scene(vertices, faces, np.zeros(len(faces), np.int32), materials, name,
                                      trimesh_uvs(loaded, vertices, faces), normals=extras.normals, colors=colors))


@dataclass
class MeshExtras:
    """What a mesh file holds beside positions and UVs, per corner of its triangles: ``normals``
    (F, 3, 3) or None, and ``attributes``: {name: (F, 3, C)} named as Mitsuba names a PLY file's
    attributes (``vertex_color``, ``face_color``, ``vertex_<prefix>``, ``face_<prefix>``)."""

    normals: np.ndarray | None = None
    attributes: dict = field(default_factory=dict)

    def colors(self, name: str | None = None):
        """(F, 3, 3) linear RGB of attribute ``name`` (default: vertex_color, else face_color), or
        None; a 1-channel attribute is grey."""
        for key in ((name,) if name else ("vertex_color", "face_color")):
            a = self.attributes.get(key)
            if a is not None:
                return np.repeat(a[..., :1], 3, axis=2) if a.shape[2] == 1 else a[..., :3]
        return None


_PLY_SKIP = {"x", "y", "z", "nx", "ny", "nz", "u", "v", "s", "t", "texture_u", "texture_v", "texture_s",
             "texture_t", "vertex_indices", "vertex_index"}
_POSTFIXES = ("xyzw", "rgba", "0123", "1234")


def _ply_attributes(data, element: str) -> dict:
    """{name: (N, C) float} of a PLY element's other properties, grouped and named as Mitsuba's
    PLY reader does (src/shapes/ply.h: r/g/b or red/green/blue is "<element>_color"; consecutive
    "<prefix>_<x|y|z>", "_<r|g|b>" (then "<prefix>_color"), "_<0|1|2>", "_<1|2|3>" fields are one
    attribute "<element>_<prefix>"; 1 or 3 fields).  Integer colours are scaled to [0, 1]."""
    names = [n for n in data.dtype.names if n not in _PLY_SKIP and data.dtype[n].shape == ()]

    def column(n):
        a = np.asarray(data[n])
        return a.astype(np.float64) / np.iinfo(a.dtype).max if a.dtype.kind in "iu" else a.astype(np.float64)

    out = {}
    for group in (("r", "g", "b"), ("red", "green", "blue")):
        if all(g in names for g in group):
            out[f"{element}_color"] = np.stack([column(g) for g in group], 1)
            names = [n for n in names if n not in group + ("a", "alpha")]
            break
    i = 0
    while i < len(names):
        prefix, _, post = names[i].rpartition("_")
        cat = next((c for c in _POSTFIXES if post == c[0]), None)
        if not prefix or cat is None:
            i += 1
            continue
        fields = [names[i]]
        while len(fields) < 4 and i + len(fields) < len(names) and names[i + len(fields)] == f"{prefix}_{cat[len(fields)]}":
            fields.append(names[i + len(fields)])
        i += len(fields)
        if len(fields) == 4:
            fields = fields[:3]
        if len(fields) not in (1, 3):
            continue
        suffix = "_color" if cat == "rgba" else ""
        out[f"{element}_{prefix}{suffix}"] = np.stack([column(n) for n in fields], 1)
    return out


def ply_extras(loaded, faces) -> MeshExtras:
    """The vertex normals and attributes of a PLY file as trimesh read it (its ``_ply_raw``), per
    corner of ``faces`` (flatten()'s, which must be trimesh's triangles: polygons fan-split, face
    attributes repeated over their triangles); empty for another format or faces that differ."""
    raw = getattr(loaded, "metadata", {}).get("_ply_raw") if hasattr(loaded, "metadata") else None
    extras = MeshExtras()
    try:
        if raw is None or "vertex" not in raw or len(loaded.faces) != len(faces):
            return extras
        f = np.asarray(faces)       # an index array as it is (an int64 copy cost 24 bytes a triangle)
        vdata = raw["vertex"]["data"]
        if len(vdata) != len(loaded.vertices):
            return extras
        if all(n in vdata.dtype.names for n in ("nx", "ny", "nz")):
            n = np.stack([np.asarray(vdata[c], np.float64) for c in ("nx", "ny", "nz")], 1)
            with np.errstate(invalid="ignore", divide="ignore"):
                n = n / np.linalg.norm(n, axis=1, keepdims=True)
            extras.normals = np.nan_to_num(n, nan=0.0, posinf=0.0, neginf=0.0)[f].astype(np.float32)
        for name, a in _ply_attributes(vdata, "vertex").items():
            extras.attributes[name] = a[f].astype(np.float32)
        if "face" in raw:
            fdata = raw["face"]["data"]
            per_face = _ply_attributes(fdata, "face")
            if per_face:
                counts = _face_sizes(fdata)
                tris = np.maximum(counts - 2, 0)
                if tris.sum() == len(f):
                    for name, a in per_face.items():
                        extras.attributes[name] = np.repeat(np.repeat(a, tris, axis=0)[:, None], 3, axis=1).astype(
                            np.float32)
    except (KeyError, TypeError, ValueError, IndexError, AttributeError):
        return MeshExtras()
    return extras


def _face_sizes(fdata) -> np.ndarray:
    """Corners of each PLY face (its vertex_indices list)."""
    name = "vertex_indices" if "vertex_indices" in fdata.dtype.names else "vertex_index"
    col = fdata[name]
    if col.dtype.names:  # trimesh's (count, indices) record of fixed-length lists
        return np.asarray(col[col.dtype.names[0]], np.int64)
    return np.fromiter((len(x) for x in col), np.int64, count=len(col))


def trimesh_uvs(loaded, v, f):
    """Per-corner UVs (v flipped to the top-down convention) of a single trimesh mesh that
    carries them (e.g. a PLY with s/t or texture_u/v), if flatten() kept its faces as they were."""
    uv = getattr(getattr(loaded, "visual", None), "uv", None)
    try:
        if uv is None or len(uv) != len(loaded.vertices) or len(loaded.faces) != len(f):
            return None
        out = np.asarray(uv, np.float32)[np.asarray(loaded.faces)][..., :2].copy()
    except (AttributeError, TypeError, ValueError, IndexError):
        return None
    out[..., 1] = 1.0 - out[..., 1]
    return out
