"""The emitter table for next-event estimation: every emissive triangle and sphere, picked in
proportion to its power (emitted radiance luminance x area x pi, x2 when two-sided)."""
from __future__ import annotations

import numpy as np

from . import layout
from .sampling import fill_light_table

LUMINANCE = np.array([0.2126, 0.7152, 0.0722])  # Rec. 709 / sRGB primaries


def build_lights(scene, bvh) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return (lights, tri_light, sphere_light): the LIGHT records and, per reordered triangle
    and per sphere, the index of its light record (-1 when it does not emit)."""
    mats = scene.materials
    emissive = np.array([m.is_emissive for m in mats] or [False])
    luminance = np.array([float(np.dot(m.emission, LUMINANCE)) for m in mats] or [0.0])
    sides = np.array([2.0 if m.two_sided else 1.0 for m in mats] or [1.0])

    tri_mat = scene.face_materials[bvh.prim_ids] if len(bvh.prim_ids) else np.zeros(0, np.int32)
    tri_idx = np.nonzero(emissive[tri_mat])[0] if len(tri_mat) else np.zeros(0, np.int64)
    tri = bvh.triangles
    if len(tri_idx):
        p0, p1, p2 = (tri[k][tri_idx, :3].astype(np.float64) for k in ("v0", "v1", "v2"))
        tri_area = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    else:
        tri_area = np.zeros(0)
    keep = tri_area > 0  # zero-area emitters cannot be sampled (and are never hit)
    tri_idx, tri_area = tri_idx[keep], tri_area[keep]

    sph_mat = scene.sphere_materials
    sph_idx = np.nonzero(emissive[sph_mat])[0] if len(sph_mat) else np.zeros(0, np.int64)
    sph_area = 4 * np.pi * scene.spheres[sph_idx, 3].astype(np.float64) ** 2 if len(sph_idx) else np.zeros(0)

    n = len(tri_idx) + len(sph_idx)
    lights = np.zeros(n, layout.LIGHT)
    tri_light = np.full(len(bvh.prim_ids), -1, np.int32)
    sphere_light = np.full(len(scene.spheres), -1, np.int32)
    if n == 0:
        return lights, tri_light, sphere_light
    k = len(tri_idx)
    lights["kind"][:k] = layout.LIGHT_TRIANGLE
    lights["prim"][:k] = tri_idx
    lights["material"][:k] = tri_mat[tri_idx]
    lights["area"][:k] = tri_area
    lights["kind"][k:] = layout.LIGHT_SPHERE
    lights["prim"][k:] = sph_idx
    lights["material"][k:] = sph_mat[sph_idx]
    lights["area"][k:] = sph_area
    tri_light[tri_idx] = np.arange(k, dtype=np.int32)
    sphere_light[sph_idx] = np.arange(k, n, dtype=np.int32)
    mat = lights["material"]
    power = luminance[mat] * lights["area"].astype(np.float64) * np.pi * sides[mat]
    if not (power > 0).any():  # e.g. pure blue emitters have luminance; this guards all-zero
        power = lights["area"].astype(np.float64)
    fill_light_table(lights, power)
    return lights, tri_light, sphere_light
