"""What every loader does with the triangles it read: drop the faces that touch non-finite
vertices (keeping their materials, UVs, normals and colours aligned), build the Scene, and frame
it with a camera when the file has none; and the vertex normals Mitsuba computes for a mesh
file without them (:func:`angle_weighted_normals`)."""
from __future__ import annotations

import math
import warnings

import numpy as np

from ...device.host_memory import aligned_empty
from ...host_stages import host_stage
from .. import meshops
from ..instances import instance_bounds, n_world_faces
from ..meshops import finite_faces
from ..mesh import check_triangles
from ..model import Camera, Material, Scene
from ..shapes import bounds as shape_bounds

DEFAULT_FOV = 40.0


def _finite_faces(vertices, faces) -> np.ndarray:
    """Which faces check_triangles keeps: those whose vertices are finite in float32."""
    return finite_faces(vertices, faces)


def kept_per_face(values, keep, dtype, shape=(), copy: bool = False):
    """``values`` per face (each of ``shape``: (3, 2) uvs, (3, 3) normals or colours, () an index)
    of the faces that checked_triangles keeps (the mask ``keep``), or None; ``values`` itself
    (as ``dtype``, contiguous) when every face is kept, unless ``copy``."""
    if values is None:
        return None
    values = np.asarray(values, dtype).reshape(-1, *shape)
    if keep.all():
        return np.array(values, order="C", copy=True) if copy else np.ascontiguousarray(values)
    return np.ascontiguousarray(values[keep])


def stacked_per_face(parts, faces, shape, fill) -> np.ndarray:
    """The per-face arrays ``parts`` (one per mesh, None: ``fill`` for each of its faces; a
    :class:`PendingNormals`: computed in place) in one float32 (F, *shape) array, written once
    (np.concatenate of the parts and placeholders)."""
    # zeros from calloc: the pages of the meshes without such values are never written; page-aligned,
    # so a CPU device reads the normals in place (device/host_memory.py)
    out = aligned_empty((sum(len(f) for f in faces), *shape), np.float32, zeros=fill == 0)
    at = 0
    for part, f in zip(parts, faces):
        n = len(f)
        if part is None:
            if fill != 0:
                out[at:at + n] = fill
        elif isinstance(part, PendingNormals):
            part.write_into(out[at:at + n])
        else:
            out[at:at + n] = np.asarray(part).reshape(n, *shape)
        at += n
    return out


def checked_triangles(vertices, faces, face_materials, name):
    """check_triangles, keeping face_materials aligned with the faces it may drop."""
    faces = np.asarray(faces)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        v32, f32 = check_triangles(vertices, faces, name)
    for w in caught:
        warnings.warn(w.message, stacklevel=3)
    face_materials = np.asarray(face_materials, np.int32)
    if len(f32) != len(faces):
        face_materials = face_materials[_finite_faces(vertices, faces)]
    return v32, f32, np.ascontiguousarray(face_materials)


def triangle_scene(vertices, faces, face_materials, materials, name, uvs=None, normals=None, colors=None,
                   face_interfaces=None, face_emitters=None, own_normals=False, **scene_fields) -> Scene:
    """The Scene of these triangles (checked) with their materials (the default one if there are
    none), per-corner UVs, shading normals and colours, and medium interfaces (per face, or None);
    no camera yet.  ``own_normals``: ``normals`` is the caller's to give away (it may be changed
    in place and kept, not copied)."""
    keep = _finite_faces(vertices, faces)
    uvs = kept_per_face(uvs, keep, np.float32, (3, 2))
    normals = kept_per_face(normals, keep, np.float32, (3, 3), copy=not own_normals)  # ours: made flat in place
    colors = kept_per_face(colors, keep, np.float32, (3, 3))
    face_interfaces = kept_per_face(face_interfaces, keep, np.int32)
    face_emitters = kept_per_face(face_emitters, keep, np.int32)
    v32, f32, face_materials = checked_triangles(vertices, faces, face_materials, name)
    return Scene(vertices=v32, faces=f32, face_materials=face_materials, materials=materials or [Material()],
                 source=name, uvs=uvs, normals=flat_where_planar(v32, f32, normals, inplace=True), colors=colors,
                 face_interfaces=face_interfaces, face_emitters=face_emitters, **scene_fields)


