"""The samplers of cl/render/sampler.h: Owen-scrambled Sobol in the ZSobol arrangement (the
default), progressive stratified, and independent; the Sobol table of pyopencl_rt/device/sobol.py.

- bit for bit: the device equals a numpy copy written here from the documented construction, so
  every device and every split of the work (devices, Dask, resumed renders) draws the same numbers;
- the Sobol matrices equal scipy's unscrambled Sobol points (Joe and Kuo's numbers, another
  implementation);
- (0,2)-sequence: every aligned run of 2^k passes of one pixel is a (0,k,2)-net in each 2D sample
  (each elementary interval of area 2^-k holds one point), and a 2x2 / 4x4 pixel group at the end
  of a block is one net (the blue-noise arrangement), checked exactly on the 24-bit outputs;
- uniformity: chi2 of every dimension the kernels use, at 1 spp over many pixels and at many spp
  over few pixels;
- independence: Pearson correlations between neighbouring pixels, seeds and padded dimensions are
  within 5 standard errors of 0;
- convergence: on a small Cornell box the relMSE measured over independent seeds falls faster than
  1/N with Sobol (and as 1/N with the independent sampler).

ALPHA = 1e-4 for the chi2 tests; the inputs are fixed, so a run is reproducible."""
import os
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.device import abi, sobol

import harness
from harness import assert_chi2

ALPHA = 1e-4
Z_MAX = 5.0  # correlation tests: |r| sqrt(n) under this (two-sided p ~ 6e-7 each)

SOURCE = r"""
#include "render/sampler.h"
/* keys: (seed, pixel, width, pass, dim) per item; out: sample_2d then sample_1d.  Work-item i
 * draws items i * PACKET_WIDTH .. + PACKET_WIDTH in its lanes (seed and width: its first item's).
 * kind: the sampler, read where no SAMPLER is compiled in (the kernels' run-time choice). */
__kernel void h_sampler(__global const uint *keys, __global float *out, const int kind)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    puint pixel, pass, dim;
    for (int j = 0; j < PACKET_WIDTH; ++j) {
        __global const uint *k = keys + 5 * (base + j);
        PLANE_U(pixel, j) = k[1]; PLANE_U(pass, j) = k[3]; PLANE_U(dim, j) = k[4];
    }
    const SampleKey sk = sampler_key(kind, keys[5 * base], pixel, keys[5 * base + 2], pass);
    pfloat u, v;
    sample_2d(sk, dim, &u, &v);
    const pfloat w = sample_1d(sk, dim);
    for (int j = 0; j < PACKET_WIDTH; ++j) {
        out[3 * (base + j)] = PLANE(u, j);
        out[3 * (base + j) + 1] = PLANE(v, j);
        out[3 * (base + j) + 2] = PLANE(w, j);
    }
}

#if PACKET_WIDTH == 1
/* Sobol dimension 1: the closed form (un-reversed) and the generated table */
__kernel void h_sobol1(__global const uint *index, __global uint *out)
{
    const int i = get_global_id(0);
    out[2 * i] = reverse_bits32(sobol_dim1_reversed(index[i]));
    out[2 * i + 1] = sobol_dim1_table(index[i]);
}
#endif

__kernel void h_layout(__global uint *out)
{
    out[0] = DIM_PIXEL; out[1] = DIM_LENS; out[2] = DIMS_PER_BOUNCE; out[3] = DIM_LIGHT_PICK;
    out[4] = DIM_LIGHT_POINT; out[5] = DIM_BSDF; out[6] = DIM_RR; out[7] = DIM_BSDF_LOBE;
}
"""
KERNELS = {name: harness.Kernels(SOURCE, defines={"SAMPLER": value}) for name, value in abi.SAMPLERS.items()}
SMALL_ROUND = 4  # a ZSobol build with blocks of 16 passes, to check whole blocks cheaply
SOBOL_SMALL = harness.Kernels(SOURCE, defines={"SAMPLER": abi.SAMPLERS["sobol"], "SOBOL_LOG2_ROUND": SMALL_ROUND})
ANY_SAMPLER = harness.Kernels(SOURCE)  # no SAMPLER: the one program of every sampler, `kind` chooses
for _name, _kernels in KERNELS.items():
    _kernels.kind = abi.SAMPLERS[_name]
