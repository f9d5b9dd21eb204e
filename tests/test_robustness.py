"""Numerical robustness: watertightness, self-intersection, scale and translation invariance,
bad geometry, adversarial kernel inputs, and the NaN guard (issue 5; docs/ROBUSTNESS.md).

Every size-dependent test runs in two variants: the quick one (``make test``) and a long one
with more rays, meshes, scales and seeds, marked ``stress`` (deselected unless ``-m`` selects it:
``pytest -m stress``, which ``make stress`` runs; tests/conftest.py).  Every size is in QUICK and
LONG below.
"""
from __future__ import annotations

import math
import os
import warnings
import zlib
from dataclasses import dataclass

import numpy as np
import pytest
import trimesh
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import harness
from meshes import moller_trumbore, ray_edge_distance, slivers
from pyopencl_rt import build_bvh, load_scene, trace
from pyopencl_rt.errors import UserError
from pyopencl_rt.scene.mesh import load_mesh
from pyopencl_rt.render.api import render_full
from pyopencl_rt.scene.model import Camera, Material, RenderSettings, Scene
from pyopencl_rt.scene.shapes.sphere import records as sphere_records, of as sphere_of

# ---- sizes: quick (make test) / long (marked stress: make stress) -----------------------------
@dataclass(frozen=True)
class Sizes:
    """The sizes of the size-dependent tests: QUICK (``make test``), LONG (``-m stress``)."""
    name: str
    watertight_rays: int              # per mesh, untransformed
    watertight_rays_transformed: int  # per mesh and transform
    icospheres: tuple                 # subdivision levels
    uvsphere: tuple                   # sections of "uvsphere256"
    cone: int                         # sections of "cone4096"
    tori: tuple                       # (major, minor) sections
    transforms: tuple                 # (scale, translation) besides the mesh as built
    spawn_trials: int                 # per seed
    spawn_seeds: tuple
    invariance_spp: int
    invariance_cases: tuple
    hypothesis_examples: int
    hypothesis_batch: int
    scene_spp: int
    scene_res: int


# (scale, translation): the translated meshes are scaled to 1/100 of the translation so that
# float32 still resolves them (a unit sphere at 1e6 is quantised to 1/16 and is another mesh).
QUICK = Sizes("quick", watertight_rays=500_000, watertight_rays_transformed=100_000, icospheres=(1, 4),
              uvsphere=(64, 256), cone=1024, tori=((160, 64),), transforms=((1e-4, 0.0), (1e4, 0.0), (1e3, 1e5)),
              spawn_trials=200_000, spawn_seeds=(1,), invariance_spp=256, invariance_cases=((1e-3, 0.0), (1.0, 1e5)),
              hypothesis_examples=25, hypothesis_batch=1024, scene_spp=4, scene_res=16)
# Not x1e-3 moved by 1e5: that box is 0.556 wide where a float32 ulp is 0.0078 (70 ulps across),
# so its float32 input is another, coarser scene (`make stress` measured a 0.47x image).
LONG = Sizes("long", watertight_rays=10_000_000, watertight_rays_transformed=10_000_000,
             icospheres=(1, 2, 3, 4, 5, 6), uvsphere=(256, 256), cone=4096,
             tori=((8, 3), (32, 8), (160, 64), (1024, 256)),
             transforms=QUICK.transforms + ((1e4, 1e6), (1.0, 1e2)), spawn_trials=2_000_000,
             spawn_seeds=(1, 2, 3, 4, 5), invariance_spp=1024,
             invariance_cases=((1e-3, 0.0), (1e3, 0.0), (1.0, 1e5), (1.0, 1e6)),
             hypothesis_examples=300, hypothesis_batch=4096, scene_spp=16, scene_res=32)
WATERTIGHT_CHUNK = 2_000_000
INVARIANCE_RES = 32


def sized(cases=lambda sizes: [pytest.param()]):
    """Parameters ``(sizes, *case)`` of a size-dependent test: the cases of QUICK, then those of
    LONG marked ``stress``; ids start with the sizes' name ("quick-...", "long-...")."""
    out = []
    for s in (QUICK, LONG):
        for case in cases(s):
            out.append(pytest.param(s, *case.values, id="-".join(filter(None, (s.name, case.id))),
                                    marks=[*case.marks] + ([pytest.mark.stress] if s is LONG else [])))
    return out


# ================================================================================================
# 1. Watertightness: rays from inside closed meshes never escape
# ================================================================================================
def _cone(sections):
    """A cone whose apex (and base centre) is shared by `sections` triangles."""
    return trimesh.creation.cone(radius=1.0, height=2.0, sections=sections)


def _box(subdiv):
    m = trimesh.creation.box(extents=(2.0, 1.0, 0.5))
    for _ in range(subdiv):
        m = m.subdivide()
    return m


def mesh_specs(sizes):
    """name -> (builder, kind).  kind 'convex' or 'torus' selects how interior points are made."""
    specs = {f"icosphere{s}": (lambda s=s: trimesh.creation.icosphere(subdivisions=s), "convex")
             for s in sizes.icospheres}
    specs["uvsphere256"] = (lambda: trimesh.creation.uv_sphere(radius=1.0, count=list(sizes.uvsphere)), "convex")
    specs["cone4096"] = (lambda: _cone(sizes.cone), "convex")
    specs["box-subdiv3"] = (lambda: _box(3), "convex")
    specs["slivers"] = (lambda: trimesh.Trimesh(*slivers(), process=False), "convex")
    for M, m in sizes.tori:
        specs[f"torus{M}x{m}"] = (
            lambda M=M, m=m: trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=M, minor_sections=m),
            ("torus", M, m))
    return specs


