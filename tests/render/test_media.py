"""The participating-media building blocks of cl/render/media.h, through harness kernels, on every device.

- homogeneous media: transmittance against exp(-sigma_t d); the free-flight distances of each hero
  channel against their exponential density (chi-square, with the escapes as one more cell); the event
  weights against their closed forms, and the spectral-MIS estimate (random hero channels) of the
  escape and scattering probabilities of every channel against exp(-sigma_t d) and
  albedo (1 - exp(-sigma_t d)) (z-tests);
- grids: grid_eval against the host reference (scene/media.py: Grid.eval) and Mitsuba 3's gridvolume;
  grid_ray_box against a float64 slab test;
- tracking in a grid of known optical depth (a linear ramp along x, and random grids along oblique
  rays, integrated on the host): delta tracking's escape frequency and its collision distances
  (chi-square against sigma_t(t) exp(-tau(t))), the spectral-MIS escape estimate, and ratio tracking's
  mean, against exp(-tau) per channel;
- Henyey-Greenstein and isotropic sampling against their pdf (chi-square on cells of equal
  probability, several g of both signs), the pdf's normalisation, and Mitsuba 3's hg plugin (its
  value and its sample for the same random numbers);
- the hero-channel pick, medium_after_crossing's rules;
- 8 and 16 lanes give the bits of one lane for every function, on mixed media, masks and channels.

ALPHA = 1e-4 for chi-square tests (tests/harness.py's pooling); z-tests |z| < Z_MAX = 4.5 (two-sided
7e-6 each).  Inputs come from fixed seeds: a run is reproducible."""
import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.scene.media import Grid, Medium, MediumInterface, PhaseFunction, pack_grids

import harness
from harness import assert_chi2, uniforms

ALPHA = 1e-4
Z_MAX = 4.5

SOURCE = r"""
#include "render/media.h"

/* PACKET_WIDTH items per work-item (1 by default): lane k holds item get_global_id(0) * W + k */
#define ITEM(k) ((int)get_global_id(0) * PACKET_WIDTH + (k))
#define MASK_TRUE (PACKET_WIDTH == 1 ? 1 : -1)
#define MASK_F(m, k) (PLANE_I(m, k) == 0 ? 0.0f : PLANE_I(m, k) == MASK_TRUE ? 1.0f : -1.0f)

RT_INLINE pvec3 lanes3(__global const float *a, int stride, int at)
{
    pvec3 v;
    for (int k = 0; k < PACKET_WIDTH; ++k) pv3_set_lane(&v, k, vload3(0, a + stride * ITEM(k) + at));
    return v;
}
RT_INLINE pfloat lanes_f(__global const float *a, int stride, int at)
{
    pfloat v;
    for (int k = 0; k < PACKET_WIDTH; ++k) PLANE(v, k) = a[stride * ITEM(k) + at];
    return v;
}
RT_INLINE pint lanes_i(__global const int *a)
{
    pint v;
    for (int k = 0; k < PACKET_WIDTH; ++k) PLANE_I(v, k) = a[ITEM(k)];
    return v;
}
RT_INLINE puint lanes_u(__global const uint *a)
{
    puint v;
    for (int k = 0; k < PACKET_WIDTH; ++k) PLANE_U(v, k) = a[ITEM(k)];
    return v;
}

/* per item: medium mi, ray (o, d), span (tmin, tmax), hero channel, stream key, active; out, with
 * free_flight: t, real, beta.xyz, r.xyz of the free-flight sample, else T.xyz, r.xyz of the
 * transmittance (each starting at 1); state: the stream after */
__kernel void h_track(__global const Medium *media, __global const MediumGrid *grids,
                      __global const float *grid_data, __global const int *mi, __global const float *ray,
                      __global const float *span, __global const int *channel, __global const uint *key,
                      __global const int *act, const int free_flight, __global float *out, __global uint *state)
{
    const MediumLanes m = medium_lanes(media, grids, lanes_i(mi));
    puint st = lanes_u(key);
    pvec3 beta = pv3_splat((float3)(1.0f)), r = beta;
    const pvec3 o = lanes3(ray, 6, 0), d = lanes3(ray, 6, 3);
    const pfloat tmin = lanes_f(span, 2, 0), tmax = lanes_f(span, 2, 1);
    if (free_flight) {
        pfloat t = PFLOAT(-1.0f);
        const pint real = medium_sample_free_flight(&m, grid_data, o, d, tmin, tmax, lanes_i(channel), &st,
                                                    lanes_i(act) != 0, &t, &beta, &r);
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            __global float *q = out + 8 * ITEM(k);
            q[0] = PLANE(t, k);
            q[1] = MASK_F(real, k);
            vstore3(pv3_lane(beta, k), 0, q + 2);
            vstore3(pv3_lane(r, k), 0, q + 5);
        }
    } else {
        medium_transmittance(&m, grid_data, o, d, tmin, tmax, lanes_i(channel), &st, lanes_i(act) != 0, &beta, &r);
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            vstore3(pv3_lane(beta, k), 0, out + 6 * ITEM(k));
            vstore3(pv3_lane(r, k), 0, out + 6 * ITEM(k) + 3);
        }
    }
    for (int k = 0; k < PACKET_WIDTH; ++k) state[ITEM(k)] = PLANE_U(st, k);
}

/* per item: grid gi, world point p, active; out: value.xyz */
__kernel void h_grid_eval(__global const MediumGrid *grids, __global const float *grid_data, __global const int *gi,
                          __global const float *p, __global const int *act, __global float *out)
{
    const GridLanes g = grid_lanes(grids, lanes_i(gi));
    const pvec3 v = grid_eval(&g, grid_data, grid_to_local(&g, lanes3(p, 3, 0)), lanes_i(act) != 0);
    for (int k = 0; k < PACKET_WIDTH; ++k) vstore3(pv3_lane(v, k), 0, out + 3 * ITEM(k));
}

/* per item: grid gi, ray, span; out: t0, t1, hit */
__kernel void h_grid_box(__global const MediumGrid *grids, __global const int *gi, __global const float *ray,
                         __global const float *span, __global float *out)
{
    const GridLanes g = grid_lanes(grids, lanes_i(gi));
    pfloat t0, t1;
    const pint hit = grid_ray_box(&g, lanes3(ray, 6, 0), lanes3(ray, 6, 3), lanes_f(span, 2, 0), lanes_f(span, 2, 1),
                                  PTRUE, &t0, &t1);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        out[3 * ITEM(k)] = PLANE(t0, k);
        out[3 * ITEM(k) + 1] = PLANE(t1, k);
        out[3 * ITEM(k) + 2] = MASK_F(hit, k);
    }
}

/* per item: phase type, g, wi, u (2); out: wo.xyz, pdf, eval(wi, wo) */
__kernel void h_phase_sample(__global const int *phase, __global const float *g, __global const float *wi,
                             __global const float *u, __global float *out)
{
    const pint ph = lanes_i(phase);
    const pfloat gg = lanes_f(g, 1, 0);
    const pvec3 w = lanes3(wi, 3, 0);
    pfloat pdf = PFLOAT(-1.0f);
    const pvec3 wo = phase_sample_pg(ph, gg, w, lanes_f(u, 2, 0), lanes_f(u, 2, 1), &pdf);
    const pfloat value = phase_eval_pg(ph, gg, w, wo);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        vstore3(pv3_lane(wo, k), 0, out + 5 * ITEM(k));
        out[5 * ITEM(k) + 3] = PLANE(pdf, k);
        out[5 * ITEM(k) + 4] = PLANE(value, k);
    }
}

/* per item: phase type, g, wi, wo; out: p(wo, wi) */
__kernel void h_phase_eval(__global const int *phase, __global const float *g, __global const float *wi,
                           __global const float *wo, __global float *out)
{
    const pfloat v = phase_eval_pg(lanes_i(phase), lanes_f(g, 1, 0), lanes3(wi, 3, 0), lanes3(wo, 3, 0));
    for (int k = 0; k < PACKET_WIDTH; ++k) out[ITEM(k)] = PLANE(v, k);
}

/* per item: u -> the hero channel; interface ii, ng, d, current -> medium after, null */
__kernel void h_misc(__global const MediumInterface *interfaces, __global const float *u, __global const int *ii,
                     __global const float *ng, __global const float *d, __global const int *current,
                     __global int *out)
{
    const pint c = medium_channel(lanes_f(u, 1, 0));
    pint null;
    const pint after = medium_after_crossing(interfaces, lanes_i(ii), lanes3(ng, 3, 0), lanes3(d, 3, 0), lanes_i(current),
                                             &null);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        out[3 * ITEM(k)] = PLANE_I(c, k);
        out[3 * ITEM(k) + 1] = PLANE_I(after, k);
        out[3 * ITEM(k) + 2] = PLANE_I(null, k) == 0 ? 0 : PLANE_I(null, k) == MASK_TRUE ? 1 : -1;
    }
}
"""
HARNESS = harness.Kernels(SOURCE)