SOBOL_SMALL.kind = abi.SAMPLERS["sobol"]


def draw(runtime, kernels, seed, pixel, width, passes, dim, kind=None):
    """The samples of each (seed, pixel, width, pass, dim), drawn by ``kernels`` (sampler ``kind``:
    the one compiled in unless given)."""
    keys = np.stack(np.broadcast_arrays(*(np.asarray(k, np.uint32) for k in (seed, pixel, width, passes, dim))), -1)
    shape = keys.shape[:-1]
    keys = np.ascontiguousarray(keys.reshape(-1, 5), np.uint32)
    kind = kernels.kind if kind is None else kind
    out = kernels(runtime, "h_sampler", len(keys), keys=keys, out=(len(keys), 3), kind=np.int32(kind))
    return out.reshape(*shape, 3)


def dims_used(runtime, bounces=3):
    """(first id, 1 or 2) of every sample the kernels draw, from cl/scene/scene.h's layout."""
    pixel, lens, per_bounce, pick, point, bsdf, rr, lobe = KERNELS["sobol"](runtime, "h_layout", 1, out=8)
    used = [(pixel, 2), (lens, 2)]
    for depth in range(bounces):
        base = 2 + per_bounce * depth
        used += [(base + pick, 1), (base + point, 2), (base + bsdf, 2), (base + rr, 1), (base + lobe, 1)]
    ids = [d + j for d, n in used for j in range(n)]
    assert len(set(ids)) == len(ids), "two samples share a dimension id"
    return used


# ----------------------------------------------------------------------------- numpy copy
U = np.uint32


def np_hash(x):
    x = np.asarray(x, U).copy()
    x ^= x >> U(16)
    x *= U(0x7FEB352D)
    x ^= x >> U(15)
    x *= U(0x846CA68B)
    x ^= x >> U(16)
    return x


def np_rng_hash(seed, pixel, sample, dim):
    h = np_hash(np.asarray(dim, U) + U(0x9E3779B9))
    h = np_hash(np.asarray(sample, U) ^ h)
    h = np_hash(np.asarray(pixel, U) ^ h)
    return np_hash(np.asarray(seed, U) ^ h)


def np_reverse(x):
    x = np.asarray(x, U)
    bits = (x[..., None] >> np.arange(32, dtype=U)) & U(1)
    return (bits << np.arange(31, -1, -1, dtype=U)).sum(-1, dtype=np.uint64).astype(U)


def np_lk(x, seed):
    """Laine and Karras's permutation with Burley's constants."""
    x = np.asarray(x, U) + np.asarray(seed, U)
    for c in (0x6C50B47C, 0xB82F1E52, 0xC7AFE638, 0x8D22F6E6):
        x = x ^ (x * U(c))
    return x


def np_nested_scramble(x, seed):
    """Burley's nested uniform scramble: reverse, Laine-Karras permutation, reverse."""
    return np_reverse(np_lk(np_reverse(x), seed))


def np_sobol(index, dim):
    columns = sobol.generator_matrix(dim)
    v = np.zeros_like(index, U)
    for k in range(32):
        v ^= np.where((index >> U(k)) & U(1), columns[k], U(0))
    return v


def np_morton(x, y):
    out = np.zeros_like(x, U)
    for b in range(16):
        out |= ((x >> U(b)) & U(1)) << U(2 * b) | ((y >> U(b)) & U(1)) << U(2 * b + 1)
    return out


def to_float(h):
    return (h >> U(8)).astype(np.float32) * np.float32(2.0 ** -24)