def _convex_interior(v, f, n, rng, eps_lo=1e-4):
    """Origins strictly inside a convex mesh, and aim points on its vertices and edges.

    A third at the centroid, a third uniform in a ball of half the inradius around it, a third
    near the surface: q + eps (c - q) for q on a random edge or at a vertex, eps = 10^U(-4,-1)
    (a convex combination with an interior point: strictly inside; checked in float64 against
    the faces around q's edge after rounding to float32)."""
    # the box centre, not the vertex mean: the 4096-triangle cone's vertex mean lies 5e-4 above its
    # base, so "near-surface" origins pulled toward it were 3e-6 above the base and rounded onto it
    # at an offset of 100 (float32 ulp 7.6e-6): `make stress` counted those as 4% escapes
    c = 0.5 * (v.min(0) + v.max(0))
    p = v[f]
    nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    nrm /= np.linalg.norm(nrm, axis=1, keepdims=True)
    plane = np.einsum("ij,ij->i", nrm, p[:, 0] - c)  # > 0: outward normals
    assert (plane > 0).all(), "mesh is not convex with outward normals around its centroid"
    r_in = plane.min()
    k = n // 3
    o = np.empty((n, 3))
    o[:k] = c
    u = rng.normal(size=(k, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    o[k:2 * k] = c + u * (0.5 * r_in * rng.random((k, 1)) ** (1 / 3))
    m = n - 2 * k
    fi = rng.integers(0, len(f), m)
    e = rng.integers(0, 3, m)
    s = rng.random(m)
    s[: m // 4] = 0.0  # at a vertex
    a, b = p[fi, e], p[fi, (e + 1) % 3]
    q = a + s[:, None] * (b - a)
    eps = 10 ** rng.uniform(math.log10(eps_lo), -1, m)
    near = q + eps[:, None] * (c - q)
    o[2 * k:] = near
    # check (float64, after rounding to float32): a sample of 500 near-surface origins lies
    # strictly inside every face plane
    near32 = near.astype(np.float32).astype(np.float64)
    pick = near32[rng.integers(0, m, min(m, 500))]
    for lo in range(0, len(f), 20_000):
        side = (pick @ nrm[lo:lo + 20_000].T) - np.einsum("ij,ij->i", nrm[lo:lo + 20_000], p[lo:lo + 20_000, 0])
        assert (side < 0).all(), "a near-surface origin is not strictly inside"
    return o, c


def _torus_interior(M, m, n, rng, R=1.0, r=0.3):
    """Origins inside a torus tessellated with M major and m minor sections: within a ball of
    the tube's centre circle that the tessellated tube contains.  Its cross-section polygon has
    inradius r cos(pi/m), and its axis, an M-gon, strays up to R (1 - cos(pi/M)) from the circle,
    so 0.9 (r cos(pi/m) - R (1 - cos(pi/M))) is safe: 0.066 for 8x3.  (A first version used
    0.4 r = 0.12 there, and 0.2% of its "interior" origins of the 8x3 torus were outside it --
    trimesh's contains() -- which `make stress` reported as 5299 escapes in 10M rays.)"""
    safe = 0.9 * (r * np.cos(np.pi / m) - R * (1.0 - np.cos(np.pi / M)))
    assert safe > 0
    phi = rng.uniform(0, 2 * np.pi, n)
    ctr = np.stack([R * np.cos(phi), R * np.sin(phi), np.zeros(n)], 1)
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    return ctr + w * (safe * rng.random(n))[:, None], None


def watertight_rays(v, f, kind, n, rng, eps_lo=1e-4):
    """(origins, aim-or-direction) in float64: half random directions, half aimed at random
    vertices and edge points of the mesh (where leaks happen)."""
    if kind == "convex":
        o, _ = _convex_interior(v, f, n, rng, eps_lo)
    else:
        o, _ = _torus_interior(kind[1], kind[2], n, rng)
    d = rng.normal(size=(n, 3))
    h = n // 2
    p = v[f[rng.integers(0, len(f), n - h)]]
    e = rng.integers(0, 3, n - h)
    s = rng.random(n - h)
    s[: (n - h) // 3] = 0.0
    i = np.arange(n - h)
    target = p[i, e] + s[:, None] * (p[i, (e + 1) % 3] - p[i, e])
    d[h:] = target - o[h:]
    return o, d


def count_escapes(v, f, kind, n, rng, device, scale=1.0, shift=0.0):
    """Rays from inside; returns (escapes, rays).  Mesh and rays transformed together in float64,
    then rounded to float32."""
    v32 = (v * scale + shift).astype(np.float32)
    bvh = build_bvh(v32, f.astype(np.int32))
    esc = 0
    done = 0
    while done < n:
        m = min(WATERTIGHT_CHUNK, n - done)
        # far from the origin, float32 resolves 2^-24 (|shift| + extent): stay 1e3 x that inside
        eps_lo = max(1e-4, 1e3 * 2.0**-24 * (abs(shift) + scale * np.abs(v).max()) / (scale * np.abs(v).max()))
        o, d = watertight_rays(v, f, kind, m, rng, min(eps_lo, 0.05))
        o = (o * scale + shift).astype(np.float32)
        d = (d * scale).astype(np.float32)
        res = trace(bvh, o, d, device=device)
        esc += int(np.count_nonzero(res["prim_id"] < 0))
        done += m
    return esc, done


@pytest.fixture(scope="module")
def closed_meshes():
    """closed_meshes(sizes, name) -> (v, f, kind), built on first use."""
    out = {}

    def get(sizes, name):
        key = (sizes.name, name)
        if key not in out:
            make, kind = mesh_specs(sizes)[name]
            m = make()
            v, f = np.asarray(m.vertices, np.float64), np.asarray(m.faces, np.int64)
            if name == "slivers":
                v = v.astype(np.float32).astype(np.float64)
            out[key] = (v, f, kind)
        return out[key]

    return get


@pytest.mark.parametrize("sizes,mesh,scale,shift", sized(lambda s: [
    pytest.param(mesh, scale, shift, id=f"{mesh}-x{scale:g}+{shift:g}")
    for mesh in mesh_specs(s) for scale, shift in ((1.0, 0.0),) + s.transforms]))
def test_watertight_no_escape(device, closed_meshes, measured, sizes, mesh, scale, shift):
    """0 escapes among the rays from inside (centre, interior, 1e-4..1e-1 from the surface),
    half of them aimed exactly at vertices and edges: watertight_rays for the mesh as built,
    watertight_rays_transformed for it scaled by 1e-4 and 1e4 and translated far away."""
    v, f, kind = closed_meshes(sizes, mesh)
    assert trimesh.Trimesh(v, f, process=False).is_watertight
    rng = np.random.default_rng(zlib.crc32(f"{mesh} {scale} {shift}".encode()))
    n = sizes.watertight_rays if (scale, shift) == (1.0, 0.0) else sizes.watertight_rays_transformed
    esc, n = count_escapes(v, f, kind, n, rng, device, scale, shift)
    measured(f"watertight {mesh} x{scale:g} +{shift:g}: {esc} escapes / {n} rays")
    assert esc == 0, f"{mesh} scaled {scale:g}, shifted {shift:g}: {esc} of {n} rays escaped"


def test_watertight_counter_detects_a_hole(device, closed_meshes):
    """The escape count is not vacuous: remove 1% of an icosphere's faces and rays leak."""
    v, f, kind = closed_meshes(QUICK, "icosphere4")
    rng = np.random.default_rng(9)
    holed = f[rng.random(len(f)) > 0.01]
    esc, n = count_escapes(v, holed, kind, 100_000, rng, device)
    assert esc > 100


# ================================================================================================
# 2. Self-intersection: spawned rays never hit their own surface
# ================================================================================================
SPAWN_HARNESS = harness.Kernels(r"""
#include "accel/intersect.h"
#include "render/spawn.h"

RT_INLINE int hits(float3 o, float3 d, float3 p0, float3 p1, float3 p2, float tmax)
{
    float t, u, v;
    return intersect_triangle(o, d, ray_shear(d), p0, p1, p2, 0.0f, tmax, &t, &u, &v);
}

/* For trial i: triangle tri[3i..3i+2]; a camera-like ray from oh[i] at the point with
 * barycentrics bary[i] finds the hit (t, u, v); the hit point is rebuilt from (u, v) as the
 * renderer should (triangle_point), or taken as o + t*d as shade.cl does (MODE 1); a ray leaves
 * it along w[i] (on either side) from offset_ray_origin_bound.  Then a shadow ray runs from the
 * spawn point to a point on a light triangle lt[3i..3i+2] (barycentrics bary[i] again), itself
 * offset toward the shading point as shade.cl does.
 * out[i]: -1 no valid trial (degenerate triangle or the camera ray missed);
 *         bit 0: the leaving ray hit its own triangle; bit 1: the shadow ray hit the source
 *         triangle; bit 2: the shadow ray hit the light triangle before reaching it. */
__kernel void h_spawn(__global const float *tri, __global const float *bary, __global const float *w,
                      __global const float *oh, __global const float *lt, int mode, float light_tmax,
                      __global int *out)
{
    const int i = get_global_id(0);
    const float3 p0 = load3(tri, 3 * i), p1 = load3(tri, 3 * i + 1), p2 = load3(tri, 3 * i + 2);
    const float3 c = cross(p1 - p0, p2 - p0);
    const float cc = dot(c, c);
    const float3 wi = load3(w, i);
    const float b1 = bary[2 * i], b2 = bary[2 * i + 1];
    pvec3 err;
    const float3 target = pv3_lane(triangle_point(pv3_from(p0), pv3_from(p1), pv3_from(p2), b1, b2, &err), 0);
    const float3 o = load3(oh, i), d = target - o;
    float t, u, v;
    if (!(cc > 0.0f && isfinite(cc)) ||
        !intersect_triangle(o, d, ray_shear(d), p0, p1, p2, 0.0f, INFINITY, &t, &u, &v)) {
        out[i] = -1;
        return;
    }
    const float3 ng = normalize(c);
    float3 p = pv3_lane(triangle_point(pv3_from(p0), pv3_from(p1), pv3_from(p2), u, v, &err), 0);
    if (mode == 1) { p = o + t * d; err = pv3_zero(); }
    int res = 0;
    const float3 n = dot(ng, wi) > 0.0f ? ng : -ng;
    const float3 so = pv3_lane(offset_ray_origin_bound(pv3_from(p), err, pv3_from(n)), 0);
    if (hits(so, wi, p0, p1, p2, INFINITY)) res |= 1;
    /* shadow ray toward the light triangle's point */
    const float3 l0 = load3(lt, 3 * i), l1 = load3(lt, 3 * i + 1), l2 = load3(lt, 3 * i + 2);
    const float3 lc = cross(l1 - l0, l2 - l0);
    /* as light_sample() decides it; 0: no sample */
    const float side = plane_distance(pv3_from(l0), pv3_from(l1), pv3_from(l2), pv3_from(so), PTRUE);
    if (dot(lc, lc) > 0.0f && side != 0.0f) {
        pvec3 lerr;
        const pvec3 lp = triangle_point(pv3_from(l0), pv3_from(l1), pv3_from(l2), b1, b2, &lerr);
        float3 ln = normalize(lc);
        if (side < 0.0f) ln = -ln;
        const float3 sp = pv3_lane(offset_ray_origin_bound(lp, lerr, pv3_from(ln)), 0);
        const float3 sd = sp - so;
        if (dot(sd, n) > 0.0f) { /* the light is on the side the ray leaves to */
            if (hits(so, sd, p0, p1, p2, 1.0f)) res |= 2;
            if (hits(so, sd, l0, l1, l2, light_tmax)) res |= 4;
        }
    }
    out[i] = res;
}
""")


def spawn_trials(n, rng, slivers_only=False):
    """Random triangles of scale 10^U(-4, 6) at 10^U(-4, 6) from the origin (20% at the origin),
    a point inside, a camera 10^U(-1, 3) triangle sizes away, a direction, and a light triangle
    facing the point from 10^U(-2, 2) triangle sizes.  Float64, rounded to float32."""
    s = 10 ** rng.uniform(-4, 6, n)
    u = rng.normal(size=(n, 3))
    u /= np.linalg.norm(u, axis=1, keepdims=True)
    mag = 10 ** rng.uniform(-4, 6, n)
    mag[rng.random(n) < 0.2] = 0.0
    c = u * mag[:, None]
    tri = c[:, None] + s[:, None, None] * rng.normal(size=(n, 3, 3))
    if slivers_only:  # the third vertex within 1e-2..1e-4 (relative) of the first edge's line
        t = rng.uniform(-0.5, 1.5, (n, 1))
        off = rng.normal(size=(n, 3)) * (10 ** rng.uniform(-4, -2, n) * s)[:, None]
        tri[:, 2] = tri[:, 0] + t * (tri[:, 1] - tri[:, 0]) + off
    r1, r2 = rng.random(n), rng.random(n)
    sq = np.sqrt(r1)
    bary = np.stack([sq * (1 - r2), sq * r2], 1)
    pt = (1 - bary.sum(1))[:, None] * tri[:, 0] + bary[:, :1] * tri[:, 1] + bary[:, 1:] * tri[:, 2]
    w = rng.normal(size=(n, 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    graze = rng.random(n) < 0.1  # 10% within 1e-1..1e-5 rad of the plane
    nrm = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    tang = w - np.sum(w * nrm, 1, keepdims=True) * nrm
    tang /= np.maximum(np.linalg.norm(tang, axis=1, keepdims=True), 1e-300)
    ang = 10 ** rng.uniform(-5, -1, n) * np.sign(rng.random(n) - 0.5)
    w[graze] = (np.cos(ang)[:, None] * tang + np.sin(ang)[:, None] * nrm)[graze]
    od = rng.normal(size=(n, 3))
    od /= np.linalg.norm(od, axis=1, keepdims=True)
    oh = pt + od * (s * 10 ** rng.uniform(-1, 3, n))[:, None]
    # light: an equilateral triangle of size ~s centred near pt + dist * w, facing pt
    dist = s * 10 ** rng.uniform(-2, 2, n)
    lc = pt + dist[:, None] * w
    a1 = rng.normal(size=(n, 3))
    a1 -= np.sum(a1 * w, 1, keepdims=True) * w
    a1 /= np.linalg.norm(a1, axis=1, keepdims=True)
    a2 = np.cross(w, a1)
    ls = (s * 10 ** rng.uniform(-1, 1, n))[:, None]
    lt = np.stack([lc + ls * a1, lc + ls * (-0.5 * a1 + 0.866 * a2), lc + ls * (-0.5 * a1 - 0.866 * a2)], 1)
    f32 = lambda a: np.ascontiguousarray(a, np.float32)  # noqa: E731
    return f32(tri), f32(bary), f32(w), f32(oh), f32(lt)


def min_angle_sine(tri):
    """float64: the sine of each triangle's smallest angle (0 for a degenerate one)."""
    p = tri.astype(np.float64)
    e = [p[:, (k + 1) % 3] - p[:, k] for k in range(3)]
    ln = [np.linalg.norm(x, axis=1) for x in e]
    area2 = np.linalg.norm(np.cross(e[0], e[1]), axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        s = np.nan_to_num(area2 / np.maximum(np.maximum(ln[0] * ln[1], ln[1] * ln[2]), ln[2] * ln[0]))
    return s


SHADOW_TMAX = 1.0 - 1e-4  # pbrt's 1 - ShadowEpsilon; cl/wavefront/shadow.cl uses 1 (both tested below)


def run_spawn(runtime, arrays, mode=0, light_tmax=SHADOW_TMAX):
    n = len(arrays[0])
    return SPAWN_HARNESS(runtime, "h_spawn", n, *arrays, mode=mode, light_tmax=light_tmax, out=n)


def spawn_failures(out, keep=None):
    valid = out >= 0
    if keep is not None:
        valid &= keep
    return {"trials": int(valid.sum()), "self": int(np.count_nonzero(valid & (out & 1 > 0))),
            "shadow_source": int(np.count_nonzero(valid & (out & 2 > 0))),
            "shadow_light": int(np.count_nonzero(valid & (out & 4 > 0)))}


SLIVER_SINE = 0.01  # triangles whose smallest angle is below ~0.6 degrees: test_spawn_on_slivers


@pytest.mark.parametrize("sizes,seed", sized(lambda s: [pytest.param(seed, id=str(seed)) for seed in s.spawn_seeds]))
def test_spawn_never_hits_own_triangle(runtime, measured, sizes, seed):
    """pbrt's test: random triangles (scale 1e-4..1e6, up to 1e6 from the origin; smallest angle
    above 0.6 degrees, slivers below); the hit point rebuilt from the hit's barycentrics and
    offset by offset_ray_origin_bound: a ray leaving it (10% grazing, down to 1e-5 rad) never
    hits its own triangle, and a shadow ray to a point on a light triangle on that side (offset
    toward the shading point likewise) is not blocked by the source triangle (t < 1)."""
    rng = np.random.default_rng(seed)
    arrays = spawn_trials(sizes.spawn_trials, rng)
    r = spawn_failures(run_spawn(runtime, arrays), keep=min_angle_sine(arrays[0]) >= SLIVER_SINE)
    measured(f"spawn seed {seed}: {r}")
    assert r["trials"] > 0.85 * sizes.spawn_trials
    assert r["self"] == 0 and r["shadow_source"] == 0, r  # the light end: test_shadow_ray_not_blocked_by_the_light


@pytest.mark.parametrize("sizes", sized())
def test_spawn_on_slivers(runtime, measured, sizes):
    """The same on slivers (third vertex 1e-4..1e-2 relative from the first edge's line)."""
    rng = np.random.default_rng(11)
    r = spawn_failures(run_spawn(runtime, spawn_trials(sizes.spawn_trials // 2, rng, slivers_only=True)))
    measured(f"spawn slivers: {r}")
    assert r["self"] == 0 and r["shadow_source"] == 0, r
    assert r["shadow_light"] == 0, r  # `make stress` saw 5 in 850k before plane_distance (spawn.h)


@pytest.mark.parametrize("sizes", sized())
def test_shadow_ray_not_blocked_by_the_light(runtime, measured, sizes):
    """The light end of the shadow rays of test_spawn_never_hits_own_triangle, at pbrt's tmax
    1 - 1e-4 and at cl/wavefront/shadow.cl's 1.  (Deciding the light's side from the sampled
    point, whose rounding grows with |p|, blocked ~2e-5 of them far from the origin: the shading
    point was closer to the light's plane than that rounding; cl/render/spawn.h plane_distance.)"""
    rng = np.random.default_rng(1)
    arrays = spawn_trials(sizes.spawn_trials, rng)
    keep = min_angle_sine(arrays[0]) >= SLIVER_SINE
    for tmax in (SHADOW_TMAX, 1.0):
        r = spawn_failures(run_spawn(runtime, arrays, light_tmax=tmax), keep=keep)
        measured(f"shadow rays blocked by the light, tmax {tmax}: {r}")
        assert r["trials"] > 0.85 * sizes.spawn_trials
        assert r["shadow_light"] == 0, r


def test_spawn_from_o_plus_td_is_not_enough(runtime):
    """Why the hit point must come from barycentrics: p = o + t*d (as cl/wavefront/shade.cl
    computed it until the Mitsuba comparison exposed the bias) carries the rounding of |o|, and with the camera 10^U(-1,3) triangle sizes
    away the Wächter-Binder offset of p alone leaves percent-level self-hits.  (Documents the
    failure mode: the test fails if that ever stops being true, i.e. if the harness is broken.)"""
    rng = np.random.default_rng(1)
    r = spawn_failures(run_spawn(runtime, spawn_trials(50_000, rng), mode=1))
    assert r["self"] > 0.001 * r["trials"], r


# ================================================================================================
# 3. Scale and translation invariance of a rendered image
# ================================================================================================
def tile_means(image, var, k=8):
    h, w, c = image.shape
    m = image.astype(np.float64).reshape(h // k, k, w // k, k, c).mean(axis=(1, 3))
    v = var.reshape(h // k, k, w // k, k, c).sum(axis=(1, 3)) / (k * k) ** 2
    return m, v


def transformed(scene: Scene, scale: float, shift: float) -> Scene:
    """The scene's geometry and camera (eye, look_at; up unchanged) scaled then translated by
    (shift, shift, shift), in float64, then rounded to float32."""
    import dataclasses

    v = (scene.vertices.astype(np.float64) * scale + shift).astype(np.float32)
    cam = scene.camera
    f = lambda p: tuple(float(x) for x in (np.asarray(p, np.float64) * scale + shift))  # noqa: E731
    sph = sphere_of(scene.shapes).astype(np.float64).copy()
    if len(sph):
        sph[:, :3] = sph[:, :3] * scale + shift
        sph[:, 3] *= scale
    return dataclasses.replace(scene, vertices=v, shapes=sphere_records(sph.astype(np.float32)),
                               camera=Camera(eye=f(cam.eye), look_at=f(cam.look_at), up=cam.up, fov=cam.fov))


@pytest.fixture(scope="module")
def cornell_reference(request):
    scene = load_scene("scenes/cornell-box.toml")
    return scene, {}


@pytest.mark.parametrize("sizes,scale,shift", sized(lambda sz: [pytest.param(s, t, id=f"x{s:g}+{t:g}")
                                                                 for s, t in sz.invariance_cases]))
def test_cornell_box_scale_translation_invariance(device, cornell_reference, measured, sizes, scale, shift):
    """The Cornell box scaled and/or translated renders the unscaled image within noise:
    tile-wise z-test (8x8-pixel tiles x 3 channels = 48 tests; |z| < 4.2 is a 1e-3 overall
    false-alarm rate by Bonferroni), independent seeds; no non-finite sample."""
    scene, cache = cornell_reference
    key = (str(device), sizes.invariance_spp)
    if key not in cache:
        r = render_full(scene, spp=sizes.invariance_spp, device=device, seed=1, width=INVARIANCE_RES,
                        height=INVARIANCE_RES)
        assert r.info["nonfinite_samples"] == 0
        cache[key] = tile_means(r.image, r.film.variance_of_mean())
    m0, v0 = cache[key]
    r = render_full(transformed(scene, scale, shift), spp=sizes.invariance_spp, device=device, seed=2,
                    width=INVARIANCE_RES, height=INVARIANCE_RES)
    assert r.info["nonfinite_samples"] == 0 and np.isfinite(r.image).all()
    m1, v1 = tile_means(r.image, r.film.variance_of_mean())
    z = (m1 - m0) / np.sqrt(v0 + v1)
    measured(f"invariance x{scale:g} +{shift:g}: max |z| {np.abs(z).max():.2f}, mean ratio {m1.mean() / m0.mean():.4f}")
    assert np.abs(z).max() < 4.2, f"max |z| = {np.abs(z).max():.2f}, mean ratio {m1.mean() / m0.mean():.4f}"


def far_camera_plane(camera_distance):
    """A 2x2 diffuse plane (albedo rho) at the origin under a uniform sky (radiance L, a huge
    emissive sphere) seen from `camera_distance` away with a narrow field of view: every pixel
    is rho * L."""
    v = np.array([[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], np.float32)
    f = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    eye = np.array([0.3, 1.0, 0.2]) * camera_distance
    fov = math.degrees(2 * math.atan(0.5 / np.linalg.norm(eye)))
    return Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32),
                 materials=[Material("plane", albedo=(0.3,) * 3),
                            Material("sky", albedo=(0, 0, 0), emission=(2.0,) * 3, two_sided=True)],
                 camera=Camera(eye=tuple(eye), look_at=(0, 0, 0), up=(0, 1, 0), fov=fov),
                 shapes=sphere_records(np.array([[0, 0, 0, 100 * camera_distance]], np.float32)),
                 shape_materials=np.array([1], np.int32),
                 settings=RenderSettings(width=16, height=16, max_depth=3))


@pytest.mark.parametrize("distance", [10.0, 1e4])
def test_far_camera_sees_no_self_shadowing(device, distance):
    """Radiance rho * L of a plane under a uniform sky, whatever the camera distance."""
    r = render_full(far_camera_plane(distance), spp=64, device=device, seed=4)
    assert r.info["nonfinite_samples"] == 0
    m = float(r.image.mean())
    se = float(r.image.std()) / np.sqrt(r.image.size)
    assert abs(m - 0.6) <= 4 * se + 1e-4, f"mean {m:.4f} vs 0.6 (se {se:.2g})"


# ================================================================================================
# 4. Bad geometry: rejected with a clear message or dropped with a warning; never a NaN pixel
# ================================================================================================
GOOD = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\n"
BAD_OBJS = {
    "zero-area": GOOD + "f 1 2 3\nf 1 1 2\nf 2 2 2\n",
    "collinear": GOOD + "v 2 0 0\nf 1 2 3\nf 1 2 5\n",
    "duplicate-vertices": GOOD + "v 0 0 0\nv 1 0 0\nf 1 2 3\nf 5 6 3\nf 2 4 3\n",
    "nan": GOOD + "v nan 0 0\nf 1 2 3\nf 5 2 3\n",
    "inf": GOOD + "v inf 0 0\nv 0 -inf 1\nf 1 2 3\nf 5 2 3\nf 6 2 3\n",
    "overflow": GOOD + "v 1e39 0 0\nf 1 2 3\nf 5 2 3\n",
    "tiny": "v 0 0 0\nv 1e-30 0 0\nv 0 1e-30 0\nf 1 2 3\n",
    "huge": "v -1e30 0 -1e30\nv 1e30 0 -1e30\nv 0 0 1e30\nf 1 2 3\n",
    "empty": "# nothing\n",
    "only-vertices": GOOD,
    "all-nan": "v nan nan nan\nv nan 0 0\nv 0 nan 0\nf 1 2 3\n",
}


def _light_toml(mesh_name, mesh_material):
    return harness.toml_tables(camera=dict(eye=[0.5, 0.5, 3.0], look_at=[0.5, 0.5, 0.0], fov=60),
                               film=dict(width=16, height=16), render=dict(spp=4, max_depth=4)) + f"""
[materials.white]
albedo = [0.8, 0.8, 0.8]
[materials.light]
albedo = [0.0, 0.0, 0.0]
emission = [5.0, 5.0, 5.0]
two_sided = true
[[shape]]
type = "mesh"
file = "{mesh_name}"
material = "{mesh_material}"
[[shape]]
type = "quad"
material = "light"
points = [[-2, -2, 2], [2, -2, 2], [2, 2, 2], [-2, 2, 2]]
"""


def _one_line_naming(exc, path):
    msg = str(exc)
    return "\n" not in msg and os.path.basename(str(path)) in msg


def _load_checked(fn, path, mesh_path=None):
    """Call a loader: a UserError naming the file, or success with any warnings naming it too."""
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        try:
            out = fn(path)
        except UserError as exc:
            assert _one_line_naming(exc, path), str(exc)
            return None, caught
    names = {os.path.basename(str(path))} | ({os.path.basename(str(mesh_path))} if mesh_path else set())
    for w in caught:
        assert any(nm in str(w.message) for nm in names), str(w.message)
    return out, caught


@pytest.mark.parametrize("case", list(BAD_OBJS))
@pytest.mark.parametrize("fmt", ["obj", "ply"])
def test_bad_geometry_loads_or_fails_cleanly_and_renders_finite(device, tmp_path, case, fmt):
    """Each bad mesh, as OBJ and PLY: load_mesh and load_scene either raise a one-line
    UserError naming the file, or succeed (dropped faces warned with their count); a TOML scene
    using it (plain and as an emitter) renders an all-finite image with no non-finite sample."""
    path = tmp_path / f"{case}.obj"
    path.write_text(BAD_OBJS[case])
    if fmt == "ply":
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            v, f = _parse_obj(BAD_OBJS[case])
            ply = tmp_path / f"{case}.ply"
            head = (f"ply\nformat ascii 1.0\nelement vertex {len(v)}\nproperty float x\nproperty float y\n"
                    f"property float z\nelement face {len(f)}\nproperty list uchar int vertex_indices\nend_header\n")
            body = "".join(f"{a!r} {b!r} {c!r}\n" for a, b, c in v.tolist()) + "".join(f"3 {a} {b} {c}\n" for a, b, c in f.tolist())
            ply.write_text(head + body)
            path = ply
    res, caught = _load_checked(load_mesh, path)
    if res is not None:
        v, f = res
        assert np.isfinite(v).all()
        if any("NaN" in str(w.message) for w in caught):
            assert any(ch.isdigit() for w in caught for ch in str(w.message))
    for material in ("white", "light"):
        scene_path = tmp_path / f"scene-{material}.toml"
        scene_path.write_text(_light_toml(path.name, material))
        scene, _ = _load_checked(load_scene, scene_path, mesh_path=path)
        if scene is None:
            continue
        r = render_full(scene, device=device, seed=1)
        assert r.info["nonfinite_samples"] == 0
        assert np.isfinite(r.image).all()
    # the mesh file alone as a scene
    scene, _ = _load_checked(load_scene, path)
    if scene is not None:
        r = render_full(scene, device=device, seed=1, spp=2, width=8, height=8)
        assert r.info["nonfinite_samples"] == 0 and np.isfinite(r.image).all()


def _parse_obj(text):
    v, f = [], []
    for line in text.splitlines():
        w = line.split()
        if w and w[0] == "v":
            v.append([float(x) for x in w[1:4]])
        elif w and w[0] == "f":
            f.append([int(x) - 1 for x in w[1:4]])
    return np.array(v, np.float64).reshape(-1, 3), np.array(f, np.int64).reshape(-1, 3)


def test_nan_vertices_are_dropped_with_count(tmp_path):
    """NaN/Inf vertices: their faces are dropped, with a warning naming the file and the counts."""
    path = tmp_path / "inf.obj"
    path.write_text(BAD_OBJS["inf"])
    with pytest.warns(UserWarning) as rec:
        v, f = load_mesh(path)
    msg = " ".join(str(w.message) for w in rec)
    assert "inf.obj" in msg and "2 vertices" in msg and "2 faces" in msg
    assert len(f) == 1 and np.isfinite(v).all()


def test_empty_mesh_is_rejected_naming_the_file(tmp_path):
    path = tmp_path / "empty.obj"
    path.write_text(BAD_OBJS["empty"])
    with pytest.raises(UserError) as exc:
        load_scene(path)
    assert "empty.obj" in str(exc.value) and "\n" not in str(exc.value)


# ================================================================================================
# 5. Adversarial inputs: intersect_triangle against float64 (hypothesis)
# ================================================================================================
TRI_HARNESS = harness.Kernels(r"""
#include "accel/intersect.h"
__kernel void h_tri(__global const float *o, __global const float *d, __global const float *tri,
                    __global float *out)
{
    const int i = get_global_id(0);
    float t = 0, u = 0, v = 0;
    const float3 dd = load3(d, i);
    const int hit = intersect_triangle(load3(o, i), dd, ray_shear(dd), load3(tri, 3 * i), load3(tri, 3 * i + 1),
                                       load3(tri, 3 * i + 2), 0.0f, INFINITY, &t, &u, &v);
    out[4 * i] = hit; out[4 * i + 1] = t; out[4 * i + 2] = u; out[4 * i + 3] = v;
}
""")

MODES = ("interior", "edge", "vertex", "grazing", "in-plane", "far-origin")


def adversarial_batch(rng, n, mode, log_scale, log_offset):
    """n triangles and rays of one kind: scale 10^log_scale, centred 10^log_offset away."""
    s = 10.0 ** log_scale
    cdir = rng.normal(size=3)
    c = cdir / np.linalg.norm(cdir) * 10.0 ** log_offset
    p = c + s * rng.normal(size=(n, 3, 3))
    if mode == "sliver":
        p[:, 2] = p[:, 0] + rng.uniform(-0.5, 1.5, (n, 1)) * (p[:, 1] - p[:, 0]) + \
            s * 10 ** rng.uniform(-6, -2, (n, 1)) * rng.normal(size=(n, 3))
    p = p.astype(np.float32).astype(np.float64)
    b = rng.dirichlet([1, 1, 1], n)
    if mode == "edge":
        b[:, rng.integers(0, 3)] = 0.0
        b /= b.sum(1, keepdims=True)
    elif mode == "vertex":
        b = np.eye(3)[rng.integers(0, 3, n)]
    target = np.einsum("ij,ijk->ik", b, p)
    nrm = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    nrm /= np.maximum(np.linalg.norm(nrm, axis=1, keepdims=True), 1e-300)
    d = rng.normal(size=(n, 3))
    if mode in ("grazing", "in-plane"):
        d -= np.sum(d * nrm, 1, keepdims=True) * nrm
        if mode == "grazing":
            d += nrm * (10 ** rng.uniform(-7, -2, (n, 1))) * np.linalg.norm(d, axis=1, keepdims=True)
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    dist = s * 10 ** rng.uniform(-1, 6 if mode == "far-origin" else 1, (n, 1))
    o = target - dist * d
    return o.astype(np.float32), (target - o).astype(np.float32), p.astype(np.float32)


@pytest.mark.parametrize("sizes", sized())
def test_intersect_triangle_adversarial(runtime, sizes):
    """hypothesis_examples examples of check_adversarial's cases."""
    @settings(max_examples=sizes.hypothesis_examples, deadline=None, derandomize=True,
              suppress_health_check=[HealthCheck.too_slow])
    @given(mode=st.sampled_from(MODES), log_scale=st.floats(-4, 6), log_offset=st.floats(-4, 6),
           seed=st.integers(0, 2**32 - 1))
    def examples(mode, log_scale, log_offset, seed):
        check_adversarial(runtime, sizes.hypothesis_batch, mode, log_scale, log_offset, seed)

    examples()


@pytest.mark.parametrize("sizes", sized())
def test_intersect_triangle_adversarial_slivers(runtime, sizes):
    """The same bound on slivers (relative height 1e-6..1e-2)."""
    for seed in range(4):
        check_adversarial(runtime, sizes.hypothesis_batch, "sliver", 0.0, 0.0, seed)


def check_adversarial(runtime, n, mode, log_scale, log_offset, seed):
    """Hard rays (through vertices and edges, grazing at 1e-7..1e-2 rad, lying in the plane,
    slivers of relative height 1e-6..1e-2, origins up to 1e6 triangle sizes away) at triangles of
    scale 1e-4..1e6 up to 1e6 from the origin, against float64 Möller-Trumbore.  Stated bound:
      * hit/miss may differ only where the ray's line passes within 1e-6 (relative to the
        coordinates' magnitude) of an edge, or the ray lies within 1e-4 rad of the plane;
      * where both hit and |cos| >= 0.01, |t - t64| |d| <= 1e-5 * max(1, 0.1 / |cos|) *
        (|o| + |p| + t64 |d|): t's rounding grows like 1/|cos| toward grazing (the long run found
        2.4e-5 near |cos| = 0.01 against a flat 1e-5), so the bound is 1e-5 for |cos| >= 0.1."""
    rng = np.random.default_rng(seed)
    o, d, p = adversarial_batch(rng, n, mode, log_scale, log_offset)
    o64, d64, p64 = o.astype(np.float64), d.astype(np.float64), p.astype(np.float64)
    t, u, v, inside = moller_trumbore(o64, d64, p64)
    ref_hit = (inside >= 0) & (t > 0) & np.isfinite(t)
    nrm = np.cross(p64[:, 1] - p64[:, 0], p64[:, 2] - p64[:, 0])
    nn = np.linalg.norm(nrm, axis=1)
    with np.errstate(divide="ignore", invalid="ignore"):
        cos = np.abs(np.sum(nrm * d64, 1)) / (nn * np.linalg.norm(d64, axis=1))
    cos = np.nan_to_num(cos, nan=0.0)
    near_edge = ray_edge_distance(o64, d64, p64) <= 1e-6
    out = TRI_HARNESS(runtime, "h_tri", n, o.reshape(-1, 3), d.reshape(-1, 3), p.reshape(-1, 3), (n, 4))
    hit = out[:, 0] == 1.0
    assert np.isfinite(out[hit, 1:]).all(), "a hit with a non-finite t, u or v"
    assert (out[hit, 1] > 0).all()
    bad = (hit != ref_hit) & ~near_edge & (cos >= 1e-4)
    assert not bad.any(), (f"{mode}: {bad.sum()} hit/miss disagreements away from edges, e.g. "
                           f"o={o[bad][0].tolist()} d={d[bad][0].tolist()} tri={p[bad][0].tolist()}")
    both = hit & ref_hit & (cos >= 0.01)
    dn = np.linalg.norm(d64[both], axis=1)
    scale = np.abs(o64[both]).max(1) + np.abs(p64[both]).max((1, 2)) + t[both] * dn
    terr = np.abs(out[both, 1] - t[both]) * dn / scale
    bound = 1e-5 * np.maximum(1.0, 0.1 / cos[both])
    assert (terr <= bound).all(), f"{mode}: t error {terr.max():.3g} (worst ratio to bound {np.max(terr / bound):.3g})"


# ================================================================================================
# 6. NaN guard: every example scene renders with no non-finite sample
# ================================================================================================
SCENES = sorted(p for p in os.listdir("scenes") if p.endswith(".toml")) if os.path.isdir("scenes") else []


def test_scenes_exist():
    assert SCENES, "no scenes/*.toml found (run from the repository root)"


@pytest.mark.parametrize("sizes,name", sized(lambda s: [pytest.param(name, id=name) for name in SCENES]))
def test_scene_has_no_nonfinite_samples(device, sizes, name):
    """Each scenes/*.toml at low resolution and spp: 0 non-finite samples and a finite image."""
    scene = load_scene(os.path.join("scenes", name))
    r = render_full(scene, spp=sizes.scene_spp, device=device, seed=3, width=sizes.scene_res, height=sizes.scene_res)
    assert r.info["nonfinite_samples"] == 0
    assert np.isfinite(r.image).all()
    assert r.image.max() > 0


def test_nonfinite_counter_counts(device):
    """The counter is not vacuous: an infinite emission makes every sample that sees it
    non-finite, and render_full reports them (and the image stays finite: they are discarded).
    (A NaN emission does not get that far: the kernels' `max3(Le) > 0` tests are false for NaN,
    so it is never added.)"""
    sc = far_camera_plane(10.0)
    sc.materials[1] = Material("sky", albedo=(0, 0, 0), emission=(float("inf"),) * 3, two_sided=True)
    r = render_full(sc, spp=2, device=device, seed=1)
    assert r.info["nonfinite_samples"] > 0
    assert np.isfinite(r.image).all()
