"""The shared test helpers of tests/harness.py: the harness-kernel runner and the chi-square test."""
import numpy as np
import pytest
from scipy import stats

import harness

SOURCE = r"""
#include "render/rng.h"
/* a comment with __kernel void not_a_kernel(int x) in it */
__kernel void h_axpy(float a, __global const float *x, __global const uint *y, int n,
                     __global float *out, __global unsigned int *count)
{
    const int i = get_global_id(0);
    out[i] = a * x[i] + (float)y[i] + (float)n;
    if (i == 0) count[0] += 1;
}

__kernel void h_hash(__global const uint *x, __global uint *out)
{
    const int i = get_global_id(0);
    out[i] = hash_u32(x[i]);
}
"""

KERNELS = harness.Kernels(SOURCE)


def test_signatures_are_parsed():
    assert set(KERNELS.signatures) == {"h_axpy", "h_hash"}
    p = KERNELS.signatures["h_axpy"]
    assert [(q.name, q.kind, q.dtype) for q in p] == [
        ("a", "scalar", np.float32), ("x", "in", np.float32), ("y", "in", np.uint32), ("n", "scalar", np.int32),
        ("out", "out", np.float32), ("count", "out", np.uint32)]
    s = harness.parse_signatures("__kernel void k(__global const Material *m, __global float * const p,"
                                 " __constant float4 *c)")["k"]
    assert [(q.ctype, q.kind, q.dtype) for q in s] == [("Material", "in", None), ("float", "out", np.float32),
                                                      ("float4", "in", np.float32)]
    with pytest.raises(TypeError, match="float3"):
        harness.parse_signatures("__kernel void k(__global float3 *p)")


def test_arguments_are_checked():
    with pytest.raises(TypeError, match="missing count"):
        KERNELS.bind("h_axpy", (1.0, [1.0], [1], 0, 1), {})
    with pytest.raises(TypeError, match="given twice"):
        KERNELS.bind("h_axpy", (1.0,), {"a": 2.0})
    with pytest.raises(TypeError, match="no parameter"):
        KERNELS.bind("h_hash", (), {"x": [1], "out": 1, "z": 3})
    with pytest.raises(TypeError, match="float64 values for a uint"):
        KERNELS.bind("h_hash", ([1.5],), {"out": 1})
    with pytest.raises(TypeError, match="out of the range of uint"):
        KERNELS.bind("h_hash", ([-1],), {"out": 1})
    with pytest.raises(KeyError, match="h_nope"):
        KERNELS.bind("h_nope", (), {})


def test_kernels_run(runtime):
    """Scalars, inputs (cast to the C type), outputs by shape and an in/out array, positionally
    or by name; the caller's initial array is not modified."""
    x = np.arange(5, dtype=np.float64)
    count = np.array([41], np.uint32)
    out, c = KERNELS(runtime, "h_axpy", 5, 2.0, x, np.arange(5), n=10, out=5, count=count)
    assert out.dtype == np.float32 and out.tolist() == [10.0, 13.0, 16.0, 19.0, 22.0]
    assert c.tolist() == [42] and count.tolist() == [41]
    assert KERNELS(runtime, "h_hash", 2, x=[0, 1], out=(2,)).dtype == np.uint32


def test_chi2_pooling_follows_mitsuba():
    """Sorted by expected count; empty bins left out; bins expecting < 5 pooled in that order into
    cells closed once they expect > 5; a last pool that never gets there is left out."""
    expected = np.array([10.0, 0.0, 2.0, 3.0, 1.0, 20.0, 4.0, 0.5])
    observed = np.array([12.0, 0.0, 1.0, 5.0, 1.0, 17.0, 2.0, 1.0])
    r = harness.chi2_test(observed, expected)
    # sorted small bins: 0.5 (1), 1 (1), 2 (1), 3 (5) -> the pool expects 6.5 > 5: one cell (8 observed);
    # then 4 (2): a last pool expecting 4, left out
    stat = (12 - 10) ** 2 / 10 + (17 - 20) ** 2 / 20 + (8 - 6.5) ** 2 / 6.5
    assert (r.pooled_in, r.pooled_out, r.dof) == (5, 1, 2)
    assert r.statistic == pytest.approx(stat) and r.p == pytest.approx(stats.chi2.sf(stat, 2))


def test_chi2_rejects_and_accepts():
    rng = np.random.default_rng(5)
    e = np.full(50, 2000.0)
    assert harness.assert_chi2(rng.poisson(e), e, 1e-4, "fair").p > 1e-4
    with pytest.raises(AssertionError, match="biased: chi-square p"):
        harness.assert_chi2(rng.poisson(e * np.linspace(0.9, 1.1, 50)), e, 1e-4, "biased")
    with pytest.raises(AssertionError, match="pdf is zero"):
        harness.chi2_test([10, 10, 1], [10, 10, 0])
    with pytest.raises(AssertionError, match="too few cells"):
        harness.chi2_test([10], [10])
