"""cl/render/rng.h, cl/render/sampling.h and the host alias table (pyopencl_rt/render/sampling.py).

Statistical tests use a significance threshold of ALPHA = 1e-4: a correct implementation fails
one of them with probability 1e-4 (and every input is drawn from fixed seeds, so a run is
reproducible).  Distributions are checked as Mitsuba 3's chi2 tests do: samples drawn on the
device through small harness kernels are binned, the expected count of every bin is the device
pdf integrated over the bin in float64 on the host (Gauss-Legendre quadrature), bins expecting
fewer than 5 samples are pooled as Mitsuba 3 pools them, and the Pearson statistic is compared
with scipy's chi2 (tests/harness.py: chi2_test).  Runs on every available device."""
import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.render.sampling import build_alias_table, fill_light_table

import harness
from harness import assert_chi2, uniforms

ALPHA = 1e-4  # significance of every chi-square test below
N = 1_000_000

HARNESS = harness.Kernels(r"""
#include "render/rng.h"
#include "render/sampling.h"

__kernel void h_hash(__global const uint *x, __global uint *out)
{
    const int i = get_global_id(0);
    out[i] = hash_u32(x[i]);
}

__kernel void h_unit_float(__global const uint *x, __global float *out)
{
    const int i = get_global_id(0);
    out[i] = u32_to_unit_float(x[i]);
}

/* keys: (seed, pixel, sample, dim) per item; out: rng_uniform */
__kernel void h_rng(__global const uint *keys, __global float *out)
{
    const int i = get_global_id(0);
    out[i] = rng_uniform(keys[4 * i], keys[4 * i + 1], keys[4 * i + 2], keys[4 * i + 3]);
}

/* which: 0 cosine hemisphere, 1 uniform sphere, 2 uniform cone (param = cos_max),
 *        3 concentric disk (x, y, 0), 4 triangle barycentrics (b1, b2, 0) */
__kernel void h_sample(int which, float param, __global const float *u, __global float *out)
{
    const int i = get_global_id(0);
    const float2 uu = vload2(i, u);
    pvec3 w = pv3_zero();
    float x, y;
    if (which == 0) w = sample_cosine_hemisphere(uu.x, uu.y);
    else if (which == 1) w = sample_uniform_sphere(uu.x, uu.y);
    else if (which == 2) w = sample_uniform_cone(uu.x, uu.y, param);
    else if (which == 3) { sample_concentric_disk(uu.x, uu.y, &x, &y); w = pv3(x, y, 0.0f); }
    else if (which == 4) { sample_triangle_barycentrics(uu.x, uu.y, &x, &y); w = pv3(x, y, 0.0f); }
    store3(out, i, pv3_lane(w, 0));
}

/* the solid-angle pdf of the direction w for the sampler `which` (as in h_sample) */
__kernel void h_pdf(int which, float param, __global const float *w, __global float *out)
{
    const int i = get_global_id(0);
    const float3 d = load3(w, i);
    float p = 0.0f;
    if (which == 0) p = pdf_cosine_hemisphere(d.z);
    else if (which == 1) p = pdf_uniform_sphere();
    else if (which == 2) p = d.z >= param ? pdf_uniform_cone(param) : 0.0f;
    out[i] = p;
}

/* out: t, b, to_local(v), to_world(to_local(v)) */
__kernel void h_onb(__global const float *n, __global const float *v, __global float *out)
{
    const int i = get_global_id(0);
    const pvec3 nn = pv3_from(load3(n, i));
    pvec3 t, b;
    make_onb(nn, &t, &b);
    const pvec3 l = to_local(pv3_from(load3(v, i)), t, b, nn);
    store3(out, 4 * i, pv3_lane(t, 0));
    store3(out, 4 * i + 1, pv3_lane(b, 0));
    store3(out, 4 * i + 2, pv3_lane(l, 0));
    store3(out, 4 * i + 3, pv3_lane(to_world(l, t, b, nn), 0));
}

__kernel void h_alias(__global const Light *lights, int n, __global const float *u,
                      __global int *idx, __global float *pmf, __global float *reused)
{
    const int i = get_global_id(0);
    float p = -1.0f, r = -1.0f;
    idx[i] = sample_alias(lights, n, u[i], &p, &r);
    pmf[i] = p;
    reused[i] = r;
}

/* every u = k 2^-24 in [0, 1): item g counts the draws of u in [g per, (g+1) per) in its own row */
__kernel void h_alias_all(__global const Light *lights, int n, int per, __global int *counts)
{
    const int g = get_global_id(0);
    for (int k = g * per; k < (g + 1) * per; ++k) {
        float p, r;
        const int i = sample_alias(lights, n, (float)k * 0x1.0p-24f, &p, &r);
        counts[g * n + i] += 1;
    }
}

/* per-item cos_max: cone samples at the given u */
__kernel void h_cone(__global const float *u, __global const float *cos_max, __global float *out)
{
    const int i = get_global_id(0);
    store3(out, i, pv3_lane(sample_uniform_cone(u[2 * i], u[2 * i + 1], cos_max[i]), 0));
}

__kernel void h_power(__global const float *a, __global const float *b, __global float *out)
{
    const int i = get_global_id(0);
    out[i] = power_heuristic(a[i], b[i]);
}
""")


