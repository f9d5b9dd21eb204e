"""What the analytic shape types share: their parameter blocks as float64 rows, affine maps of
points, and what a Mitsuba XML shape's reading gives its type (:class:`ShapeMitsubaReading`)."""
from __future__ import annotations

from dataclasses import dataclass
from typing import Callable

import math

import numpy as np

from ..instances import is_similarity
from ..lights.frames import transform_points

__all__ = ["ShapeMitsubaReading", "is_similarity", "rows", "transform_points", "affine_rows", "inverse_rows",
           "coordinate_system", "to_world_maps", "ring_box", "mapped_checks"]


def rows(p) -> np.ndarray:
    """(n, 28) float64 parameter blocks (one block of 28 as one row)."""
    return np.asarray(p, np.float64).reshape(-1, 28)


def affine_rows(m) -> np.ndarray:
    """The 3 x 4 part of a 4 x 4 affine map, its rows one after another (12 floats)."""
    return np.asarray(m, np.float64)[:3, :4].reshape(12)


def to_world_maps(p) -> np.ndarray:
    """(n, 4, 4) affine maps of parameter rows whose first 12 entries are a to_world's rows (a disk's,
    a tube's)."""
    p = rows(p)
    m = np.zeros((len(p), 4, 4))
    m[:, :3, :] = p[:, :12].reshape(-1, 3, 4)
    m[:, 3, 3] = 1.0
    return m


def ring_box(m, along_z: bool = False) -> tuple:
    """(lo, hi) of the images under the (n, 4, 4) maps m of the unit circle in z = 0 (and, with
    ``along_z``, of the one in z = 1 too: a tube): each centre plus or minus the length of each row of
    the circle's two axes."""
    half = np.sqrt(m[:, :3, 0] ** 2 + m[:, :3, 1] ** 2)
    c0 = m[:, :3, 3]
    c1 = c0 + m[:, :3, 2] if along_z else c0
    return np.minimum(c0, c1) - half, np.maximum(c0, c1) + half


def mapped_checks(p, area_at: int) -> list:
    """check() of a type whose rows hold a to_world and its area at ``area_at``: (row, what is wrong)
    where a parameter is not finite or the area is not positive in float32 (a to_world that flattens it)."""
    out = []
    for i, row in enumerate(rows(p)):
        if not np.isfinite(row).all():
            out.append((i, "its to_world is not finite"))
        elif not np.float32(row[area_at]) > 0:
            out.append((i, f"its area {row[area_at]:g} is not positive in float32 (a to_world that flattens it)"))
    return out


def inverse_rows(m) -> np.ndarray:
    """The 3 x 4 part of the inverse of a 4 x 4 affine map (12 floats)."""
    return np.linalg.inv(np.asarray(m, np.float64))[:3, :4].reshape(12)


def coordinate_system(n) -> tuple:
    """Mitsuba's coordinate_system (include/mitsuba/core/vector.h, Duff et al. 2017): two unit
    vectors s, t that make (s, t, n) a right-handed orthonormal frame; (x, y) for n = +z."""
    n = np.asarray(n, np.float64)
    sign = math.copysign(1.0, n[2])
    a = -1.0 / (sign + n[2])
    b = n[0] * n[1] * a
    return (np.array([n[0] * n[0] * a * sign + 1.0, b * sign, -n[0] * sign]),
            np.array([b, n[1] * n[1] * a + sign, -n[1]]))


@dataclass
class ShapeMitsubaReading:
    """A Mitsuba XML shape as its type's ``from_mitsuba(obj, read)`` gets it: its 4 x 4 to_world
    (None: the identity), its flip_normals, ``warn(what)``: one warning at the shape's line, and
    ``error(what)``: the error to raise, at that line."""

    to_world: np.ndarray | None
    flip: bool
    warn: Callable
    error: Callable
