"""Geometry the scene importers share: 4x4 transforms and the analytic shapes of Mitsuba and pbrt as
triangle meshes in object space (vertices, faces, per-corner uvs)."""
from __future__ import annotations

import math

import numpy as np

from ..lights.frames import transform_points, transform_vector  # noqa: F401 (the importers' own)


# transforms


def translate(v) -> np.ndarray:
    m = np.eye(4)
    m[:3, 3] = v
    return m


def scale(v) -> np.ndarray:
    return np.diag([float(v[0]), float(v[1]), float(v[2]), 1.0])


def rotate(axis, angle_degrees, normalize: bool = True) -> np.ndarray:
    """Right-handed rotation by ``angle_degrees`` about ``axis``: cos I + (1 - cos) a a^T + sin [a]x
    (Rodrigues), a the unit axis as pbrt's ``Rotate`` takes it, or (``normalize`` False) the axis as
    given, as Mitsuba 3's ``rotate`` does (not a rotation unless the axis is a unit vector)."""
    a = np.asarray(axis, np.float64)
    if normalize:
        a = a / np.linalg.norm(a)
    x, y, z = a
    t = math.radians(angle_degrees)
    m = np.eye(4)
    m[:3, :3] = (math.cos(t) * np.eye(3) + (1 - math.cos(t)) * np.outer(a, a)
                 + math.sin(t) * np.array([[0, -z, y], [z, 0, -x], [-y, x, 0]]))
    return m


def look_at_camera_to_world(origin, target, up) -> np.ndarray:
    """Mitsuba's ``look_at``: columns (left, up', forward, origin), left = up x forward."""
    origin, target, up = (np.asarray(x, np.float64) for x in (origin, target, up))
    d = target - origin
    d /= np.linalg.norm(d)
    left = np.cross(up, d)
    left /= np.linalg.norm(left)
    new_up = np.cross(d, left)
    m = np.eye(4)
    m[:3, 0], m[:3, 1], m[:3, 2], m[:3, 3] = left, new_up, d, origin
    return m


# --------------------------------------------------------------------------------------------
# primitives (object space), as (vertices, faces, per-corner uvs)


def quad_mesh(corners) -> tuple:
    """Corners p0..p3 counter-clockwise seen from the front: triangles (0,1,2), (0,2,3)."""
    v = np.asarray(corners, np.float64).reshape(4, 3)
    f = np.array([[0, 1, 2], [0, 2, 3]], np.int64)
    uv = np.array([[0, 0], [1, 0], [1, 1], [0, 1]], np.float32)[f]
    return v, f, uv


def rectangle_mesh() -> tuple:
    """Mitsuba's rectangle: [-1, 1]^2 in the plane z = 0, front +z, uv = ((x+1)/2, (y+1)/2)."""
    return quad_mesh([(-1, -1, 0), (1, -1, 0), (1, 1, 0), (-1, 1, 0)])


def grid_mesh(fn, nu: int, nv: int) -> tuple:
    """Triangles of a parametric surface p = fn(u, v), (u, v) in [0, 1]^2, on an nu x nv grid;
    the front is the side of dp/du x dp/dv."""
    u, v = np.meshgrid(np.linspace(0, 1, nu + 1), np.linspace(0, 1, nv + 1), indexing="xy")
    p = fn(u.ravel(), v.ravel())
    idx = np.arange((nu + 1) * (nv + 1)).reshape(nv + 1, nu + 1)
    a, b, c, d = idx[:-1, :-1].ravel(), idx[:-1, 1:].ravel(), idx[1:, 1:].ravel(), idx[1:, :-1].ravel()
    faces = np.concatenate([np.stack([a, b, c], 1), np.stack([a, c, d], 1)])
    p = np.asarray(p, np.float64)
    area = np.linalg.norm(np.cross(p[faces[:, 1]] - p[faces[:, 0]], p[faces[:, 2]] - p[faces[:, 0]]), axis=1)
    faces = faces[area > 1e-9 * area.max()]  # the collapsed ones at a disk's centre or a sphere's poles
    uv = np.stack([u.ravel(), v.ravel()], 1).astype(np.float32)[faces]
    return p, faces.astype(np.int64), uv


def _segments(phimax_degrees: float, n_full: int = 64) -> int:
    return max(3, int(math.ceil(n_full * phimax_degrees / 360.0)))


def disk_mesh(radius=1.0, inner=0.0, height=0.0, phimax=360.0) -> tuple:
    """A disk (annulus) in the plane z = height, front +z.  The radius is scaled so that the
    polygon's area equals the disk's."""
    n = _segments(phimax)
    dphi = math.radians(phimax) / n
    k = math.sqrt(dphi / math.sin(dphi)) if n >= 3 and dphi < math.pi else 1.0

    def fn(u, v):
        phi = u * math.radians(phimax)
        r = k * (radius + (inner - radius) * v)
        return np.stack([r * np.cos(phi), r * np.sin(phi), np.full_like(u, height)], 1)

    return grid_mesh(fn, n, 1)  # dp/du (counter-clockwise) x dp/dv (inwards) = +z


def cylinder_mesh(radius=1.0, zmin=-1.0, zmax=1.0, phimax=360.0, n_full: int = 64) -> tuple:
    """An open tube about z from zmin to zmax, front outwards; the radius is scaled so that the
    polygon's perimeter equals the circle's (and so the lateral area); uv = (phi / phimax, the
    height's fraction), pbrt's and Mitsuba's; ``n_full`` segments in a full turn."""
    n = _segments(phimax, n_full)
    dphi = math.radians(phimax) / n
    k = (dphi / 2) / math.sin(dphi / 2)

    def fn(u, v):
        phi = u * math.radians(phimax)
        return np.stack([k * radius * np.cos(phi), k * radius * np.sin(phi), zmin + (zmax - zmin) * v], 1)

    return grid_mesh(fn, n, 1)


def sphere_mesh(radius=1.0, zmin=None, zmax=None, phimax=360.0, n_theta: int = 32, n_full: int = 64) -> tuple:
    """A (partial) sphere as triangles, front outwards (pbrt's zmin, zmax, phimax)."""
    zmin = -radius if zmin is None else max(-radius, min(radius, zmin))
    zmax = radius if zmax is None else max(-radius, min(radius, zmax))
    t0, t1 = math.acos(max(-1.0, min(1.0, zmax / radius))), math.acos(max(-1.0, min(1.0, zmin / radius)))

    def fn(u, v):
        phi = u * math.radians(phimax)
        theta = t0 + (t1 - t0) * v
        return radius * np.stack([np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)], 1)

    v, f, uv = grid_mesh(fn, _segments(phimax, n_full), n_theta)
    return v, f[:, ::-1].copy(), uv[:, ::-1].copy()  # dp/du x dp/dtheta points inwards: reverse
