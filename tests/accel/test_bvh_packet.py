"""Packet traversal of the 8-wide BVH (cl/accel/bvh_packet.h), which the lane megakernel traces
with: per lane, the single-ray traversal's result (bvh_wide8.h, checked against Embree and the
binary layout in test_traversal.py and test_bvh_wide.py), for all packets, for ray by ray, and for
the hybrid of the two; idle lanes untouched; packet_rays equal to wide_ray lane by lane.  The lane
kernels are built for PoCL's CPU device on x86 only (clang); on any other device the renderer
never selects them (tests/render/test_path_lanes.py)."""
import numpy as np
import pytest

from meshes import MESHES, coherent_rays, incoherent_rays
from pyopencl_rt import build_bvh, occluded, trace
from pyopencl_rt.accel.bvh_wide import device_blob, wide_bvh
from pyopencl_rt.accel.device_bvh import LANES_ENV

import harness

SOURCE = r"""
#include "accel/bvh_packet.h"
/* lanes of work-item i: rays PACKET_WIDTH * i + k; a ray with tmax < 0 is an idle lane */
RT_INLINE PacketRay load_packet(__global const float *o, __global const float *d, int n, int base)
{
    pvec3 po, pd;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int i = min(base + k, n - 1);
        pv3_set_lane(&po, k, load3(o, i));
        pv3_set_lane(&pd, k, load3(d, i));
    }
    return packet_rays(po, pd);
}

__kernel void h_closest(__global const uchar *bvh, __global const float *o, __global const float *d,
                        __global const float *tmax, int n, __global float *out_t, __global int *out_prim,
                        __global float *out_u, __global float *out_v)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    const PacketRay r = load_packet(o, d, n, base);
    pfloat t;
    for (int k = 0; k < PACKET_WIDTH; ++k) PLANE(t, k) = tmax[min(base + k, n - 1)];
    pint prim = PINT(PRIM_MISS);
    pfloat u = PFLOAT(0.0f), v = PFLOAT(0.0f);
    packet_closest_hit((__global const float8 *)bvh, &r, PFLOAT(0.0f), &t, &prim, &u, &v);
    for (int k = 0; k < PACKET_WIDTH && base + k < n; ++k) {
        out_t[base + k] = PLANE(t, k); out_prim[base + k] = PLANE_I(prim, k);
        out_u[base + k] = PLANE(u, k); out_v[base + k] = PLANE(v, k);
    }
}

__kernel void h_any(__global const uchar *bvh, __global const float *o, __global const float *d,
                    __global const float *tmax, int n, __global int *out_hit)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    const PacketRay r = load_packet(o, d, n, base);
    pfloat tm;
    for (int k = 0; k < PACKET_WIDTH; ++k) PLANE(tm, k) = tmax[min(base + k, n - 1)];
    const pint h = packet_any_hit((__global const float8 *)bvh, &r, PFLOAT(0.0f), tm);
    for (int k = 0; k < PACKET_WIDTH && base + k < n; ++k) out_hit[base + k] = PLANE_I(h, k);
}

/* packet_rays against packet_set_ray (wide_ray per lane): the 20 fields of each, as 32-bit words */
__kernel void h_rays(__global const float *d, int n, __global uint *out_vec, __global uint *out_lane)
{
    const int base = get_global_id(0) * PACKET_WIDTH;
    pvec3 po, pd;
    PacketRay lane_by_lane;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const float3 dk = load3(d, min(base + k, n - 1)), ok = (float3)(0.5f, -2.0f, 3.0f) * (float)k;
        pv3_set_lane(&po, k, ok);
        pv3_set_lane(&pd, k, dk);
        packet_set_ray(&lane_by_lane, k, ok, dk);
    }
    const PacketRay vec = packet_rays(po, pd);
    __global uint *a = out_vec + base * 20, *b = out_lane + base * 20;
    for (int f = 0; f < 20; ++f)
        for (int k = 0; k < PACKET_WIDTH && base + k < n; ++k) {
            a[k * 20 + f] = ((const uint *)&vec)[f * PACKET_WIDTH + k];
            b[k * 20 + f] = ((const uint *)&lane_by_lane)[f * PACKET_WIDTH + k];
        }
}
"""
# (packet width, PACKET_HYBRID, PACKET_PAIR_PASSES): all packets, hybrid, hybrid with leaves tested
# as pairs of rays and triangles (the default), ray by ray; and 8 lanes
DEFAULT = (16, 2, 3)
VARIANTS = [(16, 0, 0), (16, 4, 0), DEFAULT, (16, 16, 0), (8, 2, 3)]
KERNELS = {v: harness.Kernels(SOURCE, defines={"BVH_WIDE8": True, "PACKET_WIDTH": v[0], "PACKET_HYBRID": v[1],
                                               "PACKET_PAIR_PASSES": v[2]}, local_size=8)
           for v in VARIANTS}