def np_sampler(name, seed, pixel, width, passes, dim, log2_round=abi.SOBOL_LOG2_ROUND):
    seed, pixel, width, passes, dim = (np.asarray(a, U) for a in np.broadcast_arrays(seed, pixel, width, passes, dim))
    if name == "independent":
        h = [np_rng_hash(seed, pixel, passes, dim + U(j)) for j in (0, 1)]
        return np.stack([to_float(h[0]), to_float(h[1]), to_float(h[0])], -1)
    if name == "sobol":
        tile_bits = (32 - log2_round) // 2
        x, y = pixel % width, pixel // width
        mask = U((1 << tile_bits) - 1)
        index = np_morton(x & mask, y & mask) << U(log2_round) | (passes & U((1 << log2_round) - 1))
        key = np_rng_hash(seed, (x >> U(tile_bits)) | ((y >> U(tile_bits)) << U(16)), passes >> U(log2_round),
                          0x50B01)
    else:
        index = passes
        key = np_rng_hash(seed, pixel, 0, 0x57A7)
    s0 = np_hash(key ^ np_hash(dim + U(0x9E3779B9)))
    seeds = [s0] + [np_hash(s0 ^ U(j)) for j in (1, 2, 3)]
    shuffled = np_nested_scramble(index, seeds[0])
    if name == "sobol":
        u, v = np_reverse(shuffled), np_sobol(shuffled, 1)
    else:
        cells = np_lk(shuffled, seeds[3])
        even = np.zeros_like(shuffled)
        odd = np.zeros_like(shuffled)
        for b in range(16):
            even |= ((cells >> U(2 * b)) & U(1)) << U(b)
            odd |= ((cells >> U(2 * b + 1)) & U(1)) << U(b)
        u, v = np_reverse(even), np_reverse(odd)
    return np.stack([to_float(np_nested_scramble(u, seeds[1])), to_float(np_nested_scramble(v, seeds[2])),
                     to_float(np_nested_scramble(np_reverse(shuffled), seeds[1]))], -1)


# ----------------------------------------------------------------------------- the table
def test_sobol_matrices_equal_scipys_points():
    """Points C * gray(i) of the first 8 dimensions equal scipy's unscrambled Sobol points (which
    come in Gray-code order) over 2^12 indices, and the header holds the first two."""
    from scipy.stats import qmc

    n, dims = 1 << 12, 8
    i = np.arange(n, dtype=U)
    ours = np.stack([np_sobol(i ^ (i >> U(1)), d) for d in range(dims)], 1)
    theirs = qmc.Sobol(dims, scramble=False, bits=32).random(n)
    assert np.array_equal(ours.astype(np.float64) * 2.0 ** -32, theirs)
    table = sobol.cl_table()
    assert "SOBOL_MATRIX[2][32]" in table and f"0x{int(sobol.generator_matrix(1)[5]):08x}u" in table


def test_sobol_closed_form_equals_table(runtime, rng):
    """The kernels' 5-step form of Sobol dimension 1 equals the generated SOBOL_MATRIX table and
    the host matrix, over random and structured indices."""
    index = np.concatenate([rng.integers(0, 2 ** 32, 50_000, dtype=np.uint64).astype(U), np.arange(1 << 14, dtype=U),
                            (U(1) << np.arange(32, dtype=U)), np.array([0xFFFFFFFF], U)])
    out = KERNELS["sobol"](runtime, "h_sobol1", len(index), index=index, out=(len(index), 2))
    assert np.array_equal(out[:, 0], out[:, 1])
    assert np.array_equal(out[:, 0], np_sobol(index, 1))


