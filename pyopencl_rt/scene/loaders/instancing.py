"""Shape groups and their instances, shared by the Mitsuba 3 XML importer (``shapegroup`` /
``instance``) and the pbrt-v4 one (``ObjectBegin``/``ObjectEnd`` / ``ObjectInstance``).

While a group is open (:meth:`SceneBuilder.begin_group`), the builder's ``add_mesh`` and
``add_shape`` record each shape in the group's own space, as they would have added it: moved by
the shape's own transform, flipped, its shading normals (given or computed) and its material and
medium interface resolved.  Each instance (:func:`add_instance`) then adds the group's shapes moved
by its ``to_world`` M, so a shape lands at M @ (its own to_world), as in Mitsuba and pbrt-v4:

* mesh vertices by M, shading normals by M's inverse transpose (not made unit length: the
  kernels interpolate, then normalise, so an unevenly scaled instance is shaded as Mitsuba shades
  it, with the group's interpolated normal moved), UVs and vertex colours kept; an M that
  mirrors (det < 0) reverses the corners, so the front stays on the side of the moved normal;
* an analytic shape by its type's ``transformed`` (scene/shapes/): a disk stays a disk, a sphere a
  sphere when M is a similarity; otherwise the sphere is the ellipsoid M makes of it, as triangles
  with its exact normals (its type's ``mesh``).

Flattening is exact but its memory grows with the instances.  So a group of two or more instances
that would flatten to more than :data:`FLATTEN_MAX_TRIANGLES` triangles is drawn through a two-level BVH
instead (:func:`place`, at the end of loading): its faces are added once, in its own space, after
every world face (a ``BlasGroup``), and each instance is only a record (``Instance.blas``) that
the renderer moves at render time (pyopencl_rt/accel/instances.py).  A group stays flattened
whatever its size where the renderer's instances do not reach (:func:`why_flattened`): analytic
shapes (in the shapes' own BVH), emitters (Mitsuba and pbrt-v4 allow none in instances; we
warn and let each copy emit), medium interfaces, normal or bump maps, anisotropy (their frames
need the world dp/du), intersection cut-outs and mixes; so does every group of a scene with
participating media.  ``$PYOPENCL_RT_INSTANCING``: ``auto`` (the default), ``flatten`` (every
group) or ``two-level`` (every group that can).  Every instance is kept as a record
(``Scene.instances``: the group, M, and its copy's faces when flattened).
"""
from __future__ import annotations

import os
from dataclasses import dataclass, field

import numpy as np

from ...errors import UserError
from ..model import BlasGroup, Instance
from ..instances import is_similarity
from .assembly import transform_normals
from .geometry import transform_points
from .values import SceneError, error_at

INSTANCING_ENV = "PYOPENCL_RT_INSTANCING"
# auto: two-level once flattening would copy more triangles than this, the measured speed
# crossover on a CPU (docs/BENCHMARKS.md, "Instancing": the two-level render 0.6x-0.8x the flattened
# one's samples/s at 8k-65k copied triangles, even at 262k, ahead at 524k); the copies below it
# take at most about 40 MB.
FLATTEN_MAX_TRIANGLES = 1 << 18


@dataclass(eq=False)
class ShapeGroup:
    """The shapes of one group in its own space: meshes as (vertices, faces, uvs, normals, colors,
    material, interface), as the builder would append them, and analytic shapes as (ShapeType,
    parameter row, material, interface)."""

    name: str
    meshes: list = field(default_factory=list)
    shapes: list = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not self.meshes and not self.shapes


def instancing_mode() -> str:
    """$PYOPENCL_RT_INSTANCING: auto, flatten or two-level (a UserError, one line, otherwise)."""
    value = os.environ.get(INSTANCING_ENV, "auto").strip().lower() or "auto"
    if value not in ("auto", "flatten", "two-level"):
        raise UserError(f"${INSTANCING_ENV} must be auto, flatten or two-level, not {value!r}")
    return value