# ----------------------------------------------------------------------------- RNG
def np_hash(x):
    x = np.asarray(x, np.uint32).copy()
    x ^= x >> np.uint32(16)
    x *= np.uint32(0x7FEB352D)
    x ^= x >> np.uint32(15)
    x *= np.uint32(0x846CA68B)
    x ^= x >> np.uint32(16)
    return x


def np_rng_uniform(seed, pixel, sample, dim):
    """Host reference of rng_uniform in cl/render/rng.h."""
    h = np_hash(np.asarray(dim, np.uint32) + np.uint32(0x9E3779B9))
    h = np_hash(np.asarray(sample, np.uint32) ^ h)
    h = np_hash(np.asarray(pixel, np.uint32) ^ h)
    h = np_hash(np.asarray(seed, np.uint32) ^ h)
    return (h >> np.uint32(8)).astype(np.float32) * np.float32(2.0 ** -24)


def rng_draw(runtime, seed, pixel, sample, dim):
    keys = np.stack(np.broadcast_arrays(*(np.asarray(k, np.uint32) for k in (seed, pixel, sample, dim))), 1)
    keys = np.ascontiguousarray(keys, np.uint32)
    return HARNESS(runtime, "h_rng", len(keys), keys=keys, out=(len(keys), 1))


def structured_keys(n=N):
    """Keys as a renderer produces them: consecutive pixels, a few samples and dimensions."""
    i = np.arange(n, dtype=np.uint32)
    return np.uint32(2024), i >> 5, (i >> 1) & 15, (i & 1) * 7


def test_hash_matches_host_reference(runtime, rng):
    """hash_u32 and rng_uniform are the documented pure functions, bit for bit (so any device or
    split of the work gives the same numbers)."""
    x = rng.integers(0, 2 ** 32, 100_000, dtype=np.uint64).astype(np.uint32)
    x[:4] = [0, 1, 0xFFFFFFFF, 0x80000000]
    assert np.array_equal(HARNESS(runtime, "h_hash", len(x), x=x, out=x.shape), np_hash(x))
    keys = rng.integers(0, 2 ** 32, (100_000, 4), dtype=np.uint64).astype(np.uint32)
    keys[:50_000, 1:] %= 64  # small counters too
    out = rng_draw(runtime, *keys.T)
    assert np.array_equal(out[:, 0], np_rng_uniform(*keys.T))


def test_unit_float_conversion(runtime):
    """The top 24 bits scaled by 2^-24: 0 -> 0, 2^31 -> 0.5, all ones -> 1 - 2^-24 (< 1)."""
    x = np.array([0, 0xFF, 0x100, 0x80000000, 0xFFFFFFFF], np.uint32)
    out = HARNESS(runtime, "h_unit_float", len(x), x=x, out=x.shape)
    assert out.tolist() == [0.0, 0.0, 2.0 ** -24, 0.5, 1.0 - 2.0 ** -24]