# ----------------------------------------------------------------------------- bit for bit
@pytest.mark.parametrize("name", list(abi.SAMPLERS))
def test_device_equals_numpy_copy(runtime, rng, name):
    n = 20_000
    seed = rng.integers(0, 2 ** 32, n, dtype=np.uint64).astype(U)
    width = rng.integers(1, 9000, n).astype(U)
    pixel = (rng.integers(0, 2 ** 26, n) % (width * rng.integers(1, 9000, n))).astype(U)
    passes = np.where(rng.random(n) < 0.5, rng.integers(0, 300, n), rng.integers(0, 2 ** 32, n, dtype=np.uint64))
    dim = rng.integers(0, 40, n).astype(U)
    got = draw(runtime, KERNELS[name], seed, pixel, width, passes.astype(U), dim)
    assert np.array_equal(got, np_sampler(name, seed, pixel, width, passes.astype(U), dim))
    assert got.min() >= 0.0 and got.max() < 1.0
    again = draw(runtime, KERNELS[name], seed, pixel, width, passes.astype(U), dim)
    assert np.array_equal(got, again)  # deterministic
    other = draw(runtime, KERNELS[name], seed + U(1), pixel, width, passes.astype(U), dim)
    assert np.mean(other == got) < 0.01  # another seed, other numbers
    # the program of every sampler (PYOPENCL_RT_KERNEL_FEATURES=all) draws the same bits when told this one
    assert np.array_equal(draw(runtime, ANY_SAMPLER, seed, pixel, width, passes.astype(U), dim,
                               kind=abi.SAMPLERS[name]), got)


@pytest.mark.parametrize("width", [8, 16])
@pytest.mark.parametrize("name", list(abi.SAMPLERS))
def test_lanes_draw_the_same_samples(device, runtime, rng, name, width):
    """The sampler compiled at 8 or 16 lanes (the CPU lane megakernel) draws in each lane what the
    one-lane build (GPUs, the wavefront) draws for that lane's key, bit for bit, at every
    bounce's ids and at arbitrary ones."""
    harness.require_lane_kernels(device, width)
    n = width * 1024
    groups = n // width
    seed = np.repeat(rng.integers(0, 2 ** 32, groups, dtype=np.uint64).astype(U), width)
    image_width = np.repeat(rng.integers(1, 9000, groups).astype(U), width)
    keys = np.stack([seed, (rng.integers(0, 2 ** 26, n) % image_width).astype(U), image_width,
                     np.where(rng.random(n) < 0.5, rng.integers(0, 300, n),
                              rng.integers(0, 2 ** 32, n, dtype=np.uint64)).astype(U),
                     np.where(rng.random(n) < 0.8, 2 + 8 * rng.integers(0, 64, n),
                              rng.integers(0, 2 ** 32, n, dtype=np.uint64)).astype(U)], -1)
    keys = np.ascontiguousarray(keys)
    lanes = harness.Kernels(SOURCE, defines={"SAMPLER": abi.SAMPLERS[name], "PACKET_WIDTH": width})
    kind = np.int32(abi.SAMPLERS[name])
    one = KERNELS[name](runtime, "h_sampler", n, keys=keys, out=(n, 3), kind=kind)
    wide = lanes(runtime, "h_sampler", groups, keys=keys, out=(n, 3), kind=kind)
    assert np.array_equal(one.view(np.uint32), wide.view(np.uint32))
    assert one.min() >= 0.0 and one.max() < 1.0
    assert len(np.unique(one[:, :2])) > 0.99 * 2 * n


def test_small_round_equals_numpy_copy(runtime, rng):
    n = 5000
    pixel, passes, dim = rng.integers(0, 1 << 20, n), rng.integers(0, 200, n), rng.integers(0, 30, n)
    got = draw(runtime, SOBOL_SMALL, 7, pixel, 1000, passes, dim)
    assert np.array_equal(got, np_sampler("sobol", 7, pixel, 1000, passes, dim, log2_round=SMALL_ROUND))


# ----------------------------------------------------------------------------- nets
def assert_nets(u, v, what):
    """Each row of (u, v) (2^k points each) is a (0,k,2)-net in base 2: every elementary interval
    [a 2^-i, (a+1) 2^-i) x [b 2^-(k-i), (b+1) 2^-(k-i)) holds exactly one point."""
    n = u.shape[-1]
    k = n.bit_length() - 1
    assert n == 1 << k
    iu = (u.astype(np.float64) * 2 ** 24).astype(np.int64)
    iv = (v.astype(np.float64) * 2 ** 24).astype(np.int64)
    for i in range(k + 1):
        cell = (iu >> (24 - i)) << (k - i) | (iv >> (24 - (k - i)))
        ok = (np.sort(cell, axis=-1) == np.arange(n)).all(axis=-1)
        assert ok.all(), f"{what}: {np.count_nonzero(~ok)} of {ok.size} point sets miss a {2**i}x{2**(k-i)} interval"


