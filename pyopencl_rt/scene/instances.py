"""Two-level instances of a Scene (``Scene.blas_groups``, ``Instance.blas``): which faces are the
world's, the faces a group's instance draws, and the scene with them flattened.

A two-level group's faces come after every world face, in the group's own space; an instance
draws them moved by its to_world M (positions by M, shading normals by M's inverse transpose,
the front following the moved normal, also where M mirrors).  :func:`flattened` makes those
copies (the Embree intersector and the Mitsuba export render that scene; tests compare the two).
"""
from __future__ import annotations

import copy
import dataclasses

import numpy as np


def is_similarity(m, rtol: float = 1e-6) -> tuple:
    """(whether the 3x3 part of ``m`` is a rotation (or mirror) times one scale, that scale)."""
    s = np.linalg.svd(np.asarray(m, np.float64)[:3, :3], compute_uv=False)
    return bool(s.max() - s.min() <= rtol * s.max()), float(s.mean())


def two_level(scene) -> list:
    """The scene's two-level instances (blas >= 0)."""
    return [i for i in getattr(scene, "instances", ()) if i.blas >= 0]


def n_world_faces(scene) -> int:
    """Faces [0, n) are in world space; the rest belong to the two-level groups."""
    groups = getattr(scene, "blas_groups", ())
    return min(g.first_face for g in groups) if groups else len(scene.faces)


def group_vertices(scene) -> np.ndarray:
    """The indices of the vertices that the two-level groups' faces use (in their own space)."""
    return np.unique(np.asarray(scene.faces[n_world_faces(scene):], np.int64))