def test_rng_uniform_chi2_and_range(runtime, rng):
    """1M draws over structured keys (half) and random keys (half): chi-square on 64 equal bins
    (p > ALPHA), every value in [0, 1), never 1.0, mean and variance of U(0,1)."""
    s, p, k, d = structured_keys(N // 2)
    rk = rng.integers(0, 2 ** 32, (N // 2, 4), dtype=np.uint64).astype(np.uint32)
    u = np.concatenate([rng_draw(runtime, s, p, k, d)[:, 0], rng_draw(runtime, *rk.T)[:, 0]])
    assert u.min() >= 0.0 and u.max() < 1.0 and not np.any(u == 1.0)
    counts = np.bincount((u * 64).astype(np.int64), minlength=64)
    assert_chi2(counts, np.full(64, N / 64), ALPHA, "rng 64 bins")
    assert abs(u.mean() - 0.5) < 5 * np.sqrt(1 / 12 / N)
    assert abs(u.var() - 1 / 12) < 1e-3


@pytest.mark.parametrize("key", ["dim", "pixel", "sample", "seed"])
def test_rng_neighbours_independent(runtime, key):
    """u(keys) and u(keys with `key` + 1) over 1M key sets: correlation coefficient < 0.01
    (about 10 standard errors), and a 2D chi-square on a 16 x 16 grid of the pairs (p > ALPHA)."""
    s, p, k, d = structured_keys()
    s = np.full(N, s, np.uint32)
    a = rng_draw(runtime, s, p, k, d)
    nxt = dict(seed=s, pixel=p, sample=k, dim=d)
    nxt[key] = nxt[key] + np.uint32(1)
    b = rng_draw(runtime, nxt["seed"], nxt["pixel"], nxt["sample"], nxt["dim"])
    u, v = a[:, 0].astype(np.float64), b[:, 0].astype(np.float64)
    assert abs(np.corrcoef(u, v)[0, 1]) < 0.01
    grid = np.bincount((u * 16).astype(int) * 16 + (v * 16).astype(int), minlength=256)
    assert_chi2(grid, np.full(256, N / 256), ALPHA, f"pairs of neighbouring {key}")


def test_rng_deterministic(runtime):
    """The same keys give the same values (two launches); different seeds give different streams."""
    s, p, k, d = structured_keys(200_000)
    a = rng_draw(runtime, s, p, k, d)
    b = rng_draw(runtime, s, p, k, d)
    assert np.array_equal(a, b)
    c = rng_draw(runtime, s + np.uint32(1), p, k, d)
    assert np.mean(a[:, 0] == c[:, 0]) < 1e-3


# ----------------------------------------------------------------------------- directions
SAMPLERS = {  # name: (which, param, theta_max of the sampled domain)
    "cosine_hemisphere": (0, 0.0, np.pi / 2),
    "uniform_sphere": (1, 0.0, np.pi),
}
CONES = [0.999, 0.9, 0.5, 0.0, -0.5, -0.99]
for _c in CONES:
    SAMPLERS[f"cone_{_c}"] = (2, _c, float(np.arccos(np.float64(np.float32(_c)))))

N_THETA, N_PHI = 16, 32


def direction_samples(runtime, rng, which, param, n=N):
    u = uniforms(rng, (n, 2))
    return HARNESS(runtime, "h_sample", n, which=which, param=param, u=u, out=(n, 3)).astype(np.float64)


def bin_pdf_integrals(runtime, which, param, theta_edges, phi_edges, k=6):
    """Integral of the device pdf (solid angle) over each (theta, phi) bin, by k x k-point
    Gauss-Legendre quadrature per bin in float64 (the pdf itself is evaluated on the device)."""
    x, wts = np.polynomial.legendre.leggauss(k)
    th, wth = harness.gauss_legendre_cells(theta_edges, x, wts)
    ph, wph = harness.gauss_legendre_cells(phi_edges, x, wts)
    T, P = np.meshgrid(th, ph, indexing="ij")
    dirs = np.stack([np.sin(T) * np.cos(P), np.sin(T) * np.sin(P), np.cos(T)], -1).reshape(-1, 3).astype(np.float32)
    pdf = HARNESS(runtime, "h_pdf", len(dirs), which=which, param=param, w=dirs,
                  out=len(dirs)).astype(np.float64).reshape(T.shape)
    integrand = pdf * np.sin(T) * wth[:, None] * wph[None, :]
    nt, npp = len(theta_edges) - 1, len(phi_edges) - 1
    return integrand.reshape(nt, k, npp, k).sum(axis=(1, 3))


def spherical(w):
    theta = np.arctan2(np.hypot(w[:, 0], w[:, 1]), w[:, 2])  # accurate near the poles
    phi = np.mod(np.arctan2(w[:, 1], w[:, 0]), 2 * np.pi)
    return theta, phi


@pytest.mark.parametrize("name", list(SAMPLERS))
def test_direction_sampler_chi2(runtime, rng, name):
    """Samples in the domain (unit length to 2e-6; z >= 0 for the hemisphere; cos >= cos_max
    exactly for cones), then chi-square (p > ALPHA) of 1M samples on a 16 theta x 32 phi grid
    over the domain against the integrated device pdf."""
    which, param, theta_max = SAMPLERS[name]
    w = direction_samples(runtime, rng, which, param)
    assert np.all(np.isfinite(w))
    assert np.abs(np.linalg.norm(w, axis=1) - 1).max() < 2e-6
    if which == 0:
        assert w[:, 2].min() >= 0.0
    if which == 2:
        assert w[:, 2].min() >= np.float32(param)
    theta, phi = spherical(w)
    theta = np.minimum(theta, theta_max)  # rounding of the host's arctan2 at the rim
    theta_edges = np.linspace(0, theta_max, N_THETA + 1)
    phi_edges = np.linspace(0, 2 * np.pi, N_PHI + 1)
    observed, _, _ = np.histogram2d(theta, phi, [theta_edges, phi_edges])
    assert observed.sum() == len(w)
    expected = bin_pdf_integrals(runtime, which, param, theta_edges, phi_edges) * len(w)
    assert_chi2(observed, expected, ALPHA, name)


@pytest.mark.parametrize("name", list(SAMPLERS))
def test_direction_pdf_integrates_to_one(runtime, name):
    """The device pdf integrated over the whole sphere (quadrature per bin, with the domain's
    rim as a bin edge) is 1 to 1e-5; it is 0 outside the domain."""
    which, param, theta_max = SAMPLERS[name]
    inside = np.linspace(0, theta_max, N_THETA + 1)
    edges = inside if theta_max >= np.pi else np.concatenate([inside, np.linspace(theta_max, np.pi, N_THETA + 1)[1:]])
    ints = bin_pdf_integrals(runtime, which, param, edges, np.linspace(0, 2 * np.pi, N_PHI + 1))
    assert abs(ints.sum() - 1.0) < 1e-5
    assert np.all(ints[N_THETA:] == 0.0)


def test_cone_rim_and_axis(runtime, rng):
    """At the extremes u.x = 0 and u.x = 1 - 2^-24, for 100k cos_max in (-1, 1) (many near +-1):
    z = 1 on the axis, z >= cos_max at the rim, unit length."""
    n = 100_000
    c = np.concatenate([rng.uniform(-1, 1, n // 2), 1 - 10 ** rng.uniform(-7, 0, n // 4),
                        -1 + 10 ** rng.uniform(-7, 0, n // 4)]).astype(np.float32)
    c = np.clip(c, np.nextafter(np.float32(-1), np.float32(0)), np.nextafter(np.float32(1), np.float32(0)))
    u = np.stack([np.where(np.arange(n) % 2 == 0, 1 - 2.0 ** -24, 0.0), uniforms(rng, n)], 1).astype(np.float32)
    w = HARNESS(runtime, "h_cone", n, u=u, cos_max=c, out=(n, 3))
    assert np.all(w[1::2, 2] == 1.0)
    assert np.all(w[:, 2] >= c)
    assert np.abs(np.linalg.norm(w.astype(np.float64), axis=1) - 1).max() < 2e-6


def test_closed_form_pdfs(runtime):
    """pdf values at a few directions: cos/pi (0 below the horizon), 1/(4 pi), 1/(2 pi (1 - cos_max))."""
    d = np.array([[0, 0, 1], [0.6, 0, 0.8], [1, 0, 0], [0, 0.6, -0.8]], np.float32)
    pdf = lambda which, param: HARNESS(runtime, "h_pdf", 4, which=which, param=param, w=d, out=4)
    assert np.allclose(pdf(0, 0), [1 / np.pi, 0.8 / np.pi, 0, 0], rtol=1e-6, atol=0)
    assert np.allclose(pdf(1, 0), 1 / (4 * np.pi), rtol=1e-6)
    assert np.allclose(pdf(2, 0.5), [1 / np.pi, 1 / np.pi, 0, 0], rtol=1e-6, atol=0)


def test_concentric_disk(runtime, rng):
    """Points inside the unit disk (to 1e-6); chi-square (p > ALPHA) over 10 equal-area rings x
    16 sectors; the centre of the square maps to the centre and the map is continuous there."""
    w = direction_samples(runtime, rng, 3, 0.0)
    r2 = w[:, 0] ** 2 + w[:, 1] ** 2
    assert np.sqrt(r2).max() <= 1 + 1e-6
    ring = np.minimum((r2 * 10).astype(int), 9)
    sector = np.minimum((np.mod(np.arctan2(w[:, 1], w[:, 0]), 2 * np.pi) / (2 * np.pi) * 16).astype(int), 15)
    observed = np.bincount(ring * 16 + sector, minlength=160)
    assert_chi2(observed, np.full(160, len(w) / 160), ALPHA, "concentric disk")
    u = np.array([[0.5, 0.5], [0.5 + 1e-3, 0.5], [0.5, 0.5 - 1e-3], [1 - 2 ** -24, 0.5]], np.float32)
    out = HARNESS(runtime, "h_sample", 4, which=3, param=0.0, u=u, out=(4, 3))
    assert out[0].tolist() == [0.0, 0.0, 0.0]
    assert np.allclose(out[1], [2e-3, 0, 0], atol=1e-6) and np.allclose(out[2], [0, -2e-3, 0], atol=1e-6)
    assert np.allclose(out[3], [1, 0, 0], atol=1e-6)


def test_triangle_barycentrics(runtime, rng):
    """b1, b2 >= 0 and b1 + b2 <= 1; chi-square (p > ALPHA) on a 16 x 16 grid over (b1, b2) whose
    expected counts are the areas of the cells' parts inside the triangle (pdf 2 in barycentric
    space, i.e. uniform in area on any triangle); and the mapped 3D points of a skinny triangle
    have the centroid of the triangle."""
    b = direction_samples(runtime, rng, 4, 0.0)[:, :2]
    assert b.min() >= 0.0 and (b[:, 0] + b[:, 1]).max() <= 1.0
    g = 16
    i, j = np.meshgrid(np.arange(g), np.arange(g), indexing="ij")
    area = np.where(i + j + 2 <= g, 1.0, np.where(i + j + 1 == g, 0.5, 0.0)) / g ** 2
    observed = np.bincount(np.minimum((b[:, 0] * g).astype(int), g - 1) * g
                           + np.minimum((b[:, 1] * g).astype(int), g - 1), minlength=g * g).reshape(g, g)
    assert_chi2(observed, area * 2 * len(b), ALPHA, "triangle barycentrics")
    v = np.array([[0, 0, 0], [10, 0.1, 0], [3, 1, 2]], np.float64)
    pts = (1 - b.sum(1))[:, None] * v[0] + b[:, :1] * v[1] + b[:, 1:] * v[2]
    assert np.allclose(pts.mean(0), v.mean(0), atol=5 * pts.std(0).max() / np.sqrt(len(b)))


# ----------------------------------------------------------------------------- frames
def test_onb_orthonormal_right_handed(runtime, rng):
    """100k random normals plus the axes, +-0 components and normals near the poles: t, b, n
    orthonormal to 1e-6, cross(t, b) = n to 1e-6; to_local(n) = z and to_world inverts to_local."""
    special = [[0, 0, 1], [0, 0, -1], [1, 0, 0], [-1, 0, 0], [0, 1, 0], [0, -1, 0], [1, 0, -0.0], [0, -1, -0.0],
               [1e-7, 0, -1], [0, 1e-7, -1], [-1e-7, 1e-7, 1], [1e-4, -1e-4, -1], [1e-3, 0, 1], [1, 1e-7, 1e-7],
               [-1, 0, 1e-6], [0.3, 0.4, -1e-7], [0.3, 0.4, 1e-7], [1e-20, 0, -1], [0, 0, -1 + 1e-7]]
    n = rng.normal(size=(100_000, 3))
    n[:, 2] *= np.where(rng.random(len(n)) < 0.2, 1e-3, 1)  # many near the equator
    n[:1000, :2] *= 1e-4  # and near the poles
    n = np.concatenate([np.array(special, np.float64), n])
    n = (n / np.linalg.norm(n, axis=1, keepdims=True)).astype(np.float32)
    v = rng.normal(size=n.shape).astype(np.float32)
    out = HARNESS(runtime, "h_onb", len(n), n=n, v=v, out=(len(n), 4, 3)).astype(np.float64)
    t, b, loc, back = out[:, 0], out[:, 1], out[:, 2], out[:, 3]
    n64 = n.astype(np.float64)
    dot = lambda x, y: np.sum(x * y, axis=1)
    for name, err in [("|t|", np.linalg.norm(t, axis=1) - 1), ("|b|", np.linalg.norm(b, axis=1) - 1),
                      ("t.b", dot(t, b)), ("t.n", dot(t, n64)), ("b.n", dot(b, n64))]:
        assert np.abs(err).max() < 1e-6, f"{name}: {np.abs(err).max():.3g} at {n[np.argmax(np.abs(err))]}"
    assert np.abs(np.cross(t, b) - n64).max() < 1e-6
    assert np.allclose(loc, np.stack([dot(v, t), dot(v, b), dot(v, n64)], 1), atol=1e-5)
    assert np.allclose(back, v, atol=1e-5)
    assert np.all(np.isfinite(out))


# ----------------------------------------------------------------------------- alias table
def implied_distribution(prob, alias):
    """The probability of drawing each index from the table, in float64."""
    n = len(prob)
    p = prob.astype(np.float64) / n
    np.add.at(p, alias, (1 - prob.astype(np.float64)) / n)
    return p


ALIAS_CASES = {
    "mixed_with_zeros": lambda rng: np.where(rng.random(50) < 0.3, 0.0, rng.random(50) * 10),
    "single": lambda rng: np.array([3.5]),
    "wide_range": lambda rng: 10 ** rng.uniform(-6, 6, 24),
    "equal": lambda rng: np.ones(7),
    "one_nonzero": lambda rng: np.array([0, 0, 0, 2.0, 0, 0]),
}


@pytest.mark.parametrize("case", list(ALIAS_CASES))
def test_alias_table_host(rng, case):
    """pmf sums to 1 and is proportional to the weights; the table draws each index with
    exactly its pmf (to 1e-6); zero weights have pmf 0, keep-probability 0 and are nobody's alias."""
    w = ALIAS_CASES[case](rng)
    pmf, prob, alias = build_alias_table(w)
    assert pmf.dtype == np.float32 and prob.dtype == np.float32 and alias.dtype == np.int32
    assert abs(pmf.astype(np.float64).sum() - 1) < 1e-6
    assert np.allclose(pmf, w / w.sum(), rtol=1e-6, atol=0)
    assert np.all((prob >= 0) & (prob <= 1)) and np.all((alias >= 0) & (alias < len(w)))
    assert np.abs(implied_distribution(prob, alias) - w / w.sum()).max() < 1e-6
    zero = w == 0
    assert np.all(pmf[zero] == 0) and np.all(prob[zero] == 0)
    assert not np.any(zero[alias[prob < 1]])
    assert np.all(alias[prob == 1] == np.flatnonzero(prob == 1))


def test_alias_table_errors_and_fill():
    for bad in ([], [0.0, 0.0], [1.0, -1.0], [1.0, np.nan], [np.inf]):
        with pytest.raises(ValueError):
            build_alias_table(bad)
    lights = np.zeros(3, abi.LIGHT)
    lights["kind"] = [0, 1, 0]
    lights["prim"] = [5, 6, 7]
    fill_light_table(lights, [1.0, 0.0, 3.0])
    assert lights["pmf"].tolist() == [0.25, 0.0, 0.75]
    assert lights["prim"].tolist() == [5, 6, 7] and lights["kind"].tolist() == [0, 1, 0]
    pmf, prob, alias = build_alias_table([1.0, 0.0, 3.0])
    assert np.array_equal(lights["alias_prob"], prob) and np.array_equal(lights["alias"], alias)
    with pytest.raises(ValueError):
        fill_light_table(lights, [1.0, 2.0])


def light_table(w):
    lights = np.zeros(len(w), abi.LIGHT)
    lights["prim"] = np.arange(len(w))
    return fill_light_table(lights, w)


@pytest.mark.parametrize("case", list(ALIAS_CASES))
def test_alias_device_chi2(runtime, rng, case):
    """1M uniform u through sample_alias on the device: frequencies match the pmf (chi-square,
    p > ALPHA), zero-weight lights are never drawn, *pmf is the drawn light's pmf.  The reused
    remainder (*u_reused, which places the light point) lies in [0, 1) and is uniform given the
    light drawn: for each light drawn 20000 times or more, its 16 bins (chi-square)."""
    w = ALIAS_CASES[case](rng)
    lights = light_table(w)
    u = uniforms(rng, N)
    u[:5] = [0.0, 1 - 2.0 ** -24, 0.5, 1.0 / 3.0, 1 - 2.0 ** -23]
    idx, pmf, reused = HARNESS(runtime, "h_alias", N, lights=lights, n=len(lights), u=u, idx=N, pmf=N, reused=N)
    assert reused.min() >= 0 and reused.max() < 1
    for light in np.unique(idx):
        r = reused[idx == light]
        if len(r) >= 20000:
            bins = np.bincount(np.minimum((r * 16).astype(int), 15), minlength=16)
            assert_chi2(bins, np.full(16, len(r) / 16), ALPHA, f"{case}: the reused u of light {light}")
    assert idx.min() >= 0 and idx.max() < len(w)
    assert not np.any(w[idx] == 0), "a zero-weight light was drawn"
    assert np.array_equal(pmf, lights["pmf"][idx])
    observed = np.bincount(idx, minlength=len(w))
    if np.count_nonzero(w) == 1:
        assert observed[np.flatnonzero(w)[0]] == N
    else:
        assert_chi2(observed[w > 0], lights["pmf"][w > 0].astype(np.float64) * N, ALPHA, case)


@pytest.mark.parametrize("case", ["mixed_with_zeros", "wide_range", "equal", "one_nonzero"])
def test_alias_device_exhaustive(runtime, rng, case):
    """Every one of the 2^24 float32 u = k 2^-24 in [0, 1): each light is drawn with its pmf up to
    the 2^-24 quantisation of u (|freq - pmf| < 2 n 2^-24) and zero-weight lights never."""
    w = ALIAS_CASES[case](rng)
    lights = light_table(w)
    items, per = 4096, (1 << 24) // 4096
    counts = HARNESS(runtime, "h_alias_all", items, lights=lights, n=len(lights), per=per, counts=(items, len(w)))
    freq = counts.sum(0) / 2.0 ** 24
    assert counts.sum() == 1 << 24
    assert np.all(freq[w == 0] == 0)
    assert np.abs(freq - w / w.sum()).max() < 2 * len(w) * 2.0 ** -24


# ----------------------------------------------------------------------------- MIS
def test_power_heuristic(runtime):
    """Closed forms (1,1) -> 0.5, (2,1) -> 0.8, (1,2) -> 0.2, pdf_b = 0 -> 1, pdf_a = inf -> 1,
    pdf_a = 0 -> 0; huge and tiny pdfs neither overflow nor give NaN; a + b weights sum to 1."""
    inf = np.inf
    cases = [(1, 1, 0.5), (2, 1, 0.8), (1, 2, 0.2), (3, 0, 1.0), (0, 0, 1.0), (inf, 1, 1.0), (inf, 0, 1.0),
             (0, 1, 0.0), (1, inf, 0.0), (inf, inf, 0.5), (1e30, 1e30, 0.5), (1e-30, 1e-30, 0.5),
             (1e30, 1e-30, 1.0), (1e-30, 1e30, 0.0), (1e-45, 1e-45, 0.5)]
    a = np.array([c[0] for c in cases], np.float32)
    b = np.array([c[1] for c in cases], np.float32)
    out = HARNESS(runtime, "h_power", len(a), a, b, a.shape)
    assert not np.any(np.isnan(out))
    assert np.allclose(out, [c[2] for c in cases], rtol=1e-6, atol=0), out
    rng = np.random.default_rng(7)
    a = (10 ** rng.uniform(-10, 10, 10000)).astype(np.float32)
    b = (10 ** rng.uniform(-10, 10, 10000)).astype(np.float32)
    ab = HARNESS(runtime, "h_power", len(a), a, b, a.shape).astype(np.float64)
    ba = HARNESS(runtime, "h_power", len(a), b, a, a.shape).astype(np.float64)
    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    assert np.allclose(ab, a64 ** 2 / (a64 ** 2 + b64 ** 2), rtol=1e-5, atol=1e-30)
    assert np.allclose(ab + ba, 1.0, atol=1e-6)
