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
           "coordinate_system"]


def rows(p) -> np.ndarray:
    """(n, 28) float64 parameter blocks (one block of 28 as one row)."""
    return np.asarray(p, np.float64).reshape(-1, 28)


def affine_rows(m) -> np.ndarray:
    """The 3 x 4 part of a 4 x 4 affine map, its rows one after another (12 floats)."""
    return np.asarray(m, np.float64)[:3, :4].reshape(12)


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