def instance_bounds(scene):
    """(lo, hi) float64 corners of the box around the two-level instances' moved group vertices
    (each group's used vertices through each of its instances' M, exactly, a chunk of instances at
    a time: 10^6 instances of a small group never make 10^6 copies at once); None without any.
    A moving instance counts by the box of its whole way (accel/motion.py)."""
    from ..accel.motion import Motion

    insts = two_level(scene)
    if not insts:
        return None
    v64 = np.asarray(scene.vertices, np.float64)
    m_all = np.asarray([i.to_world for i in insts if not i.moves], np.float64).reshape(-1, 4, 4)
    g_all = np.asarray([i.blas for i in insts if not i.moves])
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    for k, g in enumerate(scene.blas_groups):
        faces = np.asarray(scene.faces[g.first_face:g.first_face + g.n_faces])
        m = m_all[g_all == k]
        if not len(faces) or not len(m):
            continue
        p = v64[np.unique(faces)]
        step = max(1, (1 << 20) // len(p))
        for c in range(0, len(m), step):
            w = np.einsum("nij,kj->nki", m[c:c + step, :3, :3], p) + m[c:c + step, None, :3, 3]
            lo, hi = np.minimum(lo, w.min(axis=(0, 1))), np.maximum(hi, w.max(axis=(0, 1)))
    for inst in insts:
        g = scene.blas_groups[inst.blas]
        faces = np.asarray(scene.faces[g.first_face:g.first_face + g.n_faces])
        if inst.moves and len(faces):
            p = v64[np.unique(faces)]
            box = Motion(inst.to_world, inst.to_world_end, *(inst.pivots() or ())).bounds(
                np.stack([p.min(axis=0), p.max(axis=0)]))
            lo, hi = np.minimum(lo, box[0]), np.maximum(hi, box[1])
    return (lo, hi) if np.isfinite(lo).all() else None


def camera_shifted(scene, eye) -> list:
    """The instance records with the world moved by -eye (the groups' own spaces stay)."""
    shift = np.eye(4)
    shift[:3, 3] = -np.asarray(eye, np.float64)
    return [dataclasses.replace(i, to_world=shift @ i.to_world,
                                to_world_end=None if i.to_world_end is None else shift @ i.to_world_end,
                                motion_pivot_world=None if i.motion_pivot is None else  # the world moved alone
                                tuple(np.asarray(i.pivots()[1], np.float64) - np.asarray(eye, np.float64)))
            if i.blas >= 0 else i for i in scene.instances]


def flattened(scene):
    """``scene`` with each two-level instance drawn by its own moved copy of its group's faces,
    as the loaders flatten instances (loaders/instancing.py); ``scene`` itself without any."""
    insts = two_level(scene)
    if not insts:
        return scene
    if any(i.moves for i in insts):
        from ..errors import UserError

        raise UserError(f"{scene.source}: motion blur (moving instances) is rendered by our own traversal only, "
                        "not with the Embree intersector nor in an export")
    n_world = n_world_faces(scene)
    faces = np.asarray(scene.faces, np.int64)
    v64 = np.asarray(scene.vertices, np.float64)
    normals = scene.face_normals() if scene.normals is not None else None
    parts = {k: [] for k in ("v", "f", "mat", "uv", "n", "col", "iface", "emit")}
    n_v = len(scene.vertices)
    records = []
    n_f = n_world
    as_given = scene.normals_as_given
    for inst in scene.instances:
        if inst.blas < 0:
            records.append(inst)
            continue
        g = scene.blas_groups[inst.blas]
        sel = slice(g.first_face, g.first_face + g.n_faces)
        m = inst.to_world
        f = faces[sel]
        used, local = np.unique(f, return_inverse=True)
        p = v64[used] @ m[:3, :3].T + m[:3, 3]
        order = slice(None, None, -1) if np.linalg.det(m[:3, :3]) < 0 else slice(None)
        parts["v"].append(p)
        parts["f"].append(local.reshape(-1, 3)[:, order] + n_v)
        n_v += len(used)
        for key, arr in (("mat", scene.face_materials), ("iface", scene.face_interfaces),
                         ("emit", scene.face_emitters)):
            if arr is not None:
                parts[key].append(np.asarray(arr)[sel])
        if scene.uvs is not None:
            parts["uv"].append(scene.face_uvs()[sel][:, order])
        if scene.colors is not None:
            parts["col"].append(scene.face_colors()[sel][:, order])
        if normals is not None:
            # M^-T n times M's smallest stretch, not made unit: the kernels' normalised
            # interpolation then gives the two-level render's normalize(M^-T (interpolated n))
            similar, _ = is_similarity(m)
            as_given |= not similar
            stretch = np.linalg.svd(m[:3, :3], compute_uv=False).min()
            nt = (normals[sel].astype(np.float64) @ np.linalg.inv(m[:3, :3])) * stretch
            parts["n"].append(nt[:, order])
        records.append(dataclasses.replace(inst, first_face=n_f, n_faces=g.n_faces, blas=-1))
        n_f += g.n_faces
    s = copy.copy(scene)
    keep = slice(0, n_world)
    s.vertices = np.concatenate([scene.vertices] + [x.astype(np.float32) for x in parts["v"]])
    s.faces = np.concatenate([faces[keep]] + parts["f"]).astype(np.int32)
    s.face_materials = np.concatenate([scene.face_materials[keep]] + parts["mat"]).astype(np.int32)
    for name, key, getter in (("uvs", "uv", scene.face_uvs), ("colors", "col", scene.face_colors),
                              ("normals", "n", lambda: normals)):
        if getattr(scene, name) is not None:
            setattr(s, name, np.concatenate([getter()[keep]] + parts[key]).astype(np.float32))
    for name, key in (("face_interfaces", "iface"), ("face_emitters", "emit")):
        if getattr(scene, name) is not None:
            setattr(s, name, np.concatenate([np.asarray(getattr(scene, name))[keep]] + parts[key]).astype(np.int32))
    s.normals_as_given = bool(as_given)
    s.normals_unit = False  # the instances' moved normals are not unit (see above)
    s.instances, s.blas_groups = records, []
    return s


def scene_bvh(scene, threads=None):
    """A BVH for ``scene``: the plain one, or the TwoLevelBVH (accel/instances.py) where it has
    two-level instances."""
    from ..accel.bvh import build_bvh
    from ..accel.instances import TwoLevelBVH

    if not getattr(scene, "blas_groups", None):
        return build_bvh(scene.vertices, scene.faces, threads=threads)
    return TwoLevelBVH(scene.vertices, scene.faces, n_world_faces(scene),
                       [(g.first_face, g.n_faces) for g in scene.blas_groups],
                       [(i.to_world, i.blas) for i in two_level(scene)], threads=threads,
                       ends=[i.to_world_end for i in two_level(scene)], motion_time=scene.motion_time,
                       pivots=[i.pivots() for i in two_level(scene)])
