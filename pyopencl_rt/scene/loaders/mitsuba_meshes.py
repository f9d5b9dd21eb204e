"""Mitsuba 3's cube, disk and sphere as triangle meshes with Mitsuba's own vertex layout and uv
(src/shapes/cube.cpp, disk.cpp, sphere.cpp), for the XML importer: a texture, a normal map or an
anisotropic roughness on them then reads the uv that Mitsuba's intersection would give."""
from __future__ import annotations

import math

import numpy as np

from .builder import grid_mesh, sphere_mesh

# segments in a full turn of the cylinder's, the disk's and a textured sphere's polygon: its edges
# then lie within 1e-4 of a radius of Mitsuba's exact shape
CURVED_SEGMENTS = 256

def mitsuba_cube_mesh() -> tuple:
    """Mitsuba's cube (src/shapes/cube.cpp): [-1, 1]^3, every face's front outwards, its four
    vertices and two triangles (4s, 4s+1, 4s+2), (4s+3, 4s, 4s+2) and the uv (0, 1), (1, 1), (1, 0),
    (0, 0) of its corners exactly as Mitsuba lays them out (each face's uv axes are its own)."""
    corner = [4 * s + k for s in range(6) for k in range(4)]
    position_index = [1, 5, 4, 0, 3, 2, 6, 7, 1, 3, 7, 5, 5, 7, 6, 4, 4, 6, 2, 0, 3, 1, 0, 2]
    v = np.array([[1.0 if c & 1 else -1.0, 1.0 if c & 2 else -1.0, 1.0 if c & 4 else -1.0]
                  for c in position_index])
    side_uv = np.array([[0, 1], [1, 1], [1, 0], [0, 0]], np.float32)
    f = np.array([t for s in range(6) for t in ([4 * s, 4 * s + 1, 4 * s + 2], [4 * s + 3, 4 * s, 4 * s + 2])],
                 np.int64)
    uv = side_uv[np.asarray(corner) % 4][f]
    return v, f, uv


def mitsuba_disk_mesh(n_full: int = CURVED_SEGMENTS, rings: int = 32) -> tuple:
    """Mitsuba's disk (src/shapes/disk.cpp): the unit disk in the plane z = 0, front +z, uv = (r,
    phi / 2 pi), phi counter-clockwise from +x; ``n_full`` segments and ``rings`` rings (the
    uv interpolated across a triangle then stays within a thousandth of a radius of Mitsuba's),
    the radius scaled so that the polygon's area equals the disk's."""
    dphi = 2 * math.pi / n_full
    k = math.sqrt(dphi / math.sin(dphi))

    def fn(u, v):
        phi = u * 2 * math.pi
        r = k * (1.0 - v)
        return np.stack([r * np.cos(phi), r * np.sin(phi), np.zeros_like(u)], 1)

    v, f, uv = grid_mesh(fn, n_full, rings)  # dp/du (counter-clockwise) x dp/dv (inwards) = +z
    return v, f, np.stack([1.0 - uv[..., 1], uv[..., 0]], -1).astype(np.float32)


def mitsuba_sphere_mesh(n_phi: int = CURVED_SEGMENTS, n_theta: int = CURVED_SEGMENTS // 2) -> tuple:
    """Mitsuba's sphere (src/shapes/sphere.cpp) as triangles: the unit sphere, front outwards,
    uv = (phi / 2 pi, theta / pi) of the object-space direction, theta from +z and phi
    counter-clockwise from +x (so to_world's rotation turns the texture with the sphere), and
    its exact (radial) normal at each corner.  ``n_phi`` x ``n_theta`` quads: the polygon stays
    within 1e-4 of a radius of the sphere."""
    v, f, uv = sphere_mesh(1.0, n_theta=n_theta, n_full=n_phi)
    return v, f, uv, v[f]


def flat(vertices, faces, tolerance=1e-5) -> bool:
    """Whether every face of the mesh lies in one plane (its face normals parallel, to
    ``tolerance``), so that vertex normals, if it has any, are its face normal."""
    v = np.asarray(vertices, np.float64)[np.asarray(faces)]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    n = n[np.linalg.norm(n, axis=1) > 0]
    if len(n) == 0:
        return True
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    return bool((n @ n[0] > 1.0 - tolerance).all())
