"""The wide BVH's packets and node boxes, gathered by compiled loops (issue 35), are the arrays the
numpy expressions they replaced gave, bit for bit (NaN lanes and empty slots included)."""
from __future__ import annotations

import numpy as np
import pytest

from pyopencl_rt.accel.bvh import build_bvh
from pyopencl_rt.accel.bvh_wide import _COORDS, _child_arrays, build_wide
from pyopencl_rt.bench.scale_scene import heightfield


def _meshes():
    rng = np.random.default_rng(0)
    v, f = heightfield(30)
    return {"heightfield": (v, f),
            "soup": (rng.random((600, 3)).astype(np.float32), rng.integers(0, 600, (700, 3)).astype(np.int32)),
            "one": (np.eye(3, dtype=np.float32), np.array([[0, 1, 2]], np.int32))}


@pytest.mark.parametrize("width", [4, 8])
@pytest.mark.parametrize("mesh", ["heightfield", "soup", "one"])
def test_wide_packets_and_boxes_match_numpy(mesh, width):
    v, f = _meshes()[mesh]
    bvh = build_bvh(v, f)
    wide = build_wide(bvh, width)
    T, W = len(bvh.triangles), wide.packet_width
    # the packets: numpy's gather of the triangles' vertices per lane, NaN in the empty lanes
    lane_tri = wide.packets["tri"]
    xyz = np.empty((T + 1, 3, 3), np.float32)
    for k in range(3):
        xyz[:T, k] = bvh.triangles[f"v{k}"][:, :3]
    xyz[T] = np.nan
    gathered = xyz[np.where(lane_tri < 0, T, lane_tri)]
    want = gathered.transpose(0, 2, 3, 1).reshape(len(lane_tri), 9, W)
    got = wide.packets.view(np.float32).reshape(len(lane_tri), 10, W)[:, :9]
    assert np.array_equal(got.view(np.uint32), want.view(np.uint32))
    # the node boxes: each slot's binary child box, (+inf, -inf) where empty
    clo, chi, cchild, ccount, _ = _child_arrays(bvh.nodes)
    for a, c in enumerate(_COORDS):
        lo, hi = wide.nodes[f"bmin_{c}"], wide.nodes[f"bmax_{c}"]
        assert lo.dtype == np.float32 and np.isfinite(lo[lo < np.inf]).all()
        empty = wide.nodes["count"] < 0
        assert (lo[empty] == np.inf).all() and (hi[empty] == -np.inf).all()
        assert (lo[~empty] <= hi[~empty]).all()
    assert wide.packets.tobytes() == build_wide(bvh, width).packets.tobytes()  # deterministic