def why_flattened(group: ShapeGroup) -> str | None:
    """Why ``group`` cannot be drawn through the two-level BVH (None: it can)."""
    if group.shapes:
        return "analytic shapes"
    for v, f, uv, nrm, col, material, interface in group.meshes:
        if material.is_emissive or interface is not None:
            return "an emitter" if material.is_emissive else "a medium interface"
        if material.normal_texture is not None or material.is_anisotropic or material.cutout or material.blend:
            return "a material whose frame or intersection needs world-space data"
    return None


def add_instance(builder, group: ShapeGroup, matrix, position: str, matrix_end=None, what: str = "",
                 pivot=None) -> Instance:
    """Add an instance of ``group`` moved by the 4x4 ``matrix`` (None: the identity) to
    ``builder``'s scene: flattened now, or (a group that may go two-level) once :func:`place`
    decides; returns (and records in ``builder.instances``) the Instance.  ``matrix_end``: where a
    moving instance is at the end of its motion (motion blur: always two-level; ``what`` names the
    shape in the refusals; ``pivot``: the point its way turns about, Instance.motion_pivot)."""
    if builder.recording is not None:
        raise error_at(position, "an instance inside a shape group: nested instancing is not supported")
    m = np.eye(4) if matrix is None else np.asarray(matrix, np.float64)
    det = float(np.linalg.det(m[:3, :3]))
    if not abs(det) > 1e-300 or not np.isfinite(m).all():
        raise error_at(position, f"the instance of '{group.name}': its to_world is singular")
    if matrix_end is not None:
        return _moving_instance(builder, group, m, np.asarray(matrix_end, np.float64), position, what, pivot)
    if group.meshes and why_flattened(group) is None and instancing_mode() != "flatten":
        inst = Instance(group.name, m.copy(), blas=-2)  # -2: placed at the end (place)
        builder.instances.append(inst)
        builder.pending.setdefault(group.name, (group, []))[1].append(inst)
        return inst
    return flatten_instance(builder, group, m)


def _moving_instance(builder, group: ShapeGroup, m, m_end, position: str, what: str, pivot=None) -> Instance:
    """A moving instance (motion blur): the renderer moves a two-level instance along pbrt-v4's way
    between its two transforms (accel/motion.py, cl/accel/instances.h); what it cannot move is
    refused here, in one line."""
    what = what or f"the instance of '{group.name}'"
    if not np.isfinite(m_end).all() or not np.allclose(m_end[3], (0, 0, 0, 1)) \
            or not abs(np.linalg.det(m_end[:3, :3])) > 1e-300:
        raise error_at(position, f"{what}: its transform at the end of the motion is not an invertible affine one")
    if np.linalg.det(m[:3, :3]) * np.linalg.det(m_end[:3, :3]) < 0:
        raise error_at(position, f"{what}: a motion from a transform to its mirror image is not supported")
    why = "analytic shapes" if group.shapes else why_flattened(group)
    if why is not None:
        raise error_at(position, f"{what}: motion blur of a shape with {why} is not supported")
    if builder.media or builder.interfaces:
        raise error_at(position, f"{what}: motion blur in a scene with participating media is not supported")
    inst = Instance(group.name, m.copy(), blas=-2, to_world_end=m_end.copy(),
                    motion_pivot=None if pivot is None else tuple(float(x) for x in pivot))
    builder.instances.append(inst)
    builder.pending.setdefault(group.name, (group, []))[1].append(inst)
    return inst


