"""``disk``: the unit disk x^2 + y^2 <= 1 of the plane z = 0 moved by an affine ``to_world`` (an
ellipse where it scales unevenly), its front the side its normal, to_world's image of +z as a normal,
points to (flipped by ``flip_normals``), as Mitsuba 3's disk (cl/shapes/disk.h intersects and samples it).

Params: to_world's rows (0-11), to_object's rows (12-23), the unit normal (24-26), the area (27).

TOML: ``[[shape]] type = "disk"``, ``center`` and ``normal`` (required), ``radius`` (default 1),
``flip_normals``.  Mitsuba 3: ``disk`` (``to_world``, ``flip_normals``); a disk whose material reads
the surface's uv or dp/du (a texture, a normal or bump map, anisotropy) is Mitsuba's triangles with
its uv instead.  pbrt-v4's disks (``height``, ``radius``, ``innerradius``, ``phimax``) are triangles.
"""
from __future__ import annotations

import numpy as np

from .frames import (ShapeMitsubaReading, affine_rows, coordinate_system, inverse_rows, mapped_checks, ring_box, rows,
                     to_world_maps)

TOML_KEYS = frozenset({"center", "normal", "radius", "flip_normals"})
MITSUBA_PLUGINS = ("disk",)
FLIPS = True  # flip_normals turns its normal (and so its front) over


def params(to_world, flip: bool = False) -> np.ndarray:
    """The (1, 28) parameter block of the disk moved by the 4 x 4 affine to_world."""
    m = np.asarray(to_world, np.float64)
    p = np.zeros((1, 28))
    p[0, :12], p[0, 12:24] = affine_rows(m), inverse_rows(m)
    n = p[0, 20:23]  # to_object's third row: M^-T (0, 0, 1)
    p[0, 24:27] = n / np.linalg.norm(n) * (-1.0 if flip else 1.0)
    p[0, 27] = np.pi * np.linalg.norm(np.cross(m[:3, 0], m[:3, 1]))
    return p


def bounds(p) -> tuple:
    """The box of the ellipse."""
    return ring_box(to_world_maps(p))


def area(p) -> np.ndarray:
    return rows(p)[:, 27].copy()


def emission_cone(p) -> tuple:
    """(axis, cos of the cone's half-angle) of its emitted normals: its normal alone."""
    return rows(p)[:, 24:27].copy(), np.ones(len(rows(p)))


def transformed(p, m) -> np.ndarray:
    """Moved by the 4 x 4 affine m: still a disk (its to_world composed; the front follows the moved normal)."""
    out = []
    for row, tw in zip(rows(p), to_world_maps(p)):
        flip = float(np.dot(row[24:27], params(tw)[0, 24:27])) < 0
        out.append(params(np.asarray(m, np.float64) @ tw, flip)[0])
    return np.asarray(out).reshape(-1, 28)


def check(p) -> list:
    """(row, what is wrong) for each disk the kernels cannot take."""
    return mapped_checks(p, 27)


def reach(p) -> np.ndarray:
    lo, hi = bounds(p)
    return np.maximum(np.abs(lo), np.abs(hi)).max(axis=1)


def to_mitsuba(p) -> dict:
    row = rows(p)[0]
    m = to_world_maps(row)[0]
    flip = float(np.dot(row[24:27], params(m)[0, 24:27])) < 0
    return {"type": "disk", "to_world": [list(map(float, r)) for r in m], "flip_normals": bool(flip)}


def _frame_to_world(centre, normal, radius) -> np.ndarray:
    """The to_world of a disk of ``radius`` at ``centre`` facing ``normal`` (x, y: Mitsuba's
    coordinate_system of the normal)."""
    n = np.asarray(normal, np.float64) / np.linalg.norm(normal)
    x, y = coordinate_system(n)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = x * radius, y * radius, n, centre
    return m


def read_toml(t) -> np.ndarray:
    for req in ("center", "normal"):
        if req not in t:
            raise t.error(f"missing '{req}'")
    normal = t.vector("normal")
    if not np.linalg.norm(normal) > 0:
        raise t.error("'normal' must not be the zero vector")
    radius = t.number("radius", 1.0, positive=True)
    if not np.float32(radius) > 0:
        raise t.error(f"'radius' {radius:g} is 0 in float32")
    return params(_frame_to_world(t.vector("center"), normal, radius), t.boolean("flip_normals", False))


def from_mitsuba(obj, read: ShapeMitsubaReading) -> np.ndarray:
    return params(np.eye(4) if read.to_world is None else read.to_world, read.flip)