# ----------------------------------------------------------------------------- helpers
def pack(media):
    table, data, index = pack_grids(media)
    return np.stack([m.record(index) for m in media]).astype(abi.MEDIUM), table, data


def items(n, x, dtype, width=None):
    a = np.asarray(x, dtype)
    return np.ascontiguousarray(np.broadcast_to(a, (n,) if width is None else (n, width)), dtype)


def track(runtime, kernel, media, mi, ray, span, channel, key, act=1, kernels=HARNESS, lanes=1):
    """h_track's free flight (kernel "h_free_flight") or transmittance ("h_transmittance") over len(ray)
    items -> (out, state)."""
    ray = np.asarray(ray, np.float32).reshape(-1, 6)
    n = len(ray)
    recs, table, data = pack(media)
    free_flight = kernel == "h_free_flight"  # h_track's two modes
    return kernels(runtime, "h_track", n // lanes, recs, table, data, items(n, mi, np.int32), ray,
                   items(n, span, np.float32, 2), items(n, channel, np.int32), items(n, key, np.uint32),
                   items(n, act, np.int32), int(free_flight), (n, 8 if free_flight else 6), n)


def keys(rng, n):
    return rng.integers(0, 2**32, n, dtype=np.uint64).astype(np.uint32)


def z_score(samples, expected):
    s = np.asarray(samples, np.float64)
    se = s.std(ddof=1) / np.sqrt(len(s))
    return (s.mean() - expected) / max(se, 1e-300)


def mis(beta, r):
    m = r.mean(axis=1, keepdims=True)
    return np.where(m > 0, beta / np.where(m > 0, m, 1), 0.0)


# ----------------------------------------------------------------------------- homogeneous media
SIGMA = np.array([0.5, 1.5, 3.0])
ALBEDO = np.array([0.9, 0.6, 0.3])
CHROMATIC = Medium(sigma_t=tuple(SIGMA), albedo=tuple(ALBEDO))
X_RAY = [0, 0, 0, 1, 0, 0]


