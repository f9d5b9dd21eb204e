"""The compiled collapse of the binary BVH into the 4- and 8-wide layouts (issue 35) gives, bit
for bit, the nodes and packets of the numpy level-synchronous collapse it replaced (kept here as
the reference: ``_numpy_slots`` and ``_numpy_merge`` are that code)."""
from __future__ import annotations

import numpy as np
import pytest

from meshes import MESHES
from pyopencl_rt.accel.bvh import build_bvh
from pyopencl_rt.accel.bvh_wide import _FORMATS, _PACKETS, build_wide, max_wide_depth
from pyopencl_rt.bench.scale_scene import heightfield


def _numpy_child_arrays(nodes):
    R = len(nodes)
    lo = np.empty((2 * R, 3), np.float32)
    hi = np.empty((2 * R, 3), np.float32)
    child = np.empty(2 * R, np.int64)
    count = np.empty(2 * R, np.int64)
    for k, s in enumerate(("left", "right")):
        lo[k::2] = nodes[f"bmin_{s}"]
        hi[k::2] = nodes[f"bmax_{s}"]
        child[k::2] = nodes[f"child_{s}"]
        count[k::2] = nodes[f"count_{s}"]
    ext = np.maximum(hi.astype(np.float64) - lo.astype(np.float64), 0.0)
    ext = np.where(np.isfinite(ext), ext, 0.0)
    area = ext[:, 0] * ext[:, 1] + ext[:, 1] * ext[:, 2] + ext[:, 2] * ext[:, 0]
    return lo, hi, child, count, area


def _numpy_merge(child, count, lo, hi, merge):
    R = len(child) // 2
    total = np.where(count > 0, count, 0)
    first = np.where(count > 0, child, np.iinfo(np.int64).max)
    levels, frontier = [], np.array([0], np.int64)
    while len(frontier):
        levels.append(frontier)
        slots = np.concatenate([2 * frontier, 2 * frontier + 1])
        frontier = child[slots[count[slots] == 0]]
    rec_total, rec_first = np.zeros(R, np.int64), np.zeros(R, np.int64)
    for recs in reversed(levels):
        for k in (0, 1):
            s = 2 * recs + k
            inner = count[s] == 0
            total[s[inner]] = rec_total[child[s[inner]]]
            first[s[inner]] = rec_first[child[s[inner]]]
        rec_total[recs] = total[2 * recs] + total[2 * recs + 1]
        rec_first[recs] = np.minimum(first[2 * recs], first[2 * recs + 1])
    small = (count == 0) & (total <= merge)
    child[small] = first[small]
    count[small] = total[small]
    if rec_total[0] <= merge:
        child[0], count[0] = rec_first[0], rec_total[0]
        child[1], count[1] = 0, -1
        lo[0], hi[0] = np.minimum(lo[0], lo[1]), np.maximum(hi[0], hi[1])


