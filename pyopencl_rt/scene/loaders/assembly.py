"""What every loader does with the triangles it read: drop the faces that touch non-finite
vertices (keeping their materials and UVs aligned), build the Scene, and frame it with a camera
when the file has none."""
from __future__ import annotations

import math
import warnings

import numpy as np

from ..mesh import check_triangles
from ..model import Camera, Material, Scene

DEFAULT_FOV = 40.0


def _finite_faces(vertices, faces) -> np.ndarray:
    """Which faces check_triangles keeps: those whose vertices are finite in float32."""
    with np.errstate(over="ignore", invalid="ignore"):
        finite = np.isfinite(np.asarray(vertices, np.float64).astype(np.float32)).all(axis=1)
    return finite[faces].all(axis=1) if len(faces) else np.zeros(0, bool)


def kept_uvs(vertices, faces, uvs):
    """uvs (F, 3, 2) of the faces that checked_triangles keeps, or None."""
    if uvs is None:
        return None
    keep = _finite_faces(vertices, np.asarray(faces, np.int64))
    return np.ascontiguousarray(np.asarray(uvs, np.float32)[keep])


def checked_triangles(vertices, faces, face_materials, name):
    """check_triangles, keeping face_materials aligned with the faces it may drop."""
    faces = np.asarray(faces, np.int64)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        v32, f32 = check_triangles(vertices, faces, name)
    for w in caught:
        warnings.warn(w.message, stacklevel=3)
    face_materials = np.asarray(face_materials, np.int32)
    if len(f32) != len(faces):
        face_materials = face_materials[_finite_faces(vertices, faces)]
    return v32, f32, np.ascontiguousarray(face_materials)


def triangle_scene(vertices, faces, face_materials, materials, name, uvs=None, face_interfaces=None,
                   **scene_fields) -> Scene:
    """The Scene of these triangles (checked) with their materials (the default one if there are
    none), per-corner UVs and medium interfaces (per face, or None); no camera yet."""
    uvs = kept_uvs(vertices, faces, uvs)
    if face_interfaces is not None:
        keep = _finite_faces(vertices, np.asarray(faces, np.int64))
        face_interfaces = np.ascontiguousarray(np.asarray(face_interfaces, np.int32)[keep])
    v32, f32, face_materials = checked_triangles(vertices, faces, face_materials, name)
    return Scene(vertices=v32, faces=f32, face_materials=face_materials, materials=materials or [Material()],
                 source=name, uvs=uvs, face_interfaces=face_interfaces, **scene_fields)


def scene_bounds(scene: Scene):
    """(lo, hi) corners of the box around the scene's used vertices and its spheres."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    if len(scene.faces):
        used = scene.vertices[np.unique(scene.faces)].astype(np.float64)
        lo = np.minimum(lo, used.min(axis=0))
        hi = np.maximum(hi, used.max(axis=0))
    if len(scene.spheres):
        s = scene.spheres.astype(np.float64)
        lo = np.minimum(lo, (s[:, :3] - s[:, 3:4]).min(axis=0))
        hi = np.maximum(hi, (s[:, :3] + s[:, 3:4]).max(axis=0))
    if not np.isfinite(lo).all():
        lo = hi = np.zeros(3)
    return lo, hi


def framing_camera(lo, hi, width: int = 512, height: int = 512, fov: float = DEFAULT_FOV) -> Camera:
    """A camera looking along -z at the centre of the box [lo, hi], far enough back that the
    box's bounding sphere fits the narrower of the vertical and horizontal fields of view."""
    lo = np.asarray(lo, np.float64)
    hi = np.asarray(hi, np.float64)
    centre = (lo + hi) / 2
    radius = float(np.linalg.norm(hi - lo)) / 2
    if not radius > 0:
        radius = 1.0
    half_v = math.radians(fov) / 2
    half_h = math.atan(math.tan(half_v) * width / height)
    half = min(half_v, half_h)
    distance = 1.05 * radius / math.sin(half)
    eye = centre + np.array([0.0, 0.0, distance])
    return Camera(
        eye=tuple(float(x) for x in eye), look_at=tuple(float(x) for x in centre),
        up=(0.0, 1.0, 0.0), fov=float(fov),
    )


def frame_scene(scene: Scene) -> Scene:
    """Give the scene the framing camera for its settings' image size; returns it."""
    scene.camera = framing_camera(*scene_bounds(scene), scene.settings.width, scene.settings.height)
    return scene