def test_homogeneous_transmittance_is_exp(runtime):
    """medium_transmittance in a homogeneous medium is exp(-sigma_t d) per channel (rtol 1e-6; 1 for
    sigma_t = 0, also over an infinite segment; 0 for sigma_t > 0 over it), with r untouched and no
    random number drawn; an empty or inactive segment leaves T at 1."""
    media = [CHROMATIC, Medium(sigma_t=(0.0, 2.0, 1e-3), scale=2.0)]
    d = np.array([0.0, 1e-4, 0.3, 1.0, 2.5, 7.0, 30.0, np.inf], np.float32)
    n = len(d) * 2
    mi = np.repeat([0, 1], len(d))
    span = np.stack([np.zeros(n), np.tile(d, 2)], 1)
    out, state = track(runtime, "h_transmittance", media, mi, items(n, X_RAY, np.float32, 6), span, 1, 7)
    sig = np.array([SIGMA, [0.0, 4.0, 2e-3]])[mi]
    with np.errstate(invalid="ignore"):
        expect = np.where(sig == 0, 1.0, np.exp(-sig * span[:, 1:]))
    assert np.allclose(out[:, :3], expect, rtol=1e-6, atol=1e-30)
    assert np.all(out[:, 3:] == 1.0) and np.all(state == 7)
    off, _ = track(runtime, "h_transmittance", media, mi, items(n, X_RAY, np.float32, 6), span, 1, 7, act=0)
    assert np.all(off == 1.0)
    empty, _ = track(runtime, "h_transmittance", media, 0, items(3, X_RAY, np.float32, 6), [2.0, 1.0], 1, 7)
    assert np.all(empty == 1.0)


@pytest.mark.parametrize("channel", [0, 1, 2])
def test_homogeneous_free_flight_distances(runtime, rng, channel):
    """1M free flights over [0, 1.5] with hero channel c: the collision distances against the density
    sigma_c exp(-sigma_c t) on 30 bins, the escapes (t = tmax, no collision) as one more cell
    expecting exp(-1.5 sigma_c) (chi-square, p > ALPHA); each event's weights equal their closed
    forms (rtol 2e-5): a collision at t multiplies beta by T_k sigma_s_k / (T_c sigma_c) and r by
    T_k sigma_k / (T_c sigma_c), an escape both by T_k / T_c (T_k = exp(-sigma_k t))."""
    n, tmax = 1_000_000, 1.5
    out, _ = track(runtime, "h_free_flight", [CHROMATIC], 0, items(n, X_RAY, np.float32, 6), [0.0, tmax], channel,
                   keys(rng, n))
    t, real = out[:, 0].astype(np.float64), out[:, 1] == 1
    assert set(np.unique(out[:, 1])) <= {0.0, 1.0}
    assert np.all(t[~real] == np.float32(tmax)) and np.all((t[real] >= 0) & (t[real] < tmax))
    s = SIGMA[channel]
    edges = np.linspace(0, tmax, 31)
    observed = np.append(np.histogram(t[real], edges)[0], np.count_nonzero(~real))
    expected = n * np.append(np.exp(-s * edges[:-1]) - np.exp(-s * edges[1:]), np.exp(-s * tmax))
    assert_chi2(observed, expected, ALPHA, f"free flight, channel {channel}")
    T = np.exp(-np.outer(t, SIGMA))
    Tc = T[:, channel:channel + 1]
    beta = np.where(real[:, None], T * SIGMA * ALBEDO / (Tc * s), T / Tc)
    r = np.where(real[:, None], T * SIGMA / (Tc * s), T / Tc)
    assert np.allclose(out[:, 2:5], beta, rtol=2e-5, atol=1e-30)
    assert np.allclose(out[:, 5:8], r, rtol=2e-5, atol=1e-30)


def test_homogeneous_spectral_mis_is_unbiased(runtime, rng):
    """With the hero channel drawn uniformly per flight (medium_channel), the spectral-MIS estimate
    beta / mean(r) of every channel k has the mean of its closed form: exp(-sigma_k d) for the
    escapes, albedo_k (1 - exp(-sigma_k d)) for the collisions (z-tests); so has beta alone (Mitsuba
    volpath's single-channel estimate), and its variance is never below the MIS one's."""
    n, d = 600_000, 1.2
    channel = np.minimum((uniforms(rng, n) * 3).astype(np.int64), 2)
    out, _ = track(runtime, "h_free_flight", [CHROMATIC], 0, items(n, X_RAY, np.float32, 6), [0.0, d], channel,
                   keys(rng, n))
    real = out[:, 1:2] == 1
    est = mis(out[:, 2:5].astype(np.float64), out[:, 5:8].astype(np.float64))
    single = out[:, 2:5].astype(np.float64)
    for k in range(3):
        esc, col = np.exp(-SIGMA[k] * d), ALBEDO[k] * (1 - np.exp(-SIGMA[k] * d))
        for what, w in (("mis", est[:, k]), ("single", single[:, k])):
            assert abs(z_score(np.where(real[:, 0], 0, w), esc)) < Z_MAX, (what, k, "escape")
            assert abs(z_score(np.where(real[:, 0], w, 0), col)) < Z_MAX, (what, k, "collision")
        assert est[:, k].var() <= single[:, k].var() * 1.001


# ----------------------------------------------------------------------------- grids
def random_affine(rng, scale=2.0):
    q, _ = np.linalg.qr(rng.normal(size=(3, 3)))
    m = np.eye(4)
    m[:3, :3] = q @ np.diag(rng.uniform(0.5, scale, 3))
    m[:3, 3] = rng.uniform(-1, 1, 3)
    return m


def random_grids(rng):
    shapes = [(3, 4, 5, 1), (2, 3, 4, 3), (1, 1, 1, 1), (4, 2, 1, 3)]
    grids = []
    for i, shape in enumerate(shapes):
        for filt in ("trilinear", "nearest"):
            for outside in ("clamp", "zero"):
                grids.append(Grid(rng.uniform(0, 2, shape), to_world=random_affine(rng), filter=filt, outside=outside))
    return grids


