"""The compiled binned SAH builder (pyopencl_rt.accel.bvh_binned): its root split and every node's
split and leaf decision against a float64 numpy reference of the rule, the thread pool against the
one-thread build, and its numba cache fallback."""
import numpy as np
import pytest

from pyopencl_rt.accel import bvh_binned
from pyopencl_rt.accel.bvh import build_bvh
from pyopencl_rt.accel.bvh_validate import validate

from harness import random_slivers as slivers


def soup(n, rng, size=0.05):
    c = rng.random((n, 1, 3))
    v = c + (rng.random((n, 3, 3)) - 0.5) * size
    return v.reshape(-1, 3).astype(np.float32), np.arange(3 * n, dtype=np.int32).reshape(n, 3)


def _area(lo, hi):
    d = np.maximum(hi.astype(np.float64) - lo.astype(np.float64), 0.0)
    return 2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])


def reference_root_split(V, F, bins=16, step=1):
    """The best binned SAH plane of the whole mesh, by brute force in numpy: centroids lo + hi in
    float64, ``bins`` equal bins over the centroid bounds per axis, every plane costed on the
    triangles ``0, step, 2 * step, ...`` as area(left) * n_left + area(right) * n_right; the first
    minimum (x, y, z; low bins first).  Returns every triangle's side of that plane."""
    tv = V[F]
    lo, hi = tv.min(axis=1), tv.max(axis=1)
    c = lo.astype(np.float64) + hi.astype(np.float64)
    cmin, cmax = c.min(axis=0), c.max(axis=0)
    sample = np.zeros(len(F), bool)
    sample[::step] = True
    best, left_best = np.inf, None
    for a in range(3):
        if cmax[a] <= cmin[a]:
            continue
        b = np.minimum(np.floor((c[:, a] - cmin[a]) * (bins / (cmax[a] - cmin[a]))), bins - 1)
        for j in range(bins - 1):
            left, right = (b <= j) & sample, (b > j) & sample
            nl, nr = int(left.sum()), int(right.sum())
            if nl == 0 or nr == 0:
                continue
            cost = _area(lo[left].min(0), hi[left].max(0)) * nl + _area(lo[right].min(0), hi[right].max(0)) * nr
            if cost < best:
                best, left_best = cost, b <= j
    return left_best, lo, hi


@pytest.mark.parametrize("make, n", [(soup, 3000), (slivers, 3000), (soup, 20000)])
def test_root_split_is_the_binned_sah_minimum(make, n, rng):
    """At 20k triangles the root bins a strided sample (every 2nd triangle) and grows the child
    boxes in the partition; below 2 * _SAMPLE it bins every triangle."""
    V, F = make(n, rng)
    b = build_bvh(V, F, bins=16)
    validate(b)
    step = n // bvh_binned._SAMPLE if n >= 2 * bvh_binned._SAMPLE else 1
    assert step == (2 if n == 20000 else 1)
    left, lo, hi = reference_root_split(V, F, 16, step)
    nl = int(left.sum())
    root = b.nodes[0]
    np.testing.assert_array_equal(root["bmin_left"], lo[left].min(0))
    np.testing.assert_array_equal(root["bmax_left"], hi[left].max(0))
    np.testing.assert_array_equal(root["bmin_right"], lo[~left].min(0))
    np.testing.assert_array_equal(root["bmax_right"], hi[~left].max(0))
    # the left child's triangles are the first nl of the reordered array, exactly the reference's
    assert set(b.prim_ids[:nl].tolist()) == set(np.flatnonzero(left).tolist())


def test_threads_do_not_change_the_tree(rng):
    V, F = soup(40_000, rng, size=0.02)          # above _PARALLEL_MIN: the pooled build runs
    assert len(F) >= bvh_binned._PARALLEL_MIN
    one = build_bvh(V, F, threads=1)
    validate(one)
    for threads in (2, 3):
        many = build_bvh(V, F, threads=threads)
        assert many.nodes.tobytes() == one.nodes.tobytes(), threads
        assert np.array_equal(many.prim_ids, one.prim_ids)
        assert many.triangles.tobytes() == one.triangles.tobytes()
        assert many.stats["sah_cost"] == one.stats["sah_cost"]


def test_task_path_on_degenerate_meshes(rng, monkeypatch):
    """Small meshes through the thread pool (split tasks down to 64 triangles, then subtrees):
    the same trees as on one thread, valid, on inputs with degenerate splits."""
    monkeypatch.setattr(bvh_binned, "_PARALLEL_MIN", 0)
    monkeypatch.setattr(bvh_binned, "_BIG_MIN", 64)
    v, f = soup(700, rng)
    cases = [
        soup(2000, rng),
        slivers(1500, rng),
        (np.repeat(rng.random((400, 1, 3)), 3, axis=1).reshape(-1, 3).astype(np.float32),   # zero area
         np.arange(1200).reshape(400, 3)),
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.zeros((900, 3), np.int32) + [0, 1, 2]),
        (v, np.concatenate([f, f, f])),                                                          # duplicates
        (np.stack([np.linspace(0, 1, 1500), np.zeros(1500), np.zeros(1500)], 1).astype(np.float32),
         np.arange(1500).reshape(500, 3)),                                                      # collinear
    ]
    for V, F in cases:
        pooled = build_bvh(V, F, threads=2)
        validate(pooled)
        one = build_bvh(V, F, threads=1)
        assert pooled.nodes.tobytes() == one.nodes.tobytes()
        assert np.array_equal(pooled.prim_ids, one.prim_ids)


