"""sin, cos, atan2, acos, exp and log over lanes (cl/render/lanes_math.h): within their documented
error of the double-precision functions, IEEE signs at the zeros of atan2, the library beyond the
reduction's range, exp's and log's special values, and at 8 and 16 lanes the bits of width 1."""
import numpy as np
import pytest

import harness

SOURCE = r"""
#include "render/lanes.h"
/* items i * PACKET_WIDTH .. + PACKET_WIDTH in the lanes of work-item i; out: sin, cos, atan2, acos */
__kernel LANE_KERNEL void h_math(__global const float *a, __global const float *b, __global float *out)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pfloat x, y;
    for (int k = 0; k < PACKET_WIDTH; ++k) { PLANE(x, k) = a[base + k]; PLANE(y, k) = b[base + k]; }
    pfloat s, c;
    psincos(x, &s, &c);
    const pfloat t = patan2(x, y), ac = pacos(pclamp(x, -1.0f, 1.0f)), s1 = psin(x), c1 = pcos(x);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        out[4 * (base + k)] = PLANE(s, k);
        out[4 * (base + k) + 1] = PLANE(c, k);
        out[4 * (base + k) + 2] = PLANE(t, k);
        out[4 * (base + k) + 3] = PLANE(ac, k);
        if (as_uint(PLANE(s1, k)) != as_uint(PLANE(s, k)) || as_uint(PLANE(c1, k)) != as_uint(PLANE(c, k))) out[4 * (base + k)] = 99.0f;
    }
}
/* items as h_math's; out: exp(a), log(b) */
__kernel LANE_KERNEL void h_explog(__global const float *a, __global const float *b, __global float *out)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pfloat x, y;
    for (int k = 0; k < PACKET_WIDTH; ++k) { PLANE(x, k) = a[base + k]; PLANE(y, k) = b[base + k]; }
    const pfloat e = pexp(x), l = plog(y);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        out[2 * (base + k)] = PLANE(e, k);
        out[2 * (base + k) + 1] = PLANE(l, k);
    }
}
"""
ONE = harness.Kernels(SOURCE)


def ulps(got, want):
    return np.abs(got.astype(np.float64) - want) / np.spacing(np.abs(want).astype(np.float32)).astype(np.float64)


