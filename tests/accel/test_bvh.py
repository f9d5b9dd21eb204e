"""Host-only tests of the BVH builder (pyopencl_rt.accel.bvh)."""
import numpy as np
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.accel.bvh import MAX_DEPTH, BVH, build_bvh, sah_cost
from pyopencl_rt.accel.bvh_validate import validate

from harness import random_slivers as slivers

METHODS = ["binned", "sweep"]


def soup(n, rng, size=0.05, offset=0.0, scale=1.0):
    c = rng.random((n, 1, 3))
    v = (c + (rng.random((n, 3, 3)) - 0.5) * size) * scale + offset
    return v.reshape(-1, 3).astype(np.float32), np.arange(3 * n, dtype=np.int32).reshape(n, 3)


def icosphere(sub):
    trimesh = pytest.importorskip("trimesh")
    m = trimesh.creation.icosphere(subdivisions=sub)
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32)


def torus(major=120, minor=40):
    trimesh = pytest.importorskip("trimesh")
    m = trimesh.creation.torus(major_radius=1.0, minor_radius=0.3, major_sections=major, minor_sections=minor)
    return np.asarray(m.vertices, np.float32), np.asarray(m.faces, np.int32)


def edge_cases(rng):
    v, f = soup(300, rng)
    cases = {
        "one": (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]])),
        "four": soup(4, rng),
        "five": soup(5, rng),
        "zero_area": (np.repeat(rng.random((200, 1, 3)), 3, axis=1).reshape(-1, 3).astype(np.float32),
                      np.arange(600).reshape(200, 3)),
        "collinear": (np.stack([np.linspace(0, 1, 600), np.zeros(600), np.zeros(600)], 1).astype(np.float32),
                      np.arange(600).reshape(200, 3)),
        "identical": (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.zeros((500, 3), np.int32)
                      + np.array([0, 1, 2])),
        "duplicated": (v, np.concatenate([f, f, f])),
        "tiny": soup(500, rng, scale=1e-6),
        "huge": soup(500, rng, scale=1e6),
        "offset": soup(500, rng, scale=1.0, offset=1e6),
        "mixed_scales": (np.concatenate([soup(250, rng, scale=1e-6)[0], soup(250, rng, scale=1e6)[0]]),
                         np.arange(1500).reshape(500, 3)),
        "shared_vertices": (rng.random((50, 3)).astype(np.float32), rng.integers(0, 50, (400, 3))),
    }
    return cases


def check_boxes_exact(b: BVH):
    """Independent re-check of node boxes: recompute every subtree's bounds from the triangles."""
    tv = np.stack([b.triangles["v0"], b.triangles["v1"], b.triangles["v2"]], 1)[:, :, :3]
    tlo, thi = tv.min(1), tv.max(1)

    def walk(i):
        n = b.nodes[i]
        lo_all, hi_all = [], []
        for s in ("left", "right"):
            c, ch = int(n[f"count_{s}"]), int(n[f"child_{s}"])
            if c == -1:
                assert np.all(n[f"bmin_{s}"] == np.inf) and np.all(n[f"bmax_{s}"] == -np.inf)
                continue
            if c > 0:
                lo, hi = tlo[ch:ch + c].min(0), thi[ch:ch + c].max(0)
            else:
                lo, hi = walk(ch)
            np.testing.assert_array_equal(n[f"bmin_{s}"], lo)
            np.testing.assert_array_equal(n[f"bmax_{s}"], hi)
            lo_all.append(lo)
            hi_all.append(hi)
        return np.min(lo_all, 0), np.max(hi_all, 0)

    if len(b.triangles):
        walk(0)


@pytest.mark.parametrize("method", METHODS)
def test_edge_cases_validate(method, rng):
    for name, (v, f) in edge_cases(rng).items():
        b = build_bvh(v, f, method=method)
        validate(b)
        check_boxes_exact(b)
        assert b.nodes.dtype == abi.BVH_NODE and b.triangles.dtype == abi.TRIANGLE, name
        assert b.prim_ids.dtype == np.int32
        assert sorted(b.prim_ids.tolist()) == list(range(len(f))), name
        assert b.stats["depth"] <= MAX_DEPTH
        assert sum(k * c for k, c in b.stats["leaf_size_histogram"].items()) == len(f), name
        assert max(b.stats["leaf_size_histogram"]) <= 64 or name == "identical", name
        lo, hi = b.bounds
        np.testing.assert_array_equal(lo, v[f].reshape(-1, 3).min(0))
        np.testing.assert_array_equal(hi, v[f].reshape(-1, 3).max(0))


