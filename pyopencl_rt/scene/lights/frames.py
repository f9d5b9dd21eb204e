"""What the light types share: the frame of a light aimed by a look-at, a to_world checked once,
the RGB of a record, and the luminance weights of light power."""
from __future__ import annotations

from dataclasses import replace

import numpy as np

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 / sRGB primaries


def look_at_frame(origin, target, up) -> np.ndarray:
    """The 3x3 local-to-world matrix of Mitsuba's ``lookat``: local +z toward ``target``, +y
    nearest ``up``, +x = y x z (its columns are the local axes in world space)."""
    d = np.asarray(target, np.float64) - np.asarray(origin, np.float64)
    if not np.linalg.norm(d) > 0:
        raise ValueError("look_at: the target is the origin")
    d /= np.linalg.norm(d)
    left = np.cross(np.asarray(up, np.float64), d)
    if not np.linalg.norm(left) > 0:
        raise ValueError("look_at: up is parallel to the viewing direction")
    left /= np.linalg.norm(left)
    return np.stack([left, np.cross(d, left), d], axis=1)


def checked_frame(to_world) -> np.ndarray:
    """A light's 3x3 local-to-world matrix (None: the identity), finite and invertible."""
    m = np.eye(3) if to_world is None else np.asarray(to_world, np.float64).reshape(3, 3)
    if not np.all(np.isfinite(m)) or abs(np.linalg.det(m)) < 1e-300:
        raise ValueError("a light's to_world must be a finite, invertible 3x3 matrix")
    return m


def record_rgb(x) -> np.ndarray:
    """An RGB value as a record holds it: finite and non-negative (others become 0)."""
    a = np.broadcast_to(np.asarray(x, np.float64), (3,))
    return np.where(np.isfinite(a), np.maximum(a, 0.0), 0.0)


def transform_points(m, p) -> np.ndarray:
    """(N, 3) float64 points ``p`` under the 4x4 affine map ``m`` (the importers' transform, here
    for the light types and scene/loaders/geometry.py alike)."""
    p = np.asarray(p, np.float64).reshape(-1, 3)
    return p @ m[:3, :3].T + m[:3, 3]


def transform_vector(m, v) -> np.ndarray:
    """The vector ``v`` under the linear part of the 4x4 map ``m``."""
    return np.asarray(m[:3, :3] @ np.asarray(v, np.float64), np.float64)


def affine_point(m, p) -> tuple:
    """One point under the 4x4 affine map ``m`` (a scene's mirror, a file's transform), as a tuple."""
    return tuple(transform_points(m, p)[0])


def floats(values) -> list:
    """Numbers as a list of Python floats (what an exported record holds)."""
    return [float(x) for x in values]


def transformed_framed(light, m):
    """A light with a position and a frame (spot, projector, goniometric) under the 4x4 affine map m."""
    return replace(light, position=affine_point(m, light.position), to_world=np.asarray(m)[:3, :3] @ light.frame())


def to_world_4x4(light) -> list:
    """A framed light's 4x4 local-to-world (its frame and position), as Mitsuba's to_world."""
    m = np.eye(4)
    m[:3, :3] = light.frame()
    m[:3, 3] = light.position
    return m.tolist()