def flat_where_planar(vertices, faces, normals, tolerance: float = 1e-5, inplace: bool = False):
    """``normals`` with the faces whose three corner normals are their geometric normal (within
    ``tolerance``) set to 0, flat: they shade the same, and a scene of such faces only (a box of
    planar quads, whose vertex normals Mitsuba computes) compiles no shading normals.  None when
    no face is left with normals.  ``inplace``: a float32 C-contiguous ``normals`` is changed in
    place, not copied (one parallel pass: scene/meshops.py)."""
    with host_stage("normals"):
        return meshops.flat_where_planar(vertices, faces, normals, tolerance, inplace=inplace)


def transform_normals(matrix, normals, unit: bool = True):
    """Per-corner normals (F, 3, 3) moved by the 4x4 ``matrix`` (its inverse transpose) and made
    unit length; zero (absent) normals stay 0.  ``unit`` False: not made unit length (so that the
    kernels' normalised interpolation gives the moved interpolated normal: an instance's)."""
    if normals is None:
        return None
    src = np.asarray(normals).reshape(-1, 3)
    inv = np.linalg.inv(np.asarray(matrix, np.float64)[:3, :3])
    out = np.empty(src.shape, np.float32)
    step = 1 << 20  # in float64 a chunk at a time: a whole 54M-triangle mesh's copies took 12 GB
    for lo in range(0, len(src), step):
        n = src[lo:lo + step].astype(np.float64) @ inv  # (M^-T n)^T = n^T M^-1
        if not unit:
            out[lo:lo + step] = np.nan_to_num(n)
            continue
        with np.errstate(invalid="ignore", divide="ignore"):
            n = n / np.linalg.norm(n, axis=1, keepdims=True)
        out[lo:lo + step] = np.nan_to_num(n, nan=0.0, posinf=0.0, neginf=0.0)
    return out.reshape(-1, 3, 3)


def angle_weighted_normals(vertices, faces, keys=None, out=None) -> np.ndarray:
    """Per-corner (F, 3, 3) vertex normals as Mitsuba 3 computes them for a mesh without any
    (``Mesh::recompute_vertex_normals``: Thuermer and Wuethrich 1998): each face's unit normal
    weighted by its angle at the vertex, summed over the faces that share the vertex, normalised
    ((1, 0, 0) for a vertex whose sum is 0, as Mitsuba's).  ``keys`` (F, 3) int: which corners are
    one vertex (default: the face indices; Mitsuba's OBJ reader makes one vertex per distinct
    position and texture coordinate).  In float64, one parallel pass over the faces
    (scene/meshops.py; tests/scene/test_meshops.py holds the numpy reference it matches).
    ``out``: where to write them (:class:`PendingNormals`)."""
    with host_stage("normals"):
        return meshops.angle_weighted_normals(vertices, faces, keys, out)


class PendingNormals:
    """A mesh's angle-weighted normals, computed when the scene's per-corner normals are stacked
    (:func:`stacked_per_face`), straight into their place there: no per-mesh (F, 3, 3) array
    and no copy of it (288 MB each at 8M triangles; issue 35).  Holds the mesh's own vertices,
    faces and corner keys, so the normals are those :func:`angle_weighted_normals` gives them."""

    def __init__(self, vertices, faces, keys):
        self.vertices, self.faces, self.keys = vertices, faces, keys

    def write_into(self, out) -> None:
        angle_weighted_normals(self.vertices, self.faces, self.keys, out=out)


def scene_bounds(scene: Scene):
    """(lo, hi) corners of the box around the scene's used vertices and its analytic shapes, in world
    space: a two-level group's vertices where its instances move them (scene/instances.py)."""
    lo = np.full(3, np.inf)
    hi = np.full(3, -np.inf)
    world = np.asarray(scene.faces)[:n_world_faces(scene)]
    if len(world):
        used_lo, used_hi = meshops.bounds(np.asarray(scene.vertices)[meshops.used_vertices(world, len(scene.vertices))])
        lo, hi = np.minimum(lo, used_lo), np.maximum(hi, used_hi)
    moved = instance_bounds(scene)
    if moved is not None:
        lo, hi = np.minimum(lo, moved[0]), np.maximum(hi, moved[1])
    if len(scene.shapes):
        s_lo, s_hi = shape_bounds(scene.shapes)
        lo, hi = np.minimum(lo, s_lo.min(axis=0)), np.maximum(hi, s_hi.max(axis=0))
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