@pytest.mark.parametrize("method", METHODS)
def test_empty_mesh(method):
    b = build_bvh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32), method=method)
    validate(b)
    assert len(b.nodes) == 1 and len(b.triangles) == 0 and len(b.prim_ids) == 0
    assert b.nodes["count_left"][0] == -1 and b.nodes["count_right"][0] == -1
    assert np.all(b.nodes["bmin_left"] == np.inf) and np.all(b.nodes["bmax_right"] == -np.inf)
    assert b.stats["triangles"] == 0 and b.stats["leaves"] == 0


@pytest.mark.parametrize("method", METHODS)
def test_single_leaf_root(method, rng):
    v, f = soup(3, rng)
    b = build_bvh(v, f, method=method)
    validate(b)
    n = b.nodes
    assert len(n) == 1 and n["count_left"][0] == 3 and n["child_left"][0] == 0
    assert n["count_right"][0] == -1
    assert b.stats["depth"] == 0 and b.stats["leaves"] == 1
    # cost of one record + one leaf of 3 triangles whose box is the root box
    assert sah_cost(b, 2.0, 1.5) == pytest.approx(2.0 + 3 * 1.5)


@pytest.mark.parametrize("method", METHODS)
def test_meshes_validate_and_exact(method, rng):
    meshes = [icosphere(3), torus(30, 10), soup(3000, rng), slivers(2000, rng)]
    for v, f in meshes:
        b = build_bvh(v, f, method=method)
        validate(b)
        check_boxes_exact(b)
        s = b.stats
        assert s["node_count"] == len(b.nodes) == s["inner_nodes"]
        assert s["leaves"] == s["inner_nodes"] + 1  # a full binary tree
        assert s["sah_cost"] == pytest.approx(sah_cost(b))
        assert max(s["leaf_size_histogram"]) <= 64
        assert sum(s["leaf_size_histogram"].values()) == s["leaves"]


def test_max_leaf_size_respected(rng):
    v, f = soup(2000, rng)
    for mls in (1, 2, 8):
        # SAH leaves may exceed max_leaf_size only where splitting does not pay; with costly
        # traversal those appear, with free traversal every leaf must obey the limit
        b = build_bvh(v, f, max_leaf_size=mls, traversal_cost=0.0, intersection_cost=1.0)
        validate(b)
        assert max(b.stats["leaf_size_histogram"]) <= max(mls, 64)
    b = build_bvh(v, f, max_leaf_size=1)
    validate(b)
    assert 1 in b.stats["leaf_size_histogram"]


def test_validate_catches_corruption(rng):
    v, f = soup(500, rng)
    good = build_bvh(v, f)
    validate(good)

    def corrupt(fn):
        b = build_bvh(v, f)
        fn(b)
        with pytest.raises((AssertionError, ValueError)):
            validate(b)

    def shrink_leaf_box(b):
        i = int(np.flatnonzero(b.nodes["count_left"] > 0)[0])
        b.nodes["bmax_left"][i] -= 1e-3

    def grow_inner_box(b):
        b.nodes["bmax_left"][0] += 1.0

    def swap_prim(b):
        b.prim_ids[[0, 1]] = b.prim_ids[[1, 0]]

    def dup_prim(b):
        b.prim_ids[0] = b.prim_ids[1]

    def bad_count(b):
        i = int(np.flatnonzero(b.nodes["count_left"] > 1)[0])
        b.nodes["count_left"][i] -= 1

    def cycle(b):
        i = int(np.flatnonzero(b.nodes["count_left"] == 0)[-1])
        b.nodes["child_left"][i] = 0

    def w_nonzero(b):
        b.triangles["v1"][3, 3] = 1.0

    for fn in (shrink_leaf_box, grow_inner_box, swap_prim, dup_prim, bad_count, cycle, w_nonzero):
        corrupt(fn)


def test_binned_close_to_sweep():
    # the bench checks 100k-triangle meshes; keep the test small
    rng = np.random.default_rng(7)
    for v, f in [icosphere(5), torus(160, 60), soup(20000, rng), slivers(15000, rng)]:
        binned = build_bvh(v, f, method="binned")
        sweep = build_bvh(v, f, method="sweep")
        ratio = binned.stats["sah_cost"] / sweep.stats["sah_cost"]
        assert ratio < 1.10, (len(f), ratio)
        assert ratio > 0.9  # a sweep is the reference; binned should not beat it by much