def place(builder) -> list:
    """At the end of loading: each group whose instances wait (add_instance) is flattened or, if
    its two or more copies would exceed FLATTEN_MAX_TRIANGLES (or $PYOPENCL_RT_INSTANCING=two-level),
    added once in its own space after every world face, its instances pointing at it.  Returns
    the BlasGroup records (their face ranges in the builder's faces)."""
    mode = instancing_mode()
    groups, waiting = [], []
    for name, (group, insts) in builder.pending.items():
        copies = len(insts) * sum(len(mesh[1]) for mesh in group.meshes)
        # a group drawn once is flattened whatever its size: its own space saves nothing there, and one
        # level is the faster BVH (pbrt exporters wrap every mesh in ObjectBegin / ObjectInstance)
        shared = len(insts) > 1 and copies > FLATTEN_MAX_TRIANGLES
        two_level = not (builder.media or builder.interfaces) and (mode == "two-level" or (mode == "auto" and shared))
        if any(inst.moves for inst in insts):
            if builder.media or builder.interfaces:  # (media declared after the moving shape)
                raise SceneError(f"{builder.name}: motion blur in a scene with participating media is not supported")
            two_level = True  # the kernels move two-level instances alone
        (waiting if two_level else groups).append((group, insts))
    # each waiting record's place in builder.instances, found once (by identity: records compare
    # by value), not searched for per instance: tens of thousands of small copies stay linear
    where = {id(inst): k for k, inst in enumerate(builder.instances)}
    for group, insts in groups:  # flattened after all (their faces follow the world's)
        for inst in insts:
            builder.instances[where[id(inst)]] = flatten_instance(builder, group, inst.to_world, record=False)
    blas = []
    for group, insts in waiting:
        first = builder.n_faces
        for v, f, uv, nrm, col, material, interface in group.meshes:
            builder.append_mesh(v, f, uv, nrm, col, material, interface)
        for inst in insts:
            inst.blas = len(blas)
        blas.append(BlasGroup(group.name, first, builder.n_faces - first))
    builder.pending = {}
    return blas


def flatten_instance(builder, group: ShapeGroup, m, record: bool = True) -> Instance:
    """Add ``group``'s shapes moved by ``m`` to the builder's arrays (recorded in
    builder.instances with ``record``); the Instance."""
    det = float(np.linalg.det(m[:3, :3]))
    first_face, first_shape = builder.n_faces, len(builder.shapes)
    # shading normals by the inverse transpose, not made unit length again, all divided by its
    # largest stretch: the kernels' normalised interpolation then gives normalize(M^-T (the group's
    # interpolated normal)), as Mitsuba's instance computes it, also where M scales unevenly
    similar, _ = is_similarity(m)
    stretch = np.linalg.svd(m[:3, :3], compute_uv=False).min()
    if not similar and any(mesh[3] is not None for mesh in group.meshes):
        builder.normals_as_given = True  # every other normal is unit already (add_mesh)
    for v, f, uv, nrm, col, material, interface in group.meshes:
        v, nrm = transform_points(m, v), transform_normals(m, None if nrm is None else nrm * stretch, unit=False)
        if det < 0:  # mirrored: reverse the corners, the front follows the moved normal
            f, uv, nrm, col = (None if a is None else a[:, ::-1] for a in (f, uv, nrm, col))
        builder.append_mesh(v, f, uv, nrm, col, material, interface)
    for shape, p, material, interface in group.shapes:
        moved = shape.transformed(p, m)
        if moved is not None:
            builder.add_shape(shape, moved, material, interface=interface)
            continue
        v, f, uv, nrm, matrix = shape.mesh(p, m)  # (a sphere made an ellipsoid): triangles, its exact normals
        builder.add_mesh(v, f, material, uvs=uv, matrix=matrix, normals=nrm, interface=interface)
    inst = Instance(group.name, m.copy(), first_face, builder.n_faces - first_face, first_shape,
                    len(builder.shapes) - first_shape)
    if record:
        builder.instances.append(inst)
    return inst


def remap_instances(instances: list, blas: list, keep: np.ndarray | None) -> tuple:
    """The instance and BlasGroup records with their face ranges in the Scene's faces once the
    faces that ``keep`` (a mask over the builder's faces, None: all kept) leaves out are dropped."""
    if keep is None or keep.all():
        return list(instances), list(blas)
    before = np.concatenate([[0], np.cumsum(keep, dtype=np.int64)])

    def span(lo, n):
        return int(before[lo]), int(before[lo + n] - before[lo])

    out = []
    for inst in instances:
        first, n = span(inst.first_face, inst.n_faces)
        out.append(Instance(inst.group, inst.to_world, first, n, inst.first_shape, inst.n_shapes, inst.blas,
                            inst.to_world_end, inst.motion_pivot, inst.motion_pivot_world))
    return out, [BlasGroup(g.name, *span(g.first_face, g.n_faces)) for g in blas]