def inputs(rng, n=1 << 16):
    x = np.concatenate([rng.uniform(-20, 20, n // 2), rng.uniform(-1, 1, n // 4),
                        np.linspace(0, 2 * np.pi, n // 4)]).astype(np.float32)
    v = rng.normal(size=(3, n))
    v /= np.linalg.norm(v, axis=0)
    return x, v.astype(np.float32)


def test_within_documented_error(runtime, rng):
    x, v = inputs(rng)
    out = ONE(runtime, "h_math", len(x), x, v[2], (len(x), 4))
    out2 = ONE(runtime, "h_math", len(x), -v[0], v[2], (len(x), 4))
    x64 = x.astype(np.float64)
    for got, want, ulp_max, abs_max in ((out[:, 0], np.sin(x64), 2.0, 1e-7), (out[:, 1], np.cos(x64), 2.0, 1e-7)):
        big = np.abs(want) > 1e-3
        assert ulps(got[big], want[big]).max() < ulp_max and np.abs(got - want).max() < abs_max
    want = np.arctan2(-v[0].astype(np.float64), v[2].astype(np.float64))
    assert np.abs(out2[:, 2] - want).max() < 4e-7 and ulps(out2[:, 2], want)[np.abs(want) > 1e-3].max() < 3.0
    a = np.clip(x64, -1, 1).astype(np.float32).astype(np.float64)
    want = np.arccos(a)
    assert np.abs(out[:, 3] - want).max() < 4e-7 and ulps(out[:, 3], want)[want > 1e-3].max() < 1.5


def test_special_values(runtime):
    y = np.array([0.0, -0.0, 0.0, -0.0, 0.0, 0.0, 1.0, -1.0, 1e-30, -1e-30, 1.0, -1.0], np.float32)
    x = np.array([0.0, 0.0, -0.0, -0.0, 1.0, -1.0, 0.0, 0.0, -1.0, -1.0, 1.0, -1.0], np.float32)
    out = ONE(runtime, "h_math", len(x), y, x, (len(x), 4))
    want = np.arctan2(y, x)
    assert np.array_equal(out[:, 2].view(np.uint32), want.view(np.uint32)) or np.allclose(out[:, 2], want, atol=3e-7)
    assert np.array_equal(np.signbit(out[:, 2]), np.signbit(want))
    a = np.array([1.0, -1.0, 0.0, -0.0, 0.5, -0.5, 0.4999999, 1e-8], np.float32)
    out = ONE(runtime, "h_math", len(a), a, a, (len(a), 4))
    assert out[0, 3] == 0.0 and abs(out[1, 3] - np.pi) < 3e-7
    assert np.allclose(out[:, 3], np.arccos(a.astype(np.float64)), rtol=0, atol=3e-7)
    # beyond the reduction's range the library; sin(0) = 0, cos(0) = 1 exactly
    big = np.array([1e4, -3e5, 6433.0, 6434.0, 0.0, np.inf], np.float32)
    out = ONE(runtime, "h_math", len(big), big, big, (len(big), 4))
    assert out[4, 0] == 0.0 and out[4, 1] == 1.0 and np.isnan(out[5, :2]).all()
    assert np.allclose(out[:4, 0], np.sin(big[:4].astype(np.float64)), atol=2e-7)
    assert np.allclose(out[:4, 1], np.cos(big[:4].astype(np.float64)), atol=2e-7)


def explog_inputs(rng, n=1 << 16):
    """exp's arguments over its whole range (results from the denormals to overflow) and log's over
    every binade, the denormals included, and near 1."""
    a = np.concatenate([rng.uniform(-104, 89, n // 2), rng.uniform(-2, 2, n // 4), rng.uniform(-0.35, 0.35, n // 4)])
    b = np.concatenate([2.0 ** rng.uniform(-149, 128, n // 2), rng.uniform(0.5, 2, n // 4),
                        1 + rng.uniform(-1e-3, 1e-3, n // 4)])
    return a.astype(np.float32), b.astype(np.float32)


def test_exp_log_within_error_and_special_values(runtime, rng):
    """exp within 2 ulp of the double-precision value where it is normal (and within one step of
    the denormals below), overflowing to +inf exactly where the float result does; log within 2
    ulp everywhere; the special values of IEEE exp and log."""
    a, b = explog_inputs(rng)
    a = a[np.isfinite(b)]
    b = b[np.isfinite(b)]
    out = ONE(runtime, "h_explog", len(a), a, b, (len(a), 2))
    want_e = np.exp(a.astype(np.float64))
    normal = (want_e >= np.finfo(np.float32).tiny) & (want_e <= np.finfo(np.float32).max)
    assert ulps(out[normal, 0], want_e[normal]).max() <= 2.0
    assert np.abs(out[~normal & (want_e < 1), 0] - want_e[~normal & (want_e < 1)]).max() <= 2.0 ** -149
    assert np.all(np.isinf(out[want_e > np.finfo(np.float32).max * (1 + 2**-25), 0]))
    want_l = np.log(b.astype(np.float64))
    assert ulps(out[:, 1], want_l).max() <= 2.0
    special = np.array([0.0, -0.0, -1.0, np.inf, -np.inf, np.nan, 1.0, 88.72283, 88.7229, -103.0, -110.0, 2.0**-149],
                       np.float32)
    out = ONE(runtime, "h_explog", len(special), special, special, (len(special), 2))
    e, lg = out[:, 0], out[:, 1]
    assert e[0] == 1.0 and e[1] == 1.0 and e[3] == np.inf and e[4] == 0.0 and np.isnan(e[5]) and e[6] == np.float32(np.e)
    assert np.isfinite(e[7]) and e[8] == np.inf and 0 < e[9] < 1e-44 and e[10] == 0.0
    assert lg[0] == -np.inf and lg[1] == -np.inf and np.isnan(lg[2]) and lg[3] == np.inf and np.isnan(lg[4])
    assert np.isnan(lg[5]) and lg[6] == 0.0 and abs(lg[11] - np.log(2.0**-149)) <= 2 * np.spacing(np.float32(103.3))


@pytest.mark.parametrize("width", [8, 16])
def test_lanes_give_the_one_lane_bits(device, runtime, rng, width):
    harness.require_lane_kernels(device, width)
    wide = harness.Kernels(SOURCE, defines={"PACKET_WIDTH": width}, local_size=16)
    x, v = inputs(rng)
    x = np.concatenate([x, np.array([1e4, -1e5, 0.0, -0.0, np.nan, np.inf, -np.inf, 6433.0] * 32, np.float32)])
    y = np.resize(v[2], len(x))
    one = ONE(runtime, "h_math", len(x), x, y, (len(x), 4))
    lanes = wide(runtime, "h_math", len(x) // width, x, y, (len(x), 4))
    assert np.array_equal(one.view(np.uint32), lanes.view(np.uint32))
    assert not (one[:, 0] == 99.0).any()
    a, b = explog_inputs(rng, n=1 << 14)
    a = np.concatenate([a, np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, 89.5, -120.0, 1.0] * 32, np.float32)])
    b = np.concatenate([b, np.array([np.nan, np.inf, -np.inf, 0.0, -0.0, -3.0, 1e-45, 1.0] * 32, np.float32)])
    assert len(a) % (16 * width) == 0  # whole groups of 16 work-items: none beyond the arrays
    one = ONE(runtime, "h_explog", len(a), a, b, (len(a), 2))
    lanes = wide(runtime, "h_explog", len(a) // width, a, b, (len(a), 2))
    assert np.array_equal(one.view(np.uint32), lanes.view(np.uint32))
