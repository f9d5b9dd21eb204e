"""``cylinder``: an open tube (no caps) of radius ``radius`` from ``p0`` to ``p1``, moved by an affine
``to_world``, its front outside (inside with ``flip_normals``), as Mitsuba 3's and pbrt-v4's full
cylinder (cl/shapes/cylinder.h intersects and samples it).  A right circular tube: its to_world's
x and y columns of one length, at right angles to each other and to its axis.

Params: to_world's rows (0-11: the unit tube x^2 + y^2 = 1, 0 <= z <= 1, to the world), to_object's
rows (12-23), the front's side (24: +1 outside, -1 inside) and the area (25).

TOML: ``[[shape]] type = "cylinder"``, ``p0`` and ``p1`` (its axis' ends, required), ``radius``
(default 1), ``flip_normals``.  Mitsuba 3: ``cylinder`` (``p0``, ``p1``, ``radius``, ``to_world``,
``flip_normals``; its frame about p1 - p0 is Mitsuba's coordinate_system).  pbrt-v4: a full
``cylinder`` (``radius``, ``zmin``, ``zmax``; ``phimax`` 360).  A tube that a map scales unevenly
(an elliptic one), one whose material reads the uv or dp/du, a partial or moving one: triangles
with the exact radial normals instead (:func:`mesh`, the loaders).
"""
from __future__ import annotations

import numpy as np

from .frames import (ShapeMitsubaReading, affine_rows, coordinate_system, inverse_rows, mapped_checks, ring_box, rows,
                     to_world_maps)

TOML_KEYS = frozenset({"p0", "p1", "radius", "flip_normals"})
MITSUBA_PLUGINS = ("cylinder",)
FLIPS = True  # flip_normals makes the inside its front


def right_circular(m, rtol: float = 1e-6) -> bool:
    """Whether the 4 x 4 affine m makes the unit tube a right circular one: its x and y columns of one
    length, the three columns at right angles (then phi and z uniform are uniform in area)."""
    x, y, z = (np.asarray(m, np.float64)[:3, k] for k in range(3))
    r, length = np.linalg.norm(x), np.linalg.norm(z)
    return bool(abs(np.linalg.norm(y) - r) <= rtol * r and abs(x @ y) <= rtol * r * r
                and abs(x @ z) <= rtol * r * length and abs(y @ z) <= rtol * r * length)


def params(to_world, flip: bool = False) -> np.ndarray | None:
    """The (1, 28) parameter block of the unit tube moved by the 4 x 4 affine to_world (None where it
    does not stay a right circular tube: an elliptic or a slanted one, which :func:`mesh` makes)."""
    m = np.asarray(to_world, np.float64)
    if not right_circular(m):
        return None
    p = np.zeros((1, 28))
    p[0, :12], p[0, 12:24] = affine_rows(m), inverse_rows(m)
    p[0, 24] = -1.0 if flip else 1.0
    p[0, 25] = 2.0 * np.pi * np.linalg.norm(m[:3, 0]) * np.linalg.norm(m[:3, 2])
    return p


def axis_to_world(p0, p1, radius) -> np.ndarray:
    """The to_world of the unit tube onto the one of ``radius`` from p0 to p1 (x, y: Mitsuba's
    coordinate_system of the axis)."""
    p0, p1 = np.asarray(p0, np.float64), np.asarray(p1, np.float64)
    axis = p1 - p0
    x, y = coordinate_system(axis / np.linalg.norm(axis))
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x * radius, y * radius, axis, p0
    return m


def bounds(p) -> tuple:
    """The box of the tube: its two end circles'."""
    return ring_box(to_world_maps(p), along_z=True)


def area(p) -> np.ndarray:
    return rows(p)[:, 25].copy()


def reach(p) -> np.ndarray:
    lo, hi = bounds(p)
    return np.maximum(np.abs(lo), np.abs(hi)).max(axis=1)


def emission_cone(p) -> tuple:
    """Every direction (its normals turn about the axis)."""
    n = len(rows(p))
    return np.tile([0.0, 0.0, 1.0], (n, 1)), np.full(n, -1.0)


def transformed(p, m) -> np.ndarray | None:
    """Moved by the 4 x 4 affine m: a tube where it stays a right circular one (a similarity keeps it
    so; its front kept), None otherwise."""
    out = []
    for row, tw in zip(rows(p), to_world_maps(p)):
        moved = params(np.asarray(m, np.float64) @ tw, row[24] < 0)
        if moved is None:
            return None
        out.append(moved[0])
    return np.asarray(out).reshape(-1, 28)


def mesh(p, m):
    """One tube moved by a map that keeps it not a tube of ours (an elliptic or slanted one): triangles with its
    exact radial normals (v, f, uv, normals, matrix), the inside's where it faces in."""
    from ..loaders.geometry import cylinder_mesh  # here: the loaders (their builder) import this package

    row = rows(p)[0]
    v, f, uv = cylinder_mesh(1.0, 0.0, 1.0)
    radial = v * [1.0, 1.0, 0.0]
    radial /= np.linalg.norm(radial, axis=1, keepdims=True)
    if row[24] < 0:
        f, radial = f[:, ::-1], -radial
    return v, f, uv, radial[f], np.asarray(m, np.float64) @ to_world_maps(row)[0]


def check(p) -> list:
    """(row, what is wrong) for each tube the kernels cannot take."""
    return mapped_checks(p, 25)


def to_mitsuba(p) -> dict:
    row = rows(p)[0]
    m = to_world_maps(row)[0]
    return {"type": "cylinder", "p0": [0.0, 0.0, 0.0], "p1": [0.0, 0.0, 1.0], "radius": 1.0,
            "to_world": [list(map(float, r)) for r in m], "flip_normals": bool(row[24] < 0)}


def read_toml(t) -> np.ndarray:
    for req in ("p0", "p1"):
        if req not in t:
            raise t.error(f"missing '{req}'")
    p0, p1 = t.vector("p0"), t.vector("p1")
    if not np.linalg.norm(p1 - p0) > 0:
        raise t.error("'p0' and 'p1' are the same point")
    radius = t.number("radius", 1.0, positive=True)
    if not np.float32(radius) > 0:
        raise t.error(f"'radius' {radius:g} is 0 in float32")
    return params(axis_to_world(p0, p1, radius), t.boolean("flip_normals", False))


def from_mitsuba(obj, read: ShapeMitsubaReading) -> np.ndarray | None:
    p0 = obj.point("p0", np.zeros(3))
    p1 = obj.point("p1", np.array([0.0, 0.0, 1.0]))
    radius = obj.float("radius", 1.0, positive=True)
    if not np.linalg.norm(p1 - p0) > 0:
        raise read.error("p0 and p1 are the same point")
    local = axis_to_world(p0, p1, radius)
    return params(local if read.to_world is None else read.to_world @ local, read.flip)