def grid_points(rng, grid, n):
    """World points of local coordinates in [-0.3, 1.3]^3 (inside and beyond the grid's box)."""
    q = rng.uniform(-0.3, 1.3, (n, 3))
    return q @ grid.to_world[:3, :3].T + grid.to_world[:3, 3]


def test_grid_eval_matches_host_reference(runtime, rng):
    """grid_eval (trilinear and nearest, clamped and zero outside, 1 and 3 channels, a 1x1x1 grid,
    rotated and scaled boxes) equals Grid.eval (float64) to 2e-6 of the grid's range, at points
    inside and outside the box; inactive lanes give 0."""
    grids = random_grids(rng)
    table, data, _ = pack_grids([Medium(density=g) for g in grids])
    n = 4000
    gi = np.repeat(np.arange(len(grids)), n)
    p = np.concatenate([grid_points(rng, g, n) for g in grids]).astype(np.float32)
    act = (rng.random(len(p)) < 0.9).astype(np.int32)
    out = HARNESS(runtime, "h_grid_eval", len(p), table, data, gi.astype(np.int32), p, act, (len(p), 3))
    for i, g in enumerate(grids):
        sl = slice(i * n, (i + 1) * n)
        ref = g.eval(p[sl].astype(np.float64)) * act[sl, None]
        # a point within rounding of a texel boundary may fall on either side under nearest
        bad = ~np.isclose(out[sl], ref, rtol=0, atol=2e-6 * g.data.max())
        assert bad.any(axis=1).mean() < (2e-3 if g.filter == "nearest" else 1e-9), (i, g.filter, g.outside)


def test_grid_eval_matches_mitsuba(runtime, rng):
    """Mitsuba 3's gridvolume (scalar_rgb; trilinear and nearest, clamp) gives our values at the same
    world points, to 1e-5 (Mitsuba's trilinear weights use fused multiply-adds)."""
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    for filt in ("trilinear", "nearest"):
        for channels in (1, 3):
            g = Grid(rng.uniform(0, 1, (3, 4, 5, channels)), to_world=random_affine(rng), filter=filt)
            vol = mi.load_dict({"type": "gridvolume", "grid": mi.VolumeGrid(g.data), "filter_type": filt,
                                "to_world": mi.ScalarTransform4f(g.to_world.tolist()), "accel": False})
            table, data, _ = pack_grids([Medium(density=g)])
            p = grid_points(rng, g, 300).astype(np.float32)
            ours = HARNESS(runtime, "h_grid_eval", len(p), table, data, np.zeros(len(p), np.int32), p,
                           np.ones(len(p), np.int32), (len(p), 3))
            theirs = []
            for x in p.astype(np.float64):
                it = mi.Interaction3f()
                it.p = mi.Point3f(*x)
                theirs.append(np.array(vol.eval(it), np.float64))
            close = np.isclose(ours, np.array(theirs), rtol=0, atol=1e-5).all(axis=1)
            assert close.mean() > (0.99 if filt == "nearest" else 0.9999), (filt, channels)


def test_grid_ray_box(runtime, rng):
    """grid_ray_box's [t0, t1] is the float64 slab test's part of the ray inside the rotated, scaled
    box, clipped to the span (to 1e-5 relative to the ray's reach), and hit where that is not
    empty (but for rays within 1e-5 of tangent); rays along a box face stay inside it."""
    g = Grid(np.ones((1, 1, 1)), to_world=random_affine(rng))
    table, _, _ = pack_grids([Medium(density=g)])
    n = 20000
    centre = g.to_world[:3, :3] @ [0.5, 0.5, 0.5] + g.to_world[:3, 3]
    o = centre + rng.normal(size=(n, 3)) * 2
    target = centre + rng.normal(size=(n, 3)) * 0.8
    d = target - o
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    span = np.stack([rng.uniform(-1, 2, n), rng.uniform(2, 8, n)], 1)
    ray = np.concatenate([o, d], 1).astype(np.float32)
    out = HARNESS(runtime, "h_grid_box", n, table, np.zeros(n, np.int32), ray, span.astype(np.float32), (n, 3))
    inv = np.linalg.inv(g.to_world)
    lo = ray[:, :3].astype(np.float64) @ inv[:3, :3].T + inv[:3, 3]
    ld = ray[:, 3:].astype(np.float64) @ inv[:3, :3].T
    with np.errstate(divide="ignore", invalid="ignore"):
        ta, tb = -lo / ld, (1 - lo) / ld
    t0 = np.maximum(np.minimum(ta, tb).max(1), span[:, 0].astype(np.float32))
    t1 = np.minimum(np.maximum(ta, tb).min(1), span[:, 1].astype(np.float32))
    hit = t0 <= t1
    clear = np.abs(t1 - t0) > 1e-5 * 10
    assert np.array_equal(out[clear, 2] == 1, hit[clear]) and 0.2 < hit.mean() < 0.95
    both = hit & (out[:, 2] == 1)
    assert np.allclose(out[both, 0], t0[both], rtol=0, atol=1e-5 * 10)
    assert np.allclose(out[both, 1], t1[both], rtol=0, atol=1e-5 * 10)
    # along the box's x = 0 face of an axis-aligned box: inside
    g2 = Grid(np.ones((1, 1, 1)))
    table2, _, _ = pack_grids([Medium(density=g2)])
    face = np.array([[0.0, 0.5, -1.0, 0.0, 0.0, 1.0]], np.float32)
    out2 = HARNESS(runtime, "h_grid_box", 1, table2, np.zeros(1, np.int32), face, np.array([[0.0, 9.0]], np.float32),
                   (1, 3))
    assert out2[0].tolist() == [1.0, 2.0, 1.0]


