"""cl/cpu_builtins.h: the inline versions of the OpenCL builtins, against the builtins themselves
(the same kernel built with RT_PORTABLE_BUILTINS) and against numpy.

The functions documented as bit-exact must equal the builtin bit for bit on every input,
including NaN, infinities, signed zeros and denormals; dot/cross/length/normalize are checked
against float64 numpy within a few ulp, and normalize/length at squared lengths that over- or
underflow float32 (where the inline code must hand over to the builtin's rescaling)."""
import numpy as np
import pytest

from tests import harness

SOURCE = r'''
#include "common.h"
__kernel void h_unary(__global const float *x, __global float *fabs_out, __global float *floor_out,
                      __global float *sqrt_out, __global int *finite_out, __global int *inf_out)
{
    const int i = get_global_id(0);
    fabs_out[i] = fabs(x[i]);
    floor_out[i] = floor(x[i]);
    sqrt_out[i] = sqrt(x[i]);
    finite_out[i] = isfinite(x[i]) ? 1 : 0;
    inf_out[i] = isinf(x[i]) ? 1 : 0;
}
__kernel void h_binary(__global const float *a, __global const float *b, __global float *copysign_out,
                       __global float *fmin_out, __global float *fmax_out, __global float *next_out,
                       __global float *clamp_out)
{
    const int i = get_global_id(0);
    copysign_out[i] = copysign(a[i], b[i]);
    fmin_out[i] = fmin(a[i], b[i]);
    fmax_out[i] = fmax(a[i], b[i]);
    next_out[i] = nextafter(a[i], b[i]);
    clamp_out[i] = clamp(a[i], -1.0f, 2.0f);
}
__kernel void h_vector(__global const float *a, __global const float *b, __global float *dot_out,
                       __global float *cross_out, __global float *length_out, __global float *normalize_out)
{
    const int i = get_global_id(0);
    const float3 u = load3(a, i), v = load3(b, i);
    dot_out[i] = dot(u, v);
    store3(cross_out, i, cross(u, v));
    length_out[i] = length(u);
    store3(normalize_out, i, normalize(u));
}
__kernel void h_load3(__global const float *x, __constant float *c, __global float *global_out,
                      __global float *constant_out, __global float *private_out)
{
    const int i = get_global_id(0), n = get_global_size(0);
    vstore3(vload3(n - 1 - i, x), i, global_out);      /* reversed: the index scales by 3 */
    vstore3(vload3(n - 1 - i, c), i, constant_out);
    float p[6] = {x[3 * i], x[3 * i + 1], x[3 * i + 2], 0.0f, 0.0f, 0.0f};
    vstore3(vload3(0, p), 1, p);                        /* private in and out */
    vstore3(vload3(1, p), i, private_out);
}
__kernel void h_flag(__global int *out) { out[0] = 0;
#ifdef RT_CPU_BUILTINS
    out[0] = 1;
#endif
}
'''
INLINE = harness.Kernels(SOURCE)
PORTABLE = harness.Kernels(SOURCE, defines={"RT_PORTABLE_BUILTINS": 1})


def _specials(rng, n):
    """Random floats of every magnitude plus the special values, as float32."""
    x = np.concatenate([
        rng.standard_normal(n) * 10.0 ** rng.uniform(-40, 38, n),
        [0.0, -0.0, np.inf, -np.inf, np.nan, 1.0, -1.0, 2.5, -2.5, 1e-45, -1e-45, 1.17549435e-38,
         3.4028235e38, -3.4028235e38, 0.5, -0.5],
    ])
    with np.errstate(over="ignore"):
        return x.astype(np.float32)


def _bits(a):
    return np.asarray(a, np.float32).view(np.uint32)


def test_inline_builtins_are_on_for_pocl(runtime):
    """The inline path is the one PoCL's x86 CPU device compiles (else this file tests nothing)."""
    flag = INLINE(runtime, "h_flag", 1, out=1)
    portable = PORTABLE(runtime, "h_flag", 1, out=1)
    assert portable[0] == 0
    if "Portable Computing Language" in runtime.device.platform.name and runtime.device.type & 2:  # CPU
        assert flag[0] == 1