def _double(x):
    return 2 * x


def test_cache_falls_back_when_no_location_is_writable(monkeypatch):
    from numba.core import config
    from numba.core.caching import CacheImpl, NullCache

    cached = bvh_binned._jit()(_double)
    assert cached(21) == 42 and not isinstance(cached._cache, NullCache)
    monkeypatch.setattr(config, "CACHE_LOCATOR_CLASSES", "")
    monkeypatch.setattr(CacheImpl, "_locator_classes", [])     # as if no place were writable
    uncached = bvh_binned._jit()(_double)
    assert uncached(21) == 42 and isinstance(uncached._cache, NullCache)


def _binned_split(lo, hi, bins=16):
    """The binned SAH rule at one node, in float64 numpy: (best cost, the left side's mask) of the
    first minimum over the planes (x, y, z; low bins first), bins halved down to 4 while above the
    node's size; (inf, None) where no plane separates anything."""
    n = len(lo)
    nb = bins
    while nb > 4 and nb > n:
        nb //= 2
    c = lo.astype(np.float64) + hi.astype(np.float64)
    cmin, cmax = c.min(0), c.max(0)
    best, left_best = np.inf, None
    for a in range(3):
        if not cmax[a] > cmin[a]:
            continue
        x = (c[:, a] - cmin[a]) * (nb / (cmax[a] - cmin[a]))
        b = np.where(x >= nb - 1, nb - 1, np.where(x > 0, np.floor(x), 0))
        for j in range(nb - 1):
            left = b <= j
            nl = int(left.sum())
            if nl == 0 or nl == n:
                continue
            cost = _area(lo[left].min(0), hi[left].max(0)) * nl + _area(lo[~left].min(0), hi[~left].max(0)) * (n - nl)
            if cost < best:
                best, left_best = cost, left
    return best, left_best


@pytest.mark.parametrize("mesh", ["soup", "slivers", "heightfield"])
def test_every_node_follows_the_binned_rule(mesh, rng):
    """Every node of the compiled build (below the sampling size, above the median depth) against
    the float64 reference of the rule: an inner node's left child holds exactly the triangles left
    of the first cheapest plane, a leaf is a node of <= max_leaf_size triangles or one of <= 64 the
    SAH keeps whole; the heightfield's grid gives many empty bins and tied planes."""
    from pyopencl_rt.bench.scale_scene import heightfield

    V, F = {"soup": lambda: soup(2000, rng), "slivers": lambda: slivers(1500, rng),
            "heightfield": lambda: heightfield(30)}[mesh]()
    b = build_bvh(V, F)
    validate(b)
    tv = np.stack([b.triangles[f"v{k}"][:, :3] for k in range(3)], 1)      # reordered triangles
    lo, hi = tv.min(1), tv.max(1)
    nodes = b.nodes
    R = len(nodes)
    first, size = np.zeros(R, np.int64), np.zeros(R, np.int64)
    for r in range(R - 1, -1, -1):            # children have larger record numbers (breadth first)
        sides = [(nodes[f"child_{s}"][r], nodes[f"count_{s}"][r]) for s in ("left", "right")]
        firsts = [ch if cnt > 0 else first[ch] for ch, cnt in sides]
        sizes = [cnt if cnt > 0 else size[ch] for ch, cnt in sides]
        first[r], size[r] = firsts[0], sum(sizes)
        assert firsts[1] == firsts[0] + sizes[0]

    def leaf_rule(f, n):
        if n <= 4:
            return True
        best, _ = _binned_split(lo[f:f + n], hi[f:f + n])
        return n <= 64 and (best == np.inf or 1.0 + best / _area(lo[f:f + n].min(0), hi[f:f + n].max(0)) >= n)

    checked = 0
    for r in range(R):
        f, n = first[r], size[r]
        assert not leaf_rule(f, n)
        best, left = _binned_split(lo[f:f + n], hi[f:f + n])
        nl = int(left.sum())
        assert np.all(left[:nl]) and not np.any(left[nl:]), r  # the left child: the reference's side
        for s, (cf, cn) in zip(("left", "right"), ((f, nl), (f + nl, n - nl))):
            assert (nodes[f"count_{s}"][r] > 0) == leaf_rule(cf, cn)
        checked += 1
    assert checked == R > 100