# ----------------------------------------------------------------------------- tracking in grids
RAMP_N, RAMP_L = 8, 2.0
RAMP_TEXELS = 0.5 + 3.0 * (np.arange(RAMP_N) + 0.5) / RAMP_N  # values at the texel centres along x
RAMP_SIGMA = np.array([1.0, 2.0, 3.0]) * 0.7


def ramp_medium(outside="clamp"):
    data = np.broadcast_to(RAMP_TEXELS[None, None, :], (3, 3, RAMP_N)).astype(np.float32)
    m = np.diag([RAMP_L, 2.0, 2.0, 1.0])
    m[:3, 3] = [0.0, -1.0, -1.0]
    return Medium(sigma_t=tuple(RAMP_SIGMA), albedo=(0.8, 0.5, 0.2), density=Grid(data, to_world=m, outside=outside))


def ramp_knots(outside="clamp"):
    """(x, density) knots of the piecewise-linear density along x in [0, L]."""
    centres = RAMP_L * (np.arange(RAMP_N) + 0.5) / RAMP_N
    edge = (RAMP_TEXELS[0], RAMP_TEXELS[-1]) if outside == "clamp" else (RAMP_TEXELS[0] / 2, RAMP_TEXELS[-1] / 2)
    return np.concatenate([[0.0], centres, [RAMP_L]]), np.concatenate([[edge[0]], RAMP_TEXELS, [edge[1]]])


def ramp_depth(x, outside="clamp"):
    """The integral of the density from 0 to x (piecewise quadratic, exact)."""
    kx, kv = ramp_knots(outside)
    seg = np.concatenate([[0.0], np.cumsum(np.diff(kx) * (kv[1:] + kv[:-1]) / 2)])
    x = np.clip(np.asarray(x, np.float64), 0, RAMP_L)
    i = np.clip(np.searchsorted(kx, x, side="right") - 1, 0, len(kx) - 2)
    dx = x - kx[i]
    slope = (kv[i + 1] - kv[i]) / (kx[i + 1] - kx[i])
    return seg[i] + kv[i] * dx + slope * dx * dx / 2


def ramp_rays(rng, n):
    """Rays along +x from x = -1 (outside the box) at random y, z between the outer texel centres (the
    density is the ramp there, with zero texels outside too); the span [0, 4] reaches x = 3."""
    yz = rng.uniform(-0.6, 0.6, (n, 2))
    return np.concatenate([np.full((n, 1), -1.0), yz, np.tile([1.0, 0.0, 0.0], (n, 1))], 1).astype(np.float32)


@pytest.mark.parametrize("outside", ["clamp", "zero"])
def test_delta_tracking_on_a_ramp(runtime, rng, outside):
    """Delta tracking through the ramp grid (optical depth tau_k = sigma_k * the density's exact
    integral): per hero channel, the escape frequency against exp(-tau_c) (z-test) and the collision
    distances against sigma_c rho(t) exp(-sigma_c int rho) on 24 bins plus the escape cell
    (chi-square, p > ALPHA); collisions lie inside the box; and with random hero channels the
    spectral-MIS escape estimate of every channel has the mean exp(-tau_k) (z-test)."""
    n = 300_000
    med = ramp_medium(outside)
    tau = RAMP_SIGMA * ramp_depth(RAMP_L, outside)
    ray = ramp_rays(rng, n)
    for c in range(3):
        out, _ = track(runtime, "h_free_flight", [med], 0, ray, [0.0, 4.0], c, keys(rng, n))
        real = out[:, 1] == 1
        t = out[:, 0].astype(np.float64)
        assert np.all(t[~real] == 4.0) and np.all((t[real] >= 1.0) & (t[real] <= 1.0 + RAMP_L))
        p = np.exp(-tau[c])
        z = (np.count_nonzero(~real) - n * p) / np.sqrt(n * p * (1 - p))
        assert abs(z) < Z_MAX, (c, z)
        edges = np.linspace(1.0, 1.0 + RAMP_L, 25)
        cdf = 1 - np.exp(-RAMP_SIGMA[c] * ramp_depth(edges - 1.0, outside))
        observed = np.append(np.histogram(t[real], edges)[0], np.count_nonzero(~real))
        assert_chi2(observed, n * np.append(np.diff(cdf), p), ALPHA, f"delta tracking, channel {c}, {outside}")
    channel = np.minimum((uniforms(rng, n) * 3).astype(np.int64), 2)
    out, _ = track(runtime, "h_free_flight", [med], 0, ray, [0.0, 4.0], channel, keys(rng, n))
    est = mis(out[:, 2:5].astype(np.float64), out[:, 5:8].astype(np.float64))
    esc = out[:, 1] == 0
    for k in range(3):
        assert abs(z_score(np.where(esc, est[:, k], 0), np.exp(-tau[k]))) < Z_MAX, k


def test_ratio_tracking_on_a_ramp(runtime, rng):
    """Ratio tracking through the ramp grid: the mean of T / mean(r) over random hero channels, and of
    T alone per fixed hero channel, is exp(-tau_k) in every channel (z-tests); a grey majorant (the
    same sigma in every channel) leaves r at exactly 1."""
    n = 200_000
    med = ramp_medium()
    tau = RAMP_SIGMA * ramp_depth(RAMP_L)
    ray = ramp_rays(rng, n)
    channel = np.minimum((uniforms(rng, n) * 3).astype(np.int64), 2)
    out, _ = track(runtime, "h_transmittance", [med], 0, ray, [0.0, 4.0], channel, keys(rng, n))
    est = mis(out[:, :3].astype(np.float64), out[:, 3:].astype(np.float64))
    for k in range(3):
        assert abs(z_score(est[:, k], np.exp(-tau[k]))) < Z_MAX, k
    for c in range(3):
        out, _ = track(runtime, "h_transmittance", [med], 0, ray, [0.0, 4.0], c, keys(rng, n))
        for k in range(3):
            assert abs(z_score(out[:, k], np.exp(-tau[k]))) < Z_MAX, (c, k)
    grey = ramp_medium()
    grey.sigma_t = (1.3, 1.3, 1.3)
    out, _ = track(runtime, "h_transmittance", [grey], 0, ray[:5000], [0.0, 4.0], 1, keys(rng, 5000))
    assert np.all(out[:, 3:] == 1.0) and np.all(out[:, 0] == out[:, 1])
    assert abs(z_score(out[:, 0], np.exp(-1.3 * ramp_depth(RAMP_L)))) < Z_MAX