def test_sobol_pixels_are_02_sequences(runtime, rng):
    """For N = 2^k (k = 0..10) the passes [j N, (j+1) N) of a pixel are a (0,k,2)-net in every 2D
    sample, for random pixels, widths and seeds."""
    used = [d for d, size in dims_used(runtime, bounces=2) if size == 2]
    pixels = 24
    width = rng.integers(1, 5000, pixels)
    pixel = rng.integers(0, 1 << 24, pixels) % (width * 4000)
    seed = rng.integers(0, 2 ** 32, pixels, dtype=np.uint64)
    passes = np.arange(1 << 11)
    u = draw(runtime, KERNELS["sobol"], seed[:, None, None], pixel[:, None, None], width[:, None, None],
             passes[None, None, :], np.array(used)[None, :, None])
    for k in range(11):
        blocks = u[..., :2].reshape(pixels, len(used), -1, 1 << k, 2)  # runs of 2^k passes
        assert_nets(blocks[..., 0], blocks[..., 1], f"{1 << k} passes")
    # 1D samples: the first dimension of the same nets, so 2^k passes fill the 2^k intervals
    one = (u[..., 2].reshape(pixels, len(used), -1, 1 << 8) * 256).astype(int)
    assert (np.sort(one, axis=-1) == np.arange(256)).all()


def test_sobol_pixel_groups_are_nets_at_block_ends(runtime):
    """The ZSobol arrangement: with blocks of 2^4 passes, the 2x2 pixel groups (64 samples) and
    4x4 groups (256 samples) of each block are nets too: neighbouring pixels' samples fill each
    other's gaps (blue-noise error), in two rounds."""
    width = 40
    for side in (2, 4):
        gx, gy = np.meshgrid(np.arange(0, 32, side), np.arange(0, 32, side))
        ox, oy = np.meshgrid(np.arange(side), np.arange(side))
        x = gx.reshape(-1, 1) + ox.reshape(1, -1)
        y = gy.reshape(-1, 1) + oy.reshape(1, -1)
        pixel = (y * width + x)[:, :, None]  # group, pixel of the group, pass
        for rnd in (0, 1):
            passes = rnd * 16 + np.arange(16)[None, None, :]
            for dim in (0, 3, 13):
                u = draw(runtime, SOBOL_SMALL, 99, pixel, width, passes, dim).reshape(len(pixel), -1, 3)
                assert_nets(u[..., 0], u[..., 1], f"{side}x{side} groups, round {rnd}, dim {dim}")


def test_stratified_fills_grids(runtime, rng):
    """Stratified: 4^k passes put one sample in each cell of a 2^k x 2^k grid (k = 0..5) and 2^k
    passes one 1D sample in each 1/2^k interval, in every sample of random pixels; and the jitter
    inside the cells is each sample's own (no two of the 1024 share a coordinate, as they would if
    a grid column shared its offsets)."""
    used = [d for d, _ in dims_used(runtime, bounces=1)]
    pixel = rng.integers(0, 1 << 24, 16)
    u = draw(runtime, KERNELS["stratified"], 5, pixel[:, None, None], 3000, np.arange(1 << 10)[None, None, :],
             np.array(used)[None, :, None])
    for k in range(6):
        cells = (u[..., :2] * (1 << k)).astype(int).reshape(16, len(used), -1, 1 << 2 * k, 2)
        index = np.sort(cells[..., 0] * (1 << k) + cells[..., 1], axis=-1)
        assert (index == np.arange(1 << 2 * k)).all(), f"{1 << k}^2 grid"
    one = (u[..., 2] * 1024).astype(int)
    assert (np.sort(one, axis=-1) == np.arange(1024)).all()
    for c in (0, 1):
        distinct = [len(np.unique(row)) for row in u[..., c].reshape(-1, 1024)]
        assert min(distinct) >= 1000, f"coordinate {c}: as few as {min(distinct)} distinct values of 1024"


