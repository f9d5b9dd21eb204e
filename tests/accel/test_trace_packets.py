"""trace() and occluded() with packets: on PoCL's CPU device the 8-wide layout traces 16 consecutive
rays per work-item (cl/accel/trace.cl), through cl/accel/bvh_packet.h where the packet's origins lie
close together and ray by ray where they spread.  Per ray the answer of one ray per work-item
($PYOPENCL_RT_LANES=0): t bit for bit, u, v and the normal bit for bit wherever the triangle is the
same, a different triangle only where two tie at that t; any hit exactly."""
import importlib

import numpy as np
import pytest

from meshes import MESHES, coherent_rays, incoherent_rays
from pyopencl_rt import build_bvh, occluded, trace
from pyopencl_rt.accel.device_bvh import LANES_ENV, packet_width

import harness

trace_module = importlib.import_module("pyopencl_rt.trace")  # the package's `trace` is the function


def ray_batch(v, f, rng):
    """Camera rays, bounces of neighbouring surface points (close origins, random directions) and
    rays in random order, with per-ray tmin and tmax (some short); not a multiple of 16 rays."""
    o1, d1 = coherent_rays(v, 3000)
    surface = v[f[rng.integers(0, len(f), 200)]].mean(axis=1)
    o2 = np.repeat(surface, 16, axis=0) + rng.normal(scale=1e-3, size=(3200, 3))
    d2 = rng.normal(size=(3200, 3))
    o3, d3 = incoherent_rays(v, f, 3007, rng)
    o = np.concatenate([o1, o2, o3]).astype(np.float32)
    d = np.concatenate([d1, d2, d3]).astype(np.float32)
    tmin = np.where(rng.random(len(o)) < 0.2, rng.uniform(0, 0.5, len(o)), 0.0).astype(np.float32)
    tmax = np.where(rng.random(len(o)) < 0.2, tmin + rng.uniform(0, 1, len(o)), np.inf).astype(np.float32)
    return o, d, tmin, tmax


@pytest.mark.parametrize("width", ["16", "8"])
@pytest.mark.parametrize("spread", ["default", "every packet", "ray by ray"])
@pytest.mark.parametrize("mesh", ["torus", "slivers", "grid"])
def test_packets_equal_one_ray_per_work_item(device, monkeypatch, rng, mesh, spread, width):
    harness.require_lane_kernels(device, int(width))
    monkeypatch.setenv(LANES_ENV, width)
    assert packet_width(device) == int(width)  # so that packets are traced below
    limit = {"default": trace_module.PACKET_ORIGIN_SPREAD, "every packet": np.inf, "ray by ray": -1.0}[spread]
    monkeypatch.setattr(trace_module, "PACKET_ORIGIN_SPREAD", limit)
    v, f = MESHES[mesh]()
    bvh = build_bvh(v, f)
    o, d, tmin, tmax = ray_batch(v, f, rng)
    ours = trace(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout="wide8")
    hit_ours = occluded(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout="wide8")
    monkeypatch.setenv(LANES_ENV, "0")
    ref = trace(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout="wide8")
    hit_ref = occluded(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout="wide8")
    assert 0.05 < (ref["prim_id"] >= 0).mean() < 0.95
    assert np.array_equal(ours["t"], ref["t"])
    same = ours["prim_id"] == ref["prim_id"]
    for k in ("u", "v", "normal"):
        assert np.array_equal(ours[k][same], ref[k][same]), k
    assert (~same).sum() <= 5e-3 * len(o)  # ties: rays aimed at shared vertices and edges (slivers: 0.3%)
    assert np.array_equal(hit_ours, hit_ref)


def test_packet_kernels_that_fail_to_build_fall_back(device, monkeypatch, rng):
    """Packet kernels that do not build (here a width lanes.h rejects with #error): one warning
    line, and trace()/occluded() answer as one ray per work-item."""
    harness.require_lane_kernels(device, 8)
    v, f = MESHES["torus"]()
    bvh = build_bvh(v, f)
    o, d, tmin, tmax = ray_batch(v, f, rng)
    monkeypatch.setenv(LANES_ENV, "0")
    ref = trace(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout="wide8")
    hit_ref = occluded(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout="wide8")
    monkeypatch.setattr(trace_module, "packet_width", lambda dev: 12)
    with pytest.warns(UserWarning, match="12-ray packet kernels failed.*one ray per work-item"):
        ours = trace(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout="wide8")
    assert np.array_equal(ours["t"], ref["t"]) and np.array_equal(ours["prim_id"], ref["prim_id"])
    assert np.array_equal(occluded(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout="wide8"), hit_ref)
