"""Ray/triangle, ray/box and ray/sphere helpers of cl/accel/intersect.h, each alone through a small
harness kernel, against float64 numpy references.  Runs on every available device."""
import numpy as np
import pytest

from pyopencl_rt.device import abi

import harness

HARNESS = harness.Kernels(r"""
#include "accel/intersect.h"

__kernel void h_triangle(__global const float *o, __global const float *d, __global const float *tri,
                         float tmin, float tmax, __global float *out)
{
    const int i = get_global_id(0);
    float t = 0, u = 0, v = 0;
    const float3 dd = load3(d, i);
    const int hit = intersect_triangle(load3(o, i), dd, ray_shear(dd), load3(tri, 3 * i), load3(tri, 3 * i + 1),
                                       load3(tri, 3 * i + 2), tmin, tmax, &t, &u, &v);
    out[4 * i] = hit; out[4 * i + 1] = t; out[4 * i + 2] = u; out[4 * i + 3] = v;
}

__kernel void h_box(__global const float *o, __global const float *d, __global const float *box,
                    float tmin, float tmax, __global float *out)
{
    const int i = get_global_id(0);
    const float3 dd = load3(d, i);
    out[i] = intersect_box(load3(o, i), safe_rcp3(dd), load3(box, 2 * i), load3(box, 2 * i + 1), tmin, tmax);
}

__kernel void h_sphere(__global const float *o, __global const float *d, __global const float *sph,
                       float tmin, float tmax, __global float *out)
{
    const int i = get_global_id(0);
    float t = 0;
    const int hit = intersect_sphere(pv3_from(load3(o, i)), pv3_from(load3(d, i)),
                                     pv3(sph[4 * i], sph[4 * i + 1], sph[4 * i + 2]), sph[4 * i + 3], tmin, tmax, &t,
                                     PTRUE);
    out[2 * i] = hit != 0; out[2 * i + 1] = t;
}

#define OFFSET_OF(field) (int)((__private char *)&probe.field - (__private char *)&probe)
__kernel void h_sizes(__global int *out)
{
    BVHNode probe;
    out[0] = sizeof(BVHNode);
    out[1] = OFFSET_OF(child_left);
    out[2] = OFFSET_OF(bmax_left);
    out[3] = OFFSET_OF(count_left);
    out[4] = OFFSET_OF(bmin_right);
    out[5] = OFFSET_OF(child_right);
    out[6] = OFFSET_OF(bmax_right);
    out[7] = OFFSET_OF(count_right);
}
""")


# ----------------------------------------------------------------------------- float64 references
def ref_triangle(o, d, p0, p1, p2):
    """Möller–Trumbore in float64 on the float32 inputs: t, barycentrics of p1 and p2, and
    the smallest barycentric (how far inside the triangle the ray passes)."""
    o, d, p0, p1, p2 = (np.asarray(a, np.float64) for a in (o, d, p0, p1, p2))
    e1, e2 = p1 - p0, p2 - p0
    pvec = np.cross(d, e2)
    det = np.sum(e1 * pvec, axis=1)
    inv = 1.0 / det
    tvec = o - p0
    u = np.sum(tvec * pvec, axis=1) * inv
    qvec = np.cross(tvec, e1)
    v = np.sum(d * qvec, axis=1) * inv
    t = np.sum(e2 * qvec, axis=1) * inv
    w = 1 - u - v
    return t, u, v, np.minimum(np.minimum(u, v), w)


def test_struct_layout_matches_numpy(runtime):
    """The OpenCL struct generated from abi.py has numpy's size and field offsets."""
    out = HARNESS(runtime, "h_sizes", 1, out=8)
    f = abi.BVH_NODE.fields
    expect = [abi.BVH_NODE.itemsize] + [f[n][1] for n in
              ("child_left", "bmax_left", "count_left", "bmin_right", "child_right", "bmax_right", "count_right")]
    assert out.tolist() == expect


def test_triangle_closed_form(runtime):
    """A ray down the z axis onto the triangle (0,0,1),(2,0,1),(0,2,1): t = 1/|d|-scaled, u, v exact."""
    tri = np.array([[0, 0, 1], [2, 0, 1], [0, 2, 1]], np.float32)
    o = np.array([[0.5, 0.25, -1.0], [0.5, 0.25, 3.0], [0.5, 0.25, -1.0], [3, 3, -1.0]], np.float32)
    d = np.array([[0, 0, 2.0], [0, 0, -1.0], [0, 0, -1.0], [0, 0, 1.0]], np.float32)
    out = HARNESS(runtime, "h_triangle", 4, o, d, np.tile(tri, (4, 1)), 0.0, np.inf, (4, 4))
    assert out[0].tolist() == [1.0, 1.0, 0.25, 0.125]     # t = 2 / |d| = 1; u = x/2, v = y/2
    assert out[1].tolist() == [1.0, 2.0, 0.25, 0.125]     # from above (back side): still a hit
    assert out[2, 0] == 0.0 and out[3, 0] == 0.0          # pointing away; outside
    # tmin / tmax are exclusive bounds on t
    assert HARNESS(runtime, "h_triangle", 1, o[:1], d[:1], tri, 1.0, np.inf, (1, 4))[0, 0] == 0.0
    assert HARNESS(runtime, "h_triangle", 1, o[:1], d[:1], tri, 0.0, 1.0, (1, 4))[0, 0] == 0.0
    assert HARNESS(runtime, "h_triangle", 1, o[:1], d[:1], tri, 0.99, 1.01, (1, 4))[0, 0] == 1.0