def rays_for(mesh, rng, n=6000):
    v, f = MESHES[mesh]()
    o1, d1 = coherent_rays(v, n // 2)
    o2, d2 = incoherent_rays(v, f, n // 2, rng)
    o = np.concatenate([o1, o2]).astype(np.float32)
    d = np.concatenate([d1, d2]).astype(np.float32)
    tmax = np.full(len(o), np.inf, np.float32)
    tmax[rng.random(len(o)) < 0.1] = -1.0          # idle lanes, scattered through the packets
    short = rng.random(len(o)) < 0.2
    tmax[short] = rng.uniform(0, 2, short.sum())  # rays that end early (shadow rays)
    return build_bvh(v, f), o, d, tmax


# a second implementation (Intel's CPU runtime beside PoCL, tests/conftest.py): every variant (the code)
# on the slivers in `make test`, the other meshes (data) under stress
SECOND_IMPLEMENTATION = {"test_packets_equal_single_rays": lambda params, device: params["mesh"] == "slivers"}


@pytest.mark.parametrize("variant", VARIANTS, ids=lambda v: f"w{v[0]}-hybrid{v[1]}-pairs{v[2]}")
@pytest.mark.parametrize("mesh", ["icosphere", "torus", "slivers", "grid"])
def test_packets_equal_single_rays(device, runtime, rng, mesh, variant, monkeypatch):
    """Closest hit: per lane the single-ray wide8 result (t, triangle, u, v bit for bit), except a
    different triangle where two tie at the same t (packets meet leaves in another order), with
    leaves tested triangle by triangle against the packet, ray by ray, or as pairs of a ray and a
    triangle per lane; ray by ray (hybrid 16) exactly the single-ray traversal.  Any hit: exactly the single-ray answer.
    Idle lanes: no hit, t as given."""
    harness.require_lane_kernels(device, variant[0])
    monkeypatch.setenv(LANES_ENV, "0")  # trace()/occluded() below: one ray per work-item, the reference
    bvh, o, d, tmax = rays_for(mesh, rng)
    n = len(o)
    blob = device_blob(wide_bvh(bvh, 8))
    width = variant[0]
    items = -(-n // width)
    t, prim, u, v = KERNELS[variant](runtime, "h_closest", items, blob, o, d, tmax, n,
                                     out_t=n, out_prim=n, out_u=n, out_v=n)
    active = tmax >= 0
    assert (prim[~active] == -1).all() and np.array_equal(t[~active], tmax[~active])
    ref = trace(bvh, o[active], d[active], tmax=tmax[active], device=device, layout="wide8")
    ours = np.where(prim[active] >= 0, bvh.prim_ids[np.maximum(prim[active], 0)], -1)
    same = ours == ref["prim_id"]
    for name, got in (("t", t[active]), ("u", u[active]), ("v", v[active])):
        assert np.array_equal(got[same & (ours >= 0)], ref[name][same & (ours >= 0)]), name
    assert np.array_equal(t[active][ours < 0], tmax[active][ours < 0])
    if variant[1] >= width:
        assert same.all()
    else:  # ties only: the same t within rounding; a few in 1000 (half the incoherent rays are
        # aimed exactly at vertices and edges, which several triangles share)
        assert np.allclose(t[active][~same], ref["t"][~same], rtol=1e-5)
        assert (~same).sum() <= 5e-3 * active.sum()
    hit = KERNELS[variant](runtime, "h_any", items, blob, o, d, tmax, n, out_hit=n)
    assert (hit[~active] == 0).all()
    assert np.array_equal(hit[active] != 0, occluded(bvh, o[active], d[active], tmax=tmax[active], device=device,
                                                     layout="wide8"))


def test_packets_of_the_cornell_box(device, runtime, rng, monkeypatch):
    """Mitsuba's Cornell box, the scene the lane megakernel was measured on: rays from points
    spread through the room in every direction, equal to the single-ray traversal."""
    harness.require_lane_kernels(device)
    monkeypatch.setenv(LANES_ENV, "0")  # trace() below: one ray per work-item, the reference
    from pathlib import Path

    from pyopencl_rt import load_scene

    scene = load_scene(Path(__file__).resolve().parents[2] / "scenes" / "mitsuba-cbox.toml")
    bvh = build_bvh(scene.vertices, scene.faces)
    n = 20_000
    lo, hi = bvh.bounds.astype(np.float64)
    o = (lo + (hi - lo) * (0.05 + 0.9 * rng.random((n, 3)))).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    tmax = np.full(n, np.inf, np.float32)
    blob = device_blob(wide_bvh(bvh, 8))
    t, prim, u, v = KERNELS[DEFAULT](runtime, "h_closest", n // 16, blob, o, d, tmax, n,
                                     out_t=n, out_prim=n, out_u=n, out_v=n)
    ref = trace(bvh, o, d, device=device, layout="wide8")
    ours = np.where(prim >= 0, bvh.prim_ids[np.maximum(prim, 0)], -1)
    assert (ours >= 0).mean() > 0.5  # the room is open on the camera's side only
    same = ours == ref["prim_id"]
    assert same.mean() >= 0.999
    hit = same & (ours >= 0)
    assert np.array_equal(t[hit], ref["t"][hit]) and np.array_equal(u[hit], ref["u"][hit])


def test_packet_rays_equal_wide_ray(device, runtime, rng):
    """packet_rays (the lanes at once) gives wide_ray's constants lane by lane, bit for bit: axis
    picks, sign swaps, reciprocals clamped for tiny components, for directions with ties, zeros
    (both signs), tiny and huge components."""
    harness.require_lane_kernels(device)
    n = 4096
    d = rng.normal(size=(n, 3)).astype(np.float32)
    special = np.array([[1, 0, 0], [0, -1, 0], [0, 0, 1], [-0.0, 0.0, -1], [1, 1, 1], [-1, 1, -1], [1, -1, 0],
                        [1e-30, 1, 0], [1e-19, -1e-20, 1e-21], [3e38, -1, 2], [0.5, 0.5, -0.5]], np.float32)
    d[:len(special)] = special
    d[len(special):len(special) + 500] = rng.choice([-1.0, 0.0, 1.0, 2.0], size=(500, 3))
    for variant in (DEFAULT, (8, 2, 3)):
        width = variant[0]
        vec, lane = KERNELS[variant](runtime, "h_rays", n // width, d, n, out_vec=(n, 20), out_lane=(n, 20))
        assert np.array_equal(vec, lane)