@pytest.mark.parametrize("outside", ["clamp", "zero"])
def test_tracking_along_oblique_rays(runtime, rng, outside):
    """A random 5x4x3 RGB grid in a rotated, scaled box, chromatic sigma_t: along three oblique rays
    (span ending inside the box for one), the optical depth integrated on the host (Grid.eval at 40000
    midpoints) gives exp(-tau_k), which ratio tracking's spectral-MIS mean and delta tracking's
    spectral-MIS escape estimate match (z-tests)."""
    grid = Grid(rng.uniform(0, 1.5, (3, 4, 5, 3)), to_world=random_affine(rng, 1.5), outside=outside)
    sigma = np.array([0.6, 1.1, 1.7])
    med = Medium(sigma_t=tuple(sigma), albedo=(0.7, 0.7, 0.7), density=grid)
    centre = grid.to_world[:3, :3] @ [0.5, 0.5, 0.5] + grid.to_world[:3, 3]
    n = 150_000
    for j in range(3):
        o = centre + rng.normal(size=3) * 2
        d = centre + rng.normal(size=3) * 0.2 - o
        d /= np.linalg.norm(d)
        tmax = np.linalg.norm(centre - o) if j == 2 else 10.0
        ray = np.concatenate([o, d]).astype(np.float32)
        o64, d64 = ray[:3].astype(np.float64), ray[3:].astype(np.float64)
        ts = (np.arange(40000) + 0.5) / 40000 * tmax
        pts = o64 + ts[:, None] * d64
        inv = np.linalg.inv(grid.to_world)
        q = pts @ inv[:3, :3].T + inv[:3, 3]
        inside = np.all((q >= 0) & (q <= 1), axis=1)
        tau = sigma * (grid.eval(pts) * inside[:, None]).sum(0) * tmax / 40000
        assert tau.min() > 0.05
        channel = np.minimum((uniforms(rng, n) * 3).astype(np.int64), 2)
        out, _ = track(runtime, "h_transmittance", [med], 0, items(n, ray, np.float32, 6), [0.0, tmax], channel,
                       keys(rng, n))
        est = mis(out[:, :3].astype(np.float64), out[:, 3:].astype(np.float64))
        ff, _ = track(runtime, "h_free_flight", [med], 0, items(n, ray, np.float32, 6), [0.0, tmax], channel,
                      keys(rng, n))
        esc = mis(ff[:, 2:5].astype(np.float64), ff[:, 5:8].astype(np.float64)) * (ff[:, 1:2] == 0)
        for k in range(3):
            assert abs(z_score(est[:, k], np.exp(-tau[k]))) < Z_MAX, (j, k, "ratio")
            assert abs(z_score(esc[:, k], np.exp(-tau[k]))) < Z_MAX, (j, k, "delta")


# ----------------------------------------------------------------------------- phase functions
def frame(w):
    """An orthonormal (e1, e2, w) (float64)."""
    a = np.array([1.0, 0, 0]) if abs(w[0]) < 0.9 else np.array([0, 1.0, 0])
    e1 = np.cross(w, a)
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(w, e1), w


def hg_cdf_inverse(g, u):
    """mu = cos(angle to the travel direction) at the HG CDF value u (u = 0: mu = -1)."""
    if abs(g) < 1e-6:
        return 2 * u - 1
    s = (1 - g * g) / (1 - g + 2 * g * u)
    return (1 + g * g - s * s) / (2 * g)


PHASES = [("isotropic", 0.0)] + [("hg", g) for g in (-0.9, -0.5, -0.2, 0.0, 0.3, 0.7, 0.95)]
WI = np.array([0.3, -0.5, 0.8]) / np.linalg.norm([0.3, -0.5, 0.8])


def phase_eval(runtime, ptype, g, wo):
    n = len(wo)
    return HARNESS(runtime, "h_phase_eval", n, items(n, int(ptype == "hg"), np.int32), items(n, g, np.float32),
                   items(n, WI, np.float32, 3), np.asarray(wo, np.float32), n).astype(np.float64)


def cell_integrals(runtime, ptype, g, mu_edges, phi_edges, k=8):
    """The device pdf integrated over (mu, phi) cells about the travel direction -wi (k x k-point
    Gauss-Legendre per cell, float64 on the host)."""
    x, w = np.polynomial.legendre.leggauss(k)
    mu, wmu = harness.gauss_legendre_cells(mu_edges, x, w)
    phi, wphi = harness.gauss_legendre_cells(phi_edges, x, w)
    M, P = np.meshgrid(mu, phi, indexing="ij")
    e1, e2, e3 = frame(-WI)
    s = np.sqrt(np.maximum(0, 1 - M * M))
    dirs = (s * np.cos(P))[..., None] * e1 + (s * np.sin(P))[..., None] * e2 + M[..., None] * e3
    pdf = phase_eval(runtime, ptype, g, dirs.reshape(-1, 3)).reshape(M.shape)
    cells = pdf * wmu[:, None] * wphi[None, :]
    return cells.reshape(len(mu_edges) - 1, k, len(phi_edges) - 1, k).sum(axis=(1, 3))