def test_bit_exact_unary_and_binary(runtime):
    rng = np.random.default_rng(7)
    x = _specials(rng, 4000)
    a, b = x, rng.permutation(x)
    ours = INLINE(runtime, "h_unary", len(x), x, fabs_out=len(x), floor_out=len(x), sqrt_out=len(x),
                  finite_out=len(x), inf_out=len(x))
    theirs = PORTABLE(runtime, "h_unary", len(x), x, fabs_out=len(x), floor_out=len(x), sqrt_out=len(x),
                      finite_out=len(x), inf_out=len(x))
    for name, o, t in zip(("fabs", "floor", "sqrt"), ours[:3], theirs[:3]):
        nan = np.isnan(t)
        assert np.array_equal(np.isnan(o), nan), name
        assert np.array_equal(_bits(o)[~nan], _bits(t)[~nan]), name
    assert np.array_equal(ours[3], np.isfinite(x).astype(np.int32))
    assert np.array_equal(ours[4], np.isinf(x).astype(np.int32))
    assert np.array_equal(ours[3], theirs[3]) and np.array_equal(ours[4], theirs[4])

    names = ("copysign", "fmin", "fmax", "nextafter", "clamp")
    outs = dict(copysign_out=len(a), fmin_out=len(a), fmax_out=len(a), next_out=len(a), clamp_out=len(a))
    ours = INLINE(runtime, "h_binary", len(a), a, b, **outs)
    theirs = PORTABLE(runtime, "h_binary", len(a), a, b, **outs)
    with np.errstate(invalid="ignore"):
        expected = {"copysign": np.copysign(a, b), "fmin": np.fmin(a, b), "fmax": np.fmax(a, b),
                    "nextafter": np.nextafter(a, b)}
    for name, o, t in zip(names, ours, theirs):
        nan = np.isnan(t)
        assert np.array_equal(np.isnan(o), nan), name
        if name == "clamp":  # NaN in, NaN-free out is not specified; compare the rest
            keep = ~np.isnan(a)
            assert np.array_equal(_bits(o)[keep], _bits(t)[keep]), name
            continue
        assert np.array_equal(_bits(o)[~nan], _bits(t)[~nan]), name
        e = expected[name]
        assert np.array_equal(_bits(o)[~nan], _bits(e)[~nan]), name


def test_vload3_vstore3_move_bits(runtime):
    """vload3/vstore3 copy the three components of element i (offset 3i) bit for bit (NaN payloads,
    signed zeros, denormals), from global, constant and private memory."""
    x = _specials(np.random.default_rng(3), 3000)[:3 * 1000].copy()
    x.view(np.uint32)[7] = 0x7fc01234                    # a NaN with a payload
    n = len(x) // 3
    for kernels in (INLINE, PORTABLE):
        out_global, out_constant, out_private = kernels(runtime, "h_load3", n, x, x, global_out=(n, 3),
                                                        constant_out=(n, 3), private_out=(n, 3))
        assert np.array_equal(_bits(out_global), _bits(x.reshape(n, 3)[::-1]))
        assert np.array_equal(_bits(out_constant), _bits(x.reshape(n, 3)[::-1]))
        assert np.array_equal(_bits(out_private), _bits(x.reshape(n, 3)))


@pytest.mark.parametrize("scale", [1e-30, 1e-20, 1e-8, 1.0, 1e8, 1e18, 1e30])
def test_geometric_functions_against_float64(runtime, scale):
    """dot, cross, length and normalize within a few ulp of float64, at scales where the squared
    length underflows (1e-20, 1e-30) or overflows (1e30) float32."""
    rng = np.random.default_rng(int(np.log10(scale)) + 50)
    n = 2000
    a = (rng.standard_normal((n, 3)) * scale).astype(np.float32)
    b = rng.standard_normal((n, 3)).astype(np.float32)
    dot, cross, length, normal = INLINE(runtime, "h_vector", n, a, b, dot_out=n, cross_out=(n, 3),
                                        length_out=n, normalize_out=(n, 3))
    a64, b64 = a.astype(np.float64), b.astype(np.float64)
    length64 = np.linalg.norm(a64, axis=1)
    np.testing.assert_allclose(length, length64, rtol=4e-7)
    np.testing.assert_allclose(normal, a64 / length64[:, None], rtol=0, atol=4e-7)
    # dot and cross: each term exact in float64; the float32 sums round per operation
    bound = np.abs(a64) @ np.ones(3) * np.abs(b64).max(axis=1) * 4e-7
    assert np.all(np.abs(dot - np.einsum("ij,ij->i", a64, b64)) <= bound + 1e-45)
    ref_cross = np.cross(a64, b64)
    scale_cross = (np.abs(a64) * np.abs(b64).max(axis=1)[:, None]).sum(axis=1)[:, None]
    assert np.all(np.abs(cross - ref_cross) <= scale_cross * 2.4e-7 + 1e-45)