@pytest.mark.parametrize("scale", [1e-4, 1.0, 1e4])
def test_triangle_random_vs_float64(runtime, rng, scale):
    """Random rays at random triangles: hit/miss agrees with float64 except for rays passing
    within a relative 1e-6 (in barycentric terms) of an edge; t agrees to 1e-5 relative to the
    scale of the coordinates, u and v to 1e-5."""
    n = 200_000
    center = rng.normal(size=(n, 3)) * scale
    p = (center[:, None, :] + rng.normal(size=(n, 3, 3)) * scale).astype(np.float32)
    target = (p[:, 0] + (p[:, 1] - p[:, 0]) * rng.uniform(-0.2, 1.2, (n, 1))
              + (p[:, 2] - p[:, 0]) * rng.uniform(-0.2, 1.2, (n, 1)) * 0.6)
    o = (target + rng.normal(size=(n, 3)) * 3 * scale).astype(np.float32)
    d = (target - o).astype(np.float32)
    out = HARNESS(runtime, "h_triangle", n, o, d, p.reshape(-1, 3), 0.0, np.inf, (n, 4))
    t, u, v, inside = ref_triangle(o, d, p[:, 0], p[:, 1], p[:, 2])
    ref_hit = (inside >= 0) & (t > 0)
    hit = out[:, 0] == 1.0
    # t and the barycentrics are ill-conditioned for rays grazing the plane (error ~ 1/cos):
    # the strict comparisons hold where |cos| > 0.05; grazing rays count in the overall rate only.
    normal = np.cross(p[:, 1].astype(np.float64) - p[:, 0], p[:, 2].astype(np.float64) - p[:, 0])
    cos = np.abs(np.sum(normal * d, axis=1)) / (np.linalg.norm(normal, axis=1) * np.linalg.norm(d, axis=1))
    ambiguous = np.abs(inside) < 1e-6 * 4  # within ~1e-6 of an edge (plus float32 input rounding)
    disagree = (hit != ref_hit) & ~ambiguous & (cos > 0.05)
    assert disagree.sum() == 0, f"{disagree.sum()} clear-cut disagreements"
    assert (hit != ref_hit).mean() < 1e-4
    both = hit & ref_hit & ~ambiguous & (cos > 0.05)
    coord_scale = np.abs(o).max(axis=1) + np.abs(p).max(axis=(1, 2))
    t_err = np.abs(out[both, 1] - t[both]) * np.linalg.norm(d[both], axis=1) / coord_scale[both]
    assert t_err.max() < 1e-5
    # barycentrics: absolute error, on triangles that are not near-degenerate (float32 inputs
    # give the edge functions a relative error of a few ulp of the larger products)
    well_shaped = both & (np.abs(np.linalg.det(p.astype(np.float64) - o[:, None, :])) >
                          1e-3 * np.prod(np.linalg.norm(p.astype(np.float64) - o[:, None, :], axis=2), axis=1))
    assert np.abs(out[well_shaped, 2] - u[well_shaped]).max() < 1e-4
    assert np.abs(out[well_shaped, 3] - v[well_shaped]).max() < 1e-4