def mu_edges_for(ptype, g, bins=24):
    return np.array([hg_cdf_inverse(g if ptype == "hg" else 0.0, u) for u in np.linspace(0, 1, bins + 1)])


@pytest.mark.parametrize("ptype,g", PHASES)
def test_phase_sampling_chi2(runtime, rng, ptype, g):
    """1M phase samples for one incoming direction: unit length, pdf = the phase function's value at
    the sample = the closed form HG(g, mu) (isotropic 1 / 4 pi), to 5e-4 (near the peak of g = 0.95,
    d log p / d mu reaches 3 |g| / (1 - |g|)^2 ~ 1000, times float rounding); chi-square (p > ALPHA) on
    24 cells of equal HG probability in mu (the cosine to the travel direction -wi) x 8 in phi against
    the device pdf integrated over each cell."""
    n = 1_000_000
    u = uniforms(rng, (n, 2))
    out = HARNESS(runtime, "h_phase_sample", n, items(n, int(ptype == "hg"), np.int32), items(n, g, np.float32),
                  items(n, WI, np.float32, 3), u, (n, 5)).astype(np.float64)
    wo, pdf, value = out[:, :3], out[:, 3], out[:, 4]
    assert np.abs(np.linalg.norm(wo, axis=1) - 1).max() < 3e-6
    assert np.allclose(pdf, value, rtol=5e-4)
    e1, e2, e3 = frame(-WI)
    mu = np.clip(wo @ e3, -1, 1)
    closed = (1 - g * g) / (4 * np.pi * (1 + g * g - 2 * g * mu) ** 1.5) if ptype == "hg" else 1 / (4 * np.pi)
    assert np.allclose(pdf, closed, rtol=5e-4)
    phi = np.mod(np.arctan2(wo @ e2, wo @ e1), 2 * np.pi)
    mu_edges, phi_edges = mu_edges_for(ptype, g), np.linspace(0, 2 * np.pi, 9)
    mu_edges[0], mu_edges[-1] = -1.0, 1.0
    observed = np.histogram2d(mu, phi, [mu_edges, phi_edges])[0]
    expected = cell_integrals(runtime, ptype, g, mu_edges, phi_edges) * n
    assert_chi2(observed, expected, ALPHA, f"{ptype} g={g}")


@pytest.mark.parametrize("ptype,g", PHASES)
def test_phase_pdf_integrates_to_one(runtime, ptype, g):
    """The device phase function integrated over the sphere is 1 to 2e-5."""
    mu_edges = mu_edges_for(ptype, g, 64)
    mu_edges[0], mu_edges[-1] = -1.0, 1.0
    total = cell_integrals(runtime, ptype, g, mu_edges, np.linspace(0, 2 * np.pi, 5)).sum()
    assert abs(total - 1) < 2e-5


def test_phase_matches_mitsuba(runtime, rng):
    """Mitsuba 3's hg (and isotropic) phase function gives our value at random (wi, wo) pairs (rtol
    1e-5) and, for the same random numbers, our sampled direction (to 2e-5) and pdf: g's sign means
    the same thing (g > 0 forward) in both."""
    mi = pytest.importorskip("mitsuba")
    mi.set_variant("scalar_rgb")
    n = 200
    wi = rng.normal(size=(n, 3))
    wi /= np.linalg.norm(wi, axis=1, keepdims=True)
    wo = rng.normal(size=(n, 3))
    wo /= np.linalg.norm(wo, axis=1, keepdims=True)
    u = uniforms(rng, (n, 2))
    ctx = mi.PhaseFunctionContext(None)
    for ptype, g in (("hg", 0.6), ("hg", -0.4), ("hg", 0.0), ("isotropic", 0.0)):
        phase = mi.load_dict({"type": "hg", "g": g} if ptype == "hg" else {"type": "isotropic"})
        ours = HARNESS(runtime, "h_phase_sample", n, items(n, int(ptype == "hg"), np.int32), items(n, g, np.float32),
                       wi.astype(np.float32), u, (n, 5)).astype(np.float64)
        val = HARNESS(runtime, "h_phase_eval", n, items(n, int(ptype == "hg"), np.int32), items(n, g, np.float32),
                      wi.astype(np.float32), wo.astype(np.float32), n)
        for i in range(n):
            mei = mi.MediumInteraction3f()
            mei.wi = mi.Vector3f(*wi[i].astype(np.float32))
            mei.sh_frame = mi.Frame3f(mei.wi)
            v, _ = phase.eval_pdf(ctx, mei, mi.Vector3f(*wo[i].astype(np.float32)))
            assert np.isclose(val[i], float(v[0] if hasattr(v, "__len__") else v), rtol=1e-5), (ptype, g, i)
            d, w, pdf = phase.sample(ctx, mei, 0.5, mi.Point2f(*u[i]))
            assert np.allclose(ours[i, :3], np.array(d), atol=2e-5), (ptype, g, i)
            assert np.isclose(ours[i, 3], float(pdf), rtol=1e-4), (ptype, g, i)