# ----------------------------------------------------------------------------- uniformity
@pytest.mark.parametrize("name", ["sobol", "stratified"])
def test_every_dimension_uniform(runtime, name):
    """chi2 of each dimension the kernels use: at 1 spp over 2^15 pixels of a 256 x 128 image and
    at 1024 spp over 32 pixels: 64 bins in 1D, 16 x 16 in 2D."""
    for what, pixel, passes in (("1 spp", np.arange(1 << 15)[:, None], np.zeros((1, 1), int)),
                                ("1024 spp", np.arange(0, 1 << 15, 1 << 10)[:, None], np.arange(1024)[None, :])):
        for dim, size in dims_used(runtime, bounces=2):
            u = draw(runtime, KERNELS[name], 11, pixel, 256, passes, dim).reshape(-1, 3)
            if size == 1:
                counts = np.bincount((u[:, 2] * 64).astype(int), minlength=64)
            else:
                counts = np.bincount((u[:, 0] * 16).astype(int) * 16 + (u[:, 1] * 16).astype(int), minlength=256)
            assert_chi2(counts, np.full(len(counts), len(u) / len(counts)), ALPHA, f"{name} {what} dim {dim}")


# ----------------------------------------------------------------------------- independence
def assert_uncorrelated(a, b, what):
    a = a - a.mean()
    b = b - b.mean()
    r = float((a * b).sum() / np.sqrt((a * a).sum() * (b * b).sum()))
    z = r * np.sqrt(len(a))
    assert abs(z) < Z_MAX, f"{what}: correlation {r:.4f} (z = {z:.1f}) over {len(a)} pairs"


@pytest.mark.parametrize("name", ["sobol", "stratified"])
def test_scrambles_independent(runtime, name):
    """Pearson correlation over 2^15 pixels, at passes 0, 1 and 5: a pixel against its right and
    lower neighbours, a pixel of another Sobol tile, the same pixel with the next seed, and two
    padded samples of one pixel (pixel jitter x against the BSDF sample x of bounce 0 and
    against the 1D light pick)."""
    width = 512
    x, y = np.meshgrid(np.arange(0, 256, 2), np.arange(0, 512, 2))
    pixel = (y * width + x).ravel()
    for s in (0, 1, 5):
        base = draw(runtime, KERNELS[name], 3, pixel, width, s, 0)
        pairs = {"right neighbour": (3, pixel + 1, 0), "lower neighbour": (3, pixel + width, 0),
                 "next seed": (4, pixel, 0), "other tile": (3, pixel + 256, 0)}
        for what, (seed, other, dim) in pairs.items():
            u = draw(runtime, KERNELS[name], seed, other, width, s, dim)
            for c in (0, 1):
                assert_uncorrelated(base[:, c], u[:, c], f"{name} pass {s} {what} coordinate {c}")
        assert_uncorrelated(base[:, 0], base[:, 1], f"{name} pass {s} x against y")
        bsdf = draw(runtime, KERNELS[name], 3, pixel, width, s, 5)
        assert_uncorrelated(base[:, 0], bsdf[:, 0], f"{name} pass {s} pixel x against BSDF x")
        assert_uncorrelated(base[:, 0], bsdf[:, 2], f"{name} pass {s} pixel x against a 1D sample")