def test_triangle_watertight_shared_edges(runtime, rng):
    """Rays aimed exactly at the shared edge / shared vertex of a fan of triangles hit at least
    one of them (watertightness), for rays from many directions."""
    k = 7
    ang = np.linspace(0, 2 * np.pi, k, endpoint=False)
    rim = np.stack([np.cos(ang), np.sin(ang), np.zeros(k)], 1) * 3.3
    hub = np.array([0.1, -0.2, 0.0])
    tris = np.stack([np.broadcast_to(hub, rim.shape), rim, np.roll(rim, -1, axis=0)], 1).astype(np.float32)
    n = 20_000
    # points on the edges hub->rim[j] (shared by triangles j-1 and j), and the hub vertex itself
    j = rng.integers(0, k, n)
    s = rng.random(n)
    s[: n // 10] = 0.0  # exactly through the shared vertex
    target = hub + s[:, None] * (rim[j] - hub)
    o = (target + rng.normal(size=(n, 3)) * [1, 1, 4] + [0, 0, 5]).astype(np.float32)
    d = (target - o).astype(np.float32)
    hits = np.zeros(n, bool)
    for ti in range(k):
        out = HARNESS(runtime, "h_triangle", n, o, d, np.tile(tris[ti], (n, 1)), 0.0, np.inf, (n, 4))
        hits |= out[:, 0] == 1.0
    assert hits.all(), f"{(~hits).sum()} of {n} rays leaked through a shared edge or vertex"


def test_box_slab(runtime, rng):
    """Entry distances match float64; rays in the plane of a face and axis-parallel rays
    (1/0 = inf) behave; rays that touch the box are never missed."""
    n = 100_000
    lo = rng.normal(size=(n, 3)).astype(np.float32)
    hi = (lo + rng.random((n, 3)) * 2).astype(np.float32)
    target = lo + (hi - lo) * rng.uniform(-0.5, 1.5, (n, 3))
    o = (target + rng.normal(size=(n, 3)) * 4).astype(np.float32)
    d = (target - o).astype(np.float32)
    d[: n // 10, rng.integers(0, 3)] = 0.0  # axis-parallel components
    out = HARNESS(runtime, "h_box", n, o, d, np.stack([lo, hi], 1).reshape(-1, 3), 0.0, np.inf, n)
    o64, d64 = o.astype(np.float64), d.astype(np.float64)
    with np.errstate(divide="ignore", invalid="ignore"):
        inv = 1.0 / d64
        t0, t1 = (lo - o64) * inv, (hi - o64) * inv
    tn, tf = np.fmin(t0, t1), np.fmax(t0, t1)
    enter = np.maximum(np.nanmax(tn, axis=1), 0.0)
    leave = np.nanmin(tf, axis=1)
    ref_hit = enter <= leave
    margin = np.abs(leave - enter) <= 1e-5 * (np.abs(enter) + 1)
    hit = np.isfinite(out)
    assert (ref_hit & ~hit).sum() == 0, "a ray that crosses the box was reported as a miss"
    assert (hit & ~ref_hit & ~margin).sum() == 0
    both = hit & ref_hit
    assert np.allclose(out[both], enter[both], rtol=1e-5, atol=1e-5)
    # a ray lying exactly in the plane of a face
    o1 = np.array([[-1, 0.5, 0.0]], np.float32)
    d1 = np.array([[1, 0, 0.0]], np.float32)
    box = np.array([[0, 0, 0], [1, 1, 1]], np.float32)
    assert HARNESS(runtime, "h_box", 1, o1, d1, box, 0.0, np.inf, 1)[0] == pytest.approx(1.0)
    # tmax before the box: miss
    assert HARNESS(runtime, "h_box", 1, o1, d1, box, 0.0, 0.5, 1)[0] == np.inf


def test_sphere_closed_form(runtime):
    """Closed-form roots, including the factor of 2 of the half-b form and unnormalised d."""
    o = np.array([[0, 0, 0], [0, 0, 0], [5, 0, 0], [0, 0, 0], [0, 2, 0]], np.float32)
    d = np.array([[1, 0, 0], [2, 0, 0], [1, 0, 0], [-1, 0, 0], [1, 0, 0]], np.float32)
    sph = np.array([[5, 0, 0, 1]] * 5, np.float32)
    out = HARNESS(runtime, "h_sphere", 5, o, d, sph, 0.0, np.inf, (5, 2))
    assert out[0].tolist() == [1.0, 4.0]   # first root
    assert out[1].tolist() == [1.0, 2.0]   # |d| = 2 halves t
    assert out[2].tolist() == [1.0, 1.0]   # from the centre: the exit at t = r
    assert out[3, 0] == 0.0                # sphere behind the ray
    assert out[4, 0] == 0.0                # passes at distance 2 > r


def test_sphere_far_and_small_vs_float64(runtime, rng):
    """Spheres of radius 1e-3..1 at distances up to 1e4: the naive discriminant b^2 - ac loses
    every digit there; the stable form must agree with float64 on hit/miss (except within
    1e-3 r of tangency) and on t to 1e-5 relative."""
    n = 100_000
    radius = 10 ** rng.uniform(-3, 0, n)
    dist = 10 ** rng.uniform(0, 4, n)
    center = rng.normal(size=(n, 3))
    center *= (dist / np.linalg.norm(center, axis=1))[:, None]
    # aim at a point of the sphere's disc, sometimes beyond its rim
    offset = rng.normal(size=(n, 3))
    offset *= (radius * rng.uniform(0, 1.3, n) / np.linalg.norm(offset, axis=1))[:, None]
    o = np.zeros((n, 3), np.float32)
    d = (center + offset).astype(np.float32)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    sph = np.concatenate([center, radius[:, None]], 1).astype(np.float32)
    out = HARNESS(runtime, "h_sphere", n, o, d, sph, 0.0, np.inf, (n, 2))
    c64, r64, d64 = sph[:, :3].astype(np.float64), sph[:, 3].astype(np.float64), d.astype(np.float64)
    b = np.sum(c64 * d64, axis=1)
    perp = np.linalg.norm(c64 - b[:, None] * d64, axis=1)
    ref_hit = perp < r64
    near_tangent = np.abs(perp - r64) < 1e-3 * r64 + 1e-6 * dist
    hit = out[:, 0] == 1.0
    assert ((hit != ref_hit) & ~near_tangent).sum() == 0
    both = hit & ref_hit & ~near_tangent
    t_ref = b[both] - np.sqrt((r64[both] - perp[both]) * (r64[both] + perp[both]))
    assert (np.abs(out[both, 1] - t_ref) / t_ref).max() < 1e-5