# ----------------------------------------------------------------------------- channels and boundaries
def test_channel_pick_and_crossings(runtime):
    """medium_channel: [0, 1/3) -> 0, [1/3, 2/3) -> 1, the rest -> 2 (1 - 2^-24 too).
    medium_after_crossing: a transition enters the exterior along the normal and the interior against
    it (a grazing direction, dot = 0, the interior: Mitsuba's rule), a surface that is no transition
    or has no interface keeps the ray's medium; null flags the index-matched ones."""
    interfaces = np.stack([MediumInterface(2, 0).record(), MediumInterface(-1, 1, null=True).record(),
                           MediumInterface(transition=False, null=True).record()]).astype(abi.MEDIUM_INTERFACE)
    u = np.array([0, 0.333, 1 / 3 + 1e-7, 0.5, 0.6666, 0.6667, 0.9, 1 - 2**-24], np.float32)
    cases = [  # ii, ng, d, current -> after, null
        (0, [0, 0, 1], [0, 0.2, 1], 5, 0, 0), (0, [0, 0, 1], [0, 0, -1], 5, 2, 0), (0, [0, 0, 1], [1, 0, 0], 5, 2, 0),
        (1, [1, 0, 0], [1, 0, 0], 0, 1, 1), (1, [1, 0, 0], [-1, 0, 0], 0, -1, 1), (2, [0, 1, 0], [0, 1, 0], 3, 3, 1),
        (-1, [0, 1, 0], [0, 1, 0], 4, 4, 0), (-1, [0, 1, 0], [0, -1, 0], -1, -1, 0)]
    n = len(cases)
    out = HARNESS(runtime, "h_misc", n, interfaces, u, np.array([c[0] for c in cases], np.int32),
                  np.array([c[1] for c in cases], np.float32), np.array([c[2] for c in cases], np.float32),
                  np.array([c[3] for c in cases], np.int32), (n, 3))
    assert out[:, 0].tolist() == [0, 0, 1, 1, 1, 2, 2, 2]
    assert out[:, 1].tolist() == [c[4] for c in cases] and out[:, 2].tolist() == [c[5] for c in cases]


# ----------------------------------------------------------------------------- lanes
def lane_media(rng):
    albedo = Grid(rng.uniform(0, 1, (2, 3, 2, 3)), to_world=random_affine(rng), filter="nearest", outside="zero")
    return [CHROMATIC, Medium(sigma_t=(2.0, 2.0, 2.0), albedo=(0.5, 0.5, 0.5), phase=PhaseFunction("hg", 0.4)),
            ramp_medium(),
            Medium(sigma_t=(0.5, 1.0, 1.5), density=Grid(rng.uniform(0, 2, (3, 4, 5, 3)), to_world=random_affine(rng),
                                                         outside="zero"), albedo_grid=albedo),
            Medium(sigma_t=(0.0, 1.0, 0.0))]


@pytest.mark.parametrize("width", [8, 16])
def test_lane_widths_give_the_one_lane_bits(device, runtime, rng, width):
    """Every function of cl/render/media.h over 8 and 16 lanes (each work-item `width` items of mixed
    media, homogeneous and grid, hero channels, spans, an `active` mask) gives, lane by lane, the bits
    of the one-lane code: free flight (t, collision mask, weights, the stream's state after), ratio
    tracking, grid_eval, grid_ray_box, phase sampling and evaluation of mixed phase types, the channel
    pick and medium_after_crossing."""
    harness.require_lane_kernels(device, width)
    wide = harness.Kernels(SOURCE, defines={"PACKET_WIDTH": width}, local_size=16)
    n = 16 * 512
    media = lane_media(rng)
    mi = rng.integers(0, len(media), n)
    o = rng.uniform(-1.5, 1.5, (n, 3))
    d = rng.normal(size=(n, 3))
    d /= np.linalg.norm(d, axis=1, keepdims=True)
    ray = np.concatenate([o, d], 1).astype(np.float32)
    span = np.stack([rng.uniform(0, 0.5, n), np.where(rng.random(n) < 0.2, np.inf, rng.uniform(0.5, 6, n))], 1)
    channel, key, act = rng.integers(0, 3, n), keys(rng, n), (rng.random(n) < 0.7).astype(np.int32)
    for kernel in ("h_free_flight", "h_transmittance"):
        one = track(runtime, kernel, media, mi, ray, span, channel, key, act)
        lanes = track(runtime, kernel, media, mi, ray, span, channel, key, act, kernels=wide, lanes=width)
        for a, b in zip(one, lanes):
            assert np.array_equal(a.view(np.uint32), b.view(np.uint32)), kernel
        assert np.isfinite(one[0][:, 1:]).all()  # t = tmax may be infinite
    table, data, _ = pack_grids(media)
    gi = rng.integers(0, len(table), n).astype(np.int32)
    p = rng.uniform(-1.5, 2.5, (n, 3)).astype(np.float32)
    ptype, g = rng.integers(0, 2, n).astype(np.int32), rng.uniform(-0.95, 0.95, n).astype(np.float32)
    g[::7] = 0.0
    u = uniforms(rng, (n, 2))
    interfaces = np.stack([MediumInterface(1, 0).record(), MediumInterface(-1, 2, null=True).record()])
    ii, cur = rng.integers(-1, 2, n).astype(np.int32), rng.integers(-1, 3, n).astype(np.int32)
    runs = []
    for kernels, lanes in ((HARNESS, 1), (wide, width)):
        m = n // lanes
        runs.append((kernels(runtime, "h_grid_eval", m, table, data, gi, p, act, (n, 3)),
                     kernels(runtime, "h_grid_box", m, table, gi, ray, span.astype(np.float32), (n, 3)),
                     kernels(runtime, "h_phase_sample", m, ptype, g, d.astype(np.float32), u, (n, 5)),
                     kernels(runtime, "h_phase_eval", m, ptype, g, d.astype(np.float32), p / np.linalg.norm(
                         p, axis=1, keepdims=True), n),
                     kernels(runtime, "h_misc", m, interfaces.astype(abi.MEDIUM_INTERFACE), u[:, 0].copy(), ii,
                             d.astype(np.float32), ray[:, 3:].copy(), cur, (n, 3))))
    for what, a, b in zip(("grid_eval", "grid_box", "phase_sample", "phase_eval", "misc"), *runs):
        assert np.array_equal(a.view(np.uint32), b.view(np.uint32)), what