# ----------------------------------------------------------------------------- convergence
def test_sobol_error_falls_faster_than_monte_carlo(device):
    """relMSE (eps = 1e-2) of the 32 x 32 Cornell box at 4..64 spp, measured as the variance over 8
    seeds (each sampler is unbiased, so that variance is the error and no reference is needed):
    the fitted log-log slope is about -1 with independent samples (checks the method) and steeper
    than -1.1 with Sobol (about -1.2 measured: the pixel and first-bounce dimensions are well
    stratified; the deeper bounces keep the Monte Carlo rate)."""
    from pyopencl_rt.render.film import Film
    from pyopencl_rt.render.wavefront import Wavefront
    from pyopencl_rt.scene.loaders import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "scenes" / "cornell-box.toml")
    spp = [4, 8, 16, 32, 64]
    slopes = {}
    for name in ("independent", "sobol"):
        images = []
        for seed in range(8):
            wf = Wavefront(scene, device, width=32, height=32, seed=seed, sampler=name)
            film, done, row = Film(32, 32), 0, []
            for n in spp:
                wf.run(film, passes=n - done, first_pass=done)
                done = n
                row.append(film.image().astype(np.float64))
            images.append(row)
        images = np.array(images)  # seed, spp, H, W, 3
        mean = images.mean(axis=0)
        relmse = (images.var(axis=0, ddof=1) / (mean * mean + 1e-2)).mean(axis=(1, 2, 3))
        slopes[name] = float(np.polyfit(np.log(spp), np.log(relmse), 1)[0])
    assert -1.15 < slopes["independent"] < -0.85, slopes
    assert slopes["sobol"] < -1.1, slopes


# ----------------------------------------------------------------------------- the setting
def test_sampler_is_an_image_setting(tmp_path, device):
    """The sampler comes from [render] sampler, the API and the CLI, is checked, compiled in as
    -DSAMPLER, recorded in the sidecar and keyed into checkpoints; each sampler gives its own
    image (same seed, same image: tests/render/test_multidevice.py and test_checkpoint.py)."""
    import subprocess
    import sys

    from pyopencl_rt.errors import UserError
    from pyopencl_rt.render import checkpoint as ckp
    from pyopencl_rt.render.api import render_full
    from pyopencl_rt.render.settings import ImageSettings, every_feature
    from pyopencl_rt.scene.loaders import load_scene
    from scenes_small import small_scene

    scene = small_scene(width=16, height=12)
    assert ImageSettings.resolve(scene).sampler == "sobol"
    assert ImageSettings.resolve(scene, sampler="stratified").sampler == "stratified"
    with pytest.raises(UserError, match="sampler") as e:
        ImageSettings.resolve(scene, sampler="halton")
    assert "\n" not in str(e.value)

    toml = tmp_path / "s.toml"
    toml.write_text('[render]\nsampler = "independent"\n[materials.l]\nemission = [1, 1, 1]\n'
                    '[[shape]]\ntype = "sphere"\nmaterial = "l"\ncenter = [0, 0, -3]\nradius = 1\n')
    assert load_scene(toml).settings.sampler == "independent"
    toml.write_text(toml.read_text().replace('"independent"', '"halton"'))
    with pytest.raises(UserError, match="sampler"):
        load_scene(toml)

    path = tmp_path / "r.ckpt.npz"
    images = {}
    for name in ("sobol", "independent"):
        r = render_full(scene, spp=2, device=device, sampler=name, checkpoint=path if name == "sobol" else None,
                        checkpoint_every=1e-6 if name == "sobol" else None)
        assert r.info["sampler"] == name
        # compiled in per scene; with every feature, the kernels' run-time argument
        assert (f"SAMPLER={abi.SAMPLERS[name]}" in r.info["features"]) == (not every_feature())
        images[name] = r.image
    assert not np.array_equal(images["sobol"], images["independent"])
    with pytest.raises(ckp.CheckpointError, match="sampler 'sobol' -> 'stratified'"):
        render_full(scene, spp=3, device=device, checkpoint=path, resume=True, sampler="stratified")

    repo = Path(__file__).resolve().parents[2]
    run = subprocess.run([sys.executable, "-m", "pyopencl_rt.cli", "render", str(toml), "--sampler", "nope"],
                         cwd=tmp_path, capture_output=True, text=True, env={**os.environ, "PYTHONPATH": str(repo)})
    assert run.returncode == 2 and "--sampler" in run.stderr
