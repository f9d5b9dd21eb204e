"""Any other mesh file trimesh reads (PLY, STL, OFF, ...): one default diffuse material
(albedo 0.8) and the framing camera."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ..mesh import flatten, load_trimesh
from .assembly import frame_scene, triangle_scene
from .values import SceneError


def load_mesh_scene(path: Path, name: str):
    vertices, faces = flatten(load_trimesh(path), name=name)
    if len(faces) == 0:
        raise SceneError(f"{name}: contains no triangles")
    return frame_scene(triangle_scene(vertices, faces, np.zeros(len(faces), np.int32), [], name))


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
