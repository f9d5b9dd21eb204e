"""Shape groups and their instances, shared by the Mitsuba 3 XML importer (``shapegroup`` /
``instance``) and the pbrt-v4 one (``ObjectBegin``/``ObjectEnd`` / ``ObjectInstance``).

While a group is open (:meth:`SceneBuilder.begin_group`), the builder's ``add_mesh`` and
``add_sphere`` record each shape in the group's own space, as they would have added it: moved by
the shape's own transform, flipped, its shading normals (given or computed) and its material and
medium interface resolved.  Each instance (:func:`add_instance`) then adds the group's shapes moved
by its ``to_world`` M, so a shape lands at M @ (its own to_world), as in Mitsuba and pbrt-v4:

* mesh vertices by M, shading normals by M's inverse transpose (not made unit length: the
  kernels interpolate, then normalise, so an unevenly scaled instance is shaded as Mitsuba shades
  it, with the group's interpolated normal moved), UVs and vertex colours kept; an M that
  mirrors (det < 0) reverses the corners, so the front stays on the side of the moved normal;
* a sphere stays a sphere (centre moved, radius scaled) when M is a similarity; otherwise it is the
  ellipsoid M makes of it, as triangles with its exact normals.

This flattens the instances at load time: the image is exact, but memory grows with the number of
instances.  Each instance is also kept as a record (``Scene.instances``: the group, M, and where its
copy lies in the scene's arrays) for a two-level BVH, instances sharing one BLAS, to build from.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..model import Instance
from .assembly import transform_normals


@dataclass(eq=False)
class ShapeGroup:
    """The shapes of one group in its own space: meshes as (vertices, faces, uvs, normals, colors,
    material, interface), as the builder would append them, and spheres as (centre, radius,
    material, interface)."""

    name: str
    meshes: list = field(default_factory=list)
    spheres: list = field(default_factory=list)

    @property
    def empty(self) -> bool:
        return not self.meshes and not self.spheres


def is_similarity(m, rtol: float = 1e-6) -> tuple:
    """(whether the 3x3 part of ``m`` is a rotation (or mirror) times one scale, that scale)."""
    s = np.linalg.svd(np.asarray(m, np.float64)[:3, :3], compute_uv=False)
    return bool(s.max() - s.min() <= rtol * s.max()), float(s.mean())


def add_instance(builder, group: ShapeGroup, matrix, position: str) -> Instance:
    """Add ``group``'s shapes to ``builder``'s scene moved by the 4x4 ``matrix`` (None: the
    identity); returns (and records in ``builder.instances``) the Instance."""
    from .builder import error_at, sphere_mesh, transform_points

    if builder.recording is not None:
        raise error_at(position, "an instance inside a shape group: nested instancing is not supported")
    m = np.eye(4) if matrix is None else np.asarray(matrix, np.float64)
    det = float(np.linalg.det(m[:3, :3]))
    if not abs(det) > 1e-300 or not np.isfinite(m).all():
        raise error_at(position, f"the instance of '{group.name}': its to_world is singular")
    first_face, first_sphere = builder.n_faces, len(builder.spheres)
    # shading normals by the inverse transpose, not made unit length again, all divided by its
    # largest stretch: the kernels' normalised interpolation then gives normalize(M^-T (the group's
    # interpolated normal)), as Mitsuba's instance computes it, also where M scales unevenly
    similar, s = is_similarity(m)
    stretch = np.linalg.svd(m[:3, :3], compute_uv=False).min()
    if not similar and any(mesh[3] is not None for mesh in group.meshes):
        builder.normals_as_given = True  # every other normal is unit already (add_mesh)
    for v, f, uv, nrm, col, material, interface in group.meshes:
        v, nrm = transform_points(m, v), transform_normals(m, None if nrm is None else nrm * stretch, unit=False)
        if det < 0:  # mirrored: reverse the corners, the front follows the moved normal
            f, uv, nrm, col = (None if a is None else a[:, ::-1] for a in (f, uv, nrm, col))
        builder.append_mesh(v, f, uv, nrm, col, material, interface)
    for centre, radius, material, interface in group.spheres:
        if similar:
            builder.add_sphere(transform_points(m, centre)[0], radius * s, material, interface=interface)
            continue
        v, f, uv = sphere_mesh(radius)  # an ellipsoid: as triangles with its exact normals
        moved = m @ np.block([[np.eye(3), np.reshape(centre, (3, 1))], [np.zeros((1, 3)), np.ones((1, 1))]])
        builder.add_mesh(v, f, material, uvs=uv, matrix=moved, normals=(v / radius)[f], interface=interface)
    inst = Instance(group.name, m.copy(), first_face, builder.n_faces - first_face, first_sphere,
                    len(builder.spheres) - first_sphere)
    builder.instances.append(inst)
    return inst


def remap_instances(instances: list, keep: np.ndarray | None) -> list:
    """The instance records with their face ranges in the Scene's faces once the faces that
    ``keep`` (a mask over the builder's faces, None: all kept) leaves out are dropped."""
    if keep is None or keep.all():
        return list(instances)
    before = np.concatenate([[0], np.cumsum(keep, dtype=np.int64)])
    out = []
    for inst in instances:
        lo, hi = inst.first_face, inst.first_face + inst.n_faces
        out.append(Instance(inst.group, inst.to_world, int(before[lo]), int(before[hi] - before[lo]),
                            inst.first_sphere, inst.n_spheres))
    return out