def _median_split_cost(v, f, leaf=4):
    """SAH cost of a BVH built by object-median splits on the longest centroid axis."""
    tv = v[f]
    lo, hi = tv.min(1).astype(np.float64), tv.max(1).astype(np.float64)
    c = lo + hi

    def area(l, h):
        d = np.maximum(h - l, 0)
        return 2 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])

    total = 0.0
    stack = [np.arange(len(f))]
    inner = 0
    while stack:
        ids = stack.pop()
        a = area(lo[ids].min(0), hi[ids].max(0))
        if len(ids) <= leaf:
            total += a * len(ids)
            continue
        total += a
        inner += 1
        ax = np.argmax(np.ptp(c[ids], 0))
        o = ids[np.argsort(c[ids, ax], kind="stable")]
        stack += [o[: len(o) // 2], o[len(o) // 2:]]
    root = area(lo.min(0), hi.max(0))
    return total / root


def test_binned_beats_trivial_trees(rng):
    v, f = torus(60, 24)
    b = build_bvh(v, f)
    validate(b)
    assert b.stats["sah_cost"] < _median_split_cost(v, f)
    assert b.stats["sah_cost"] < 0.1 * (1.0 + len(f))     # one-leaf root costs 1 + T
    v, f = slivers(3000, rng)
    assert build_bvh(v, f).stats["sah_cost"] < _median_split_cost(v, f)


@pytest.mark.parametrize("method", METHODS)
def test_two_clusters_hand_checked(method, rng):
    # two clusters of 8 tiny triangles, far apart along x: the root must separate them
    a = soup(8, rng, size=0.01, scale=0.1)[0]
    bverts = soup(8, rng, size=0.01, scale=0.1, offset=np.array([100.0, 0, 0]))[0]
    v = np.concatenate([a, bverts])
    f = np.arange(48).reshape(16, 3)
    b = build_bvh(v, f, method=method)
    validate(b)
    root = b.nodes[0]
    assert root["bmax_left"][0] < 1.0 and root["bmin_right"][0] > 99.0 or \
        root["bmax_right"][0] < 1.0 and root["bmin_left"][0] > 99.0

    # closed form SAH of a hand-built tree: unit cube [0,1]^3 split into two leaves
    #   left leaf box [0,0.5]x[0,1]x[0,1] with 2 triangles, right leaf [0.5,1]x[0,1]x[0,1] with 3
    nodes = np.zeros(1, abi.BVH_NODE)
    nodes["bmin_left"], nodes["bmax_left"] = [0, 0, 0], [0.5, 1, 1]
    nodes["child_left"], nodes["count_left"] = 0, 2
    nodes["bmin_right"], nodes["bmax_right"] = [0.5, 0, 0], [1, 1, 1]
    nodes["child_right"], nodes["count_right"] = 2, 3
    hand = BVH(nodes=nodes, triangles=np.zeros(5, abi.TRIANGLE), prim_ids=np.arange(5, dtype=np.int32),
               vertices=np.zeros((0, 3), np.float32), faces=np.zeros((0, 3), np.int32), stats={})
    # areas: root 6, each half 2*(0.5 + 1 + 0.5) = 4
    ct, ci = 1.5, 2.0
    assert sah_cost(hand, ct, ci) == pytest.approx(ct * 6 / 6 + ci * (4 / 6 * 2 + 4 / 6 * 3))


@pytest.mark.parametrize("method", METHODS)
def test_depth_capped_on_pathological_input(method):
    # triangles at exponentially shrinking positions 2^-k: SAH would build a chain
    k = np.arange(150)
    s = np.ldexp(1.0, -k.astype(int)).astype(np.float32)
    s = np.maximum(s, np.float32(1e-38))
    base = np.stack([s, s, s], 1)
    tri = np.stack([base, base * np.array([1.0, 0.5, 0.5], np.float32), base * np.array([0.5, 1.0, 0.5], np.float32)], 1)
    v = np.concatenate([tri.reshape(-1, 3)] * 4).astype(np.float32)
    f = np.arange(len(v)).reshape(-1, 3)
    b = build_bvh(v, f, method=method, max_leaf_size=1)
    validate(b)
    assert b.stats["depth"] <= MAX_DEPTH


def test_bad_input():
    with pytest.raises(ValueError):
        build_bvh(np.zeros((3, 3)), np.array([[0, 1, 3]]))
    with pytest.raises(ValueError):
        build_bvh(np.zeros((3, 3)), np.array([[0, 1, 2]]), method="nope")
    with pytest.raises(ValueError):
        build_bvh(np.array([[0, 0, np.nan], [1, 0, 0], [0, 1, 0]]), np.array([[0, 1, 2]]))


def test_stats_keys(rng):
    v, f = soup(100, rng)
    s = build_bvh(v, f).stats
    for k in ("method", "triangles", "sah_cost", "node_count", "inner_nodes", "leaves", "depth",
              "leaf_size_histogram", "build_seconds"):
        assert k in s
    assert s["method"] == "binned" and s["triangles"] == 100 and s["build_seconds"] >= 0
