"""``sphere``: centre ``center`` and radius ``radius``, its front outside (cl/shapes/sphere.h
intersects and samples it; params 0-2 the centre, 3 the radius).

TOML: ``[[shape]] type = "sphere"``, ``center`` and ``radius`` (required; no transforms).  Mitsuba 3:
``sphere`` (``center``, ``radius``, moved by ``to_world``; an uneven scale is refused by Mitsuba and
here warned and averaged).  pbrt-v4: ``sphere`` (``radius``; a partial one is triangles).  Our
spheres emit outwards only and do not flip (``flip_normals`` swaps a medium interface's sides, the
loaders say so for an emitter); a sphere that a map scales unevenly becomes triangles (:func:`mesh`).
"""
from __future__ import annotations

import numpy as np

from .frames import ShapeMitsubaReading, is_similarity, rows, transform_points

TOML_KEYS = frozenset({"center", "radius"})
MITSUBA_PLUGINS = ("sphere",)
FLIPS = False  # no inward-facing sphere: the loaders flip its interface instead


def params(centre, radius) -> np.ndarray:
    """The (1, 28) parameter block of one sphere."""
    p = np.zeros((1, 28))
    p[0, :3], p[0, 3] = np.asarray(centre, np.float64).reshape(3), float(radius)
    return p


def bounds(p) -> tuple:
    p = rows(p)
    return p[:, :3] - p[:, 3:4], p[:, :3] + p[:, 3:4]


def area(p) -> np.ndarray:
    return 4.0 * np.pi * rows(p)[:, 3] ** 2


def emission_cone(p) -> tuple:
    """(axis, cos of the cone's half-angle) of its emitted normals, per row: every direction."""
    n = len(rows(p))
    return np.tile([0.0, 0.0, 1.0], (n, 1)), np.full(n, -1.0)


def transformed(p, m) -> np.ndarray | None:
    """Moved by the 4x4 affine m: a sphere under a similarity, None otherwise (an ellipsoid: mesh())."""
    p = rows(p).copy()
    similar, s = is_similarity(m)
    if not similar:
        return None
    p[:, :3], p[:, 3] = transform_points(m, p[:, :3]), p[:, 3] * s
    return p


def mesh(p, m):
    """One sphere moved by a map that keeps it not: triangles with its exact normals (v, f, uv, normals)."""
    from ..loaders.geometry import sphere_mesh  # here: the loaders (their builder) import this package

    centre, radius = rows(p)[0, :3], float(rows(p)[0, 3])
    v, f, uv = sphere_mesh(radius)
    moved = m @ np.block([[np.eye(3), centre.reshape(3, 1)], [np.zeros((1, 3)), np.ones((1, 1))]])
    return v, f, uv, (v / radius)[f], moved


def check(p) -> list:
    """(row, what is wrong) for each sphere the kernels cannot take."""
    out = []
    for i, (c, r) in enumerate(zip(rows(p)[:, :3], rows(p)[:, 3])):
        if not (np.isfinite(c).all() and np.isfinite(r)):
            out.append((i, f"centre and radius must be finite, got {[*c.tolist(), float(r)]}"))
        elif not np.float32(r) > 0:
            out.append((i, f"radius {r:g} is not positive in float32"))
    return out


def reach(p) -> np.ndarray:
    """The largest coordinate each sphere reaches."""
    p = rows(p)
    return np.abs(p[:, :3]).max(axis=1) + p[:, 3]


def to_mitsuba(p) -> dict:
    c, r = rows(p)[0, :3], float(rows(p)[0, 3])
    return {"type": "sphere", "center": [float(x) for x in c], "radius": r}


def read_toml(t) -> np.ndarray:
    for req in ("center", "radius"):
        if req not in t:
            raise t.error(f"missing '{req}'")
    centre = t.vector("center")
    radius = t.number("radius", None, positive=True)
    if not np.float32(radius) > 0:
        raise t.error(f"'radius' {radius:g} is 0 in float32")
    return params(centre, radius)


def from_mitsuba(obj, read: ShapeMitsubaReading) -> np.ndarray:
    centre = obj.point("center", np.zeros(3))
    radius = obj.float("radius", 1.0, positive=True)
    m = read.to_world
    if m is not None:
        s = np.linalg.svd(m[:3, :3], compute_uv=False)
        if s.max() - s.min() > 1e-6 * s.max():
            read.warn("to_world scales unevenly (Mitsuba does not allow it); using the mean scale")
        centre, radius = transform_points(m, centre)[0], radius * float(s.mean())
    return params(centre, radius)


def records(spheres) -> np.ndarray:
    """abi.SHAPE records of (S, 4) centre-and-radius rows (the form tests and tools write spheres in)."""
    from . import records as shape_records

    s = np.asarray(spheres, np.float64).reshape(-1, 4)
    p = np.zeros((len(s), 28))
    p[:, :4] = s
    return shape_records("sphere", p)


def of(shapes) -> np.ndarray:
    """(n, 4) float32 centre and radius of the spheres among the abi.SHAPE records ``shapes``."""
    from ...device import abi

    shapes = np.asarray(shapes)
    return shapes["params"][shapes["type"] == abi.SHAPE_TYPES["sphere"], :4].astype(np.float32)