def _numpy_collapse(bvh, width):
    """The old build_wide's nodes' child/count, lane_tri and depth (boxes: test_wide_gather)."""
    fmt = _FORMATS[width]
    packet_width, merge = width, fmt["merge"]
    node_units = fmt["node"].itemsize // fmt["unit"]
    packet_units = _PACKETS[packet_width].itemsize // fmt["unit"]
    T = len(bvh.triangles)
    clo, chi, cchild, ccount, carea = _numpy_child_arrays(bvh.nodes)
    if merge > 0 and T:
        _numpy_merge(cchild, ccount, clo, chi, merge)
    level_slots = []
    frontier = np.array([0], np.int64)
    while len(frontier):
        K = len(frontier)
        slots = np.full((K, width), -1, np.int64)
        slots[:, 0] = 2 * frontier
        slots[:, 1] = 2 * frontier + 1
        two = slots[:, :2]
        two[ccount[two] < 0] = -1
        rows = np.arange(K)
        level = np.ones((K, width), np.int64)
        for n in range(2, width):
            valid = slots[:, :n] >= 0
            inner = valid & (ccount[np.maximum(slots[:, :n], 0)] == 0)
            shallow = inner & (level[:, :n] == np.where(inner, level[:, :n], 99).min(axis=1, keepdims=True))
            score = np.where(shallow, carea[np.maximum(slots[:, :n], 0)], -1.0)
            pick = np.argmax(score, axis=1)
            ok = inner[rows, pick]
            r_ok, p_ok = rows[ok], pick[ok]
            rec = cchild[slots[r_ok, p_ok]]
            slots[r_ok, p_ok] = 2 * rec
            slots[r_ok, n] = 2 * rec + 1
            level[r_ok, p_ok] += 1
            level[r_ok, n] = level[r_ok, p_ok]
        level_slots.append(slots)
        s = slots.ravel()
        inner = (s >= 0) & (ccount[np.maximum(s, 0)] == 0)
        frontier = cchild[s[inner]]
        assert len(level_slots) <= max_wide_depth(width) + 1
    n_nodes = int(sum(len(s) for s in level_slots))
    flat = np.concatenate(level_slots).ravel()
    present = flat >= 0
    fc = np.where(present, ccount[np.maximum(flat, 0)], -1)
    is_inner, is_leaf = fc == 0, fc > 0
    child_node = np.zeros(len(flat), np.int64)
    child_node[is_inner] = 1 + np.arange(int(is_inner.sum()))
    leaf_pos = np.flatnonzero(is_leaf)
    first, cnt = cchild[flat[leaf_pos]], fc[leaf_pos]
    order = np.argsort(first, kind="stable")
    npk = (cnt + packet_width - 1) // packet_width
    pk_start_sorted = np.concatenate([[0], np.cumsum(npk[order])[:-1]]).astype(np.int64)
    pk_start = np.empty_like(pk_start_sorted)
    pk_start[order] = pk_start_sorted
    lane_tri = np.full((int(npk.sum()), packet_width), -1, np.int32)
    if T:
        leaf_of = np.repeat(np.arange(len(first))[order], cnt[order])
        local = np.arange(T) - first[leaf_of]
        lane_tri.ravel()[packet_width * pk_start[leaf_of] + local] = np.arange(T, dtype=np.int32)
    child = np.zeros(len(flat), np.int64)
    child[is_inner] = node_units * child_node[is_inner]
    child[leaf_pos] = node_units * n_nodes + packet_units * pk_start
    count = np.where(is_leaf, 0, fc)
    count[leaf_pos] = npk
    return child.reshape(n_nodes, width), count.reshape(n_nodes, width), lane_tri, len(level_slots) - 1, clo, chi


def test_child_arrays_match_numpy():
    from pyopencl_rt.accel.bvh_wide import _child_arrays

    for mesh in ("heightfield", "empty", "one", "degenerate"):
        nodes = build_bvh(*CASES[mesh]).nodes
        for got, want in zip(_child_arrays(nodes), _numpy_child_arrays(nodes)):
            if want.dtype == np.int64:      # child and count: int32 as in the records
                assert got.dtype == np.int32 and np.array_equal(got, want)
            else:
                assert got.dtype == want.dtype and np.array_equal(got.view(np.uint8), want.view(np.uint8))


def _cases():
    rng = np.random.default_rng(3)
    v, f = heightfield(40)
    cases = {"heightfield": (v, f), "one": (np.eye(3, dtype=np.float32), np.array([[0, 1, 2]], np.int32)),
             "empty": (np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32))}
    for n in (2, 5, 9, 17, 700):
        cases[f"soup{n}"] = (rng.random((3 * n, 3)).astype(np.float32), rng.integers(0, 3 * n, (n, 3)).astype(np.int32))
    a = rng.normal(size=(300, 3)).astype(np.float32)       # coincident and degenerate triangles
    cases["degenerate"] = (np.concatenate([a, a, np.zeros((1, 3), np.float32)]),
                           np.concatenate([np.stack([np.arange(300), np.arange(300) + 300, np.full(300, 600)], 1),
                                           np.full((200, 3), 600)]).astype(np.int32))
    for name in ("torus", "slivers"):
        cases[name] = MESHES[name]()
    return cases


CASES = _cases()


@pytest.mark.parametrize("width", [4, 8])
@pytest.mark.parametrize("mesh", list(CASES))
def test_collapse_matches_numpy(mesh, width):
    bvh = build_bvh(*CASES[mesh])
    wide = build_wide(bvh, width)
    child, count, lane_tri, depth, clo, chi = _numpy_collapse(bvh, width)
    assert np.array_equal(wide.nodes["child"], child) and np.array_equal(wide.nodes["count"], count)
    assert np.array_equal(wide.packets["tri"], lane_tri)
    assert wide.depth == depth
    assert wide.stats["lane_fill"] == ((lane_tri >= 0).mean() if len(lane_tri) else 0.0)
