"""The binned SAH builder behind ``build_bvh(method="binned")``, compiled with numba.

Top-down, one node at a time, in place (the classic binned build of Wald 2007):

* A node is a range ``[begin, end)`` of two arrays permuted together: ``pb`` (T, 6) float32
  triangle boxes (lo xyz, hi xyz) and ``idx`` (T,) the original face indices.
* Binning: ``bins`` equal bins per axis over the node's **centroid** bounds (centroids are
  ``lo + hi`` in float64, exact for most inputs and never overflowing); each bin keeps a count
  and the float32 box of its triangles.  Every split plane between bins on the three axes is
  costed in float64; the first minimum wins (x before y before z, low bins first).  Nodes of
  fewer than ``bins`` triangles use the largest power of two of bins below their size (at least
  4); nodes of ``2 * _SAMPLE`` triangles or more (the top few levels) bin an evenly strided
  sample of about ``_SAMPLE`` of them (all of them if the sample has no separating plane).
* The leaf / split decision is :func:`pyopencl_rt.accel.bvh._decide`'s, node by node: a node
  becomes a leaf when it holds ``<= max_leaf_size`` triangles, when it is at depth
  :data:`~pyopencl_rt.accel.bvh.MAX_DEPTH`, or when it holds at most ``MAX_SAH_LEAF`` triangles
  and the SAH says a leaf is no dearer; a node that no plane separates (all centroids equal), and
  every node from depth ``_MEDIAN_DEPTH`` on, is split into index halves.
* Partition: a two-pointer (Hoare) pass sends each triangle to the side of its bin, recomputed by
  the very same expression as in binning, so the child boxes come exactly from the bins (float32
  min/max, no arithmetic); the pass also gathers each child's centroid bounds.  After a sampled
  binning the pass grows the child boxes from every triangle instead.

Node ids: the subtree of a node with ``n`` triangles and id ``i`` uses ids in ``[i, i + 2n - 1)``
(a binary tree with ``n`` triangles has at most ``2n - 1`` nodes): the left child is ``i + 1``,
the right child ``i + 2 * n_left``.  Ids therefore depend only on the tree, not on which thread
built what.  The node table keeps, per id, only the box and the triangle count (negated for a
leaf): children and first triangles follow from the counts (28 bytes an id; it held first, count,
children, depth and a kind, 45 bytes, before).  The records are then numbered breadth first, left
child before right, as the level-synchronous numpy builder numbered them: the 4- and 8-wide
collapses of :mod:`pyopencl_rt.accel.bvh_wide`, breadth first too, read them in that order.  The
node table and the triangle boxes are freed before the reordered triangle records are made.

Parallelism (meshes of at least ``_PARALLEL_MIN`` triangles): nodes bigger than
``max(T / (8 * threads), _BIG_MIN)`` are split one by one as tasks of a thread pool; the smaller
subtrees are built whole by one compiled call each, also in the pool (every
compiled function releases the GIL).  The tree does not depend on the thread count.

Compilation: the first call in a process compiles the kernels (a few seconds) unless numba's
on-disk cache has them.  The cache sits in ``__pycache__`` next to this file, or, where that is
not writable (an installed wheel in a read-only location), in numba's per-user cache directory
(``NUMBA_CACHE_DIR`` overrides both); :func:`warm_up` compiles or loads them on purpose.
"""
from __future__ import annotations

import os
import time
from concurrent.futures import FIRST_COMPLETED, ThreadPoolExecutor, wait

import numpy as np
from numba import njit

from ..device import abi
from ..device.host_memory import aligned_empty


def _jit(inline="never"):
    """numba.njit, releasing the GIL, cached on disk where numba finds a writable place."""
    def decorate(fn):
        options = dict(nogil=True, error_model="numpy", inline=inline)
        try:
            return njit(cache=True, **options)(fn)
        except RuntimeError:    # no writable cache location: compile in every process instead
            return njit(**options)(fn)
    return decorate


# _records and build write the records as raw words: per side bmin xyz, child, bmax xyz, count
assert [abi.BVH_NODE.fields[f"{k}_{s}"][1] for s in ("left", "right") for k in ("bmin", "child", "bmax", "count")] \
    == [0, 12, 16, 28, 32, 44, 48, 60] and abi.BVH_NODE.itemsize == 64
assert [abi.TRIANGLE.fields[f"v{i}"][1] for i in range(3)] == [0, 16, 32] and abi.TRIANGLE.itemsize == 48

_STACK = 128            # explicit traversal stack of the subtree builder (depth <= MAX_DEPTH + 1)
_PARALLEL_MIN = 32768   # meshes below this are built by one call on the calling thread
_BIG_MIN = 4096         # nodes above max(this, T / (8 * threads)) are split as single tasks
_SAMPLE = 8192          # nodes of 2 * _SAMPLE triangles or more bin a strided sample of about this many


@_jit()
def _bin_of(c, cmin, scale, nb):
    b = (c - cmin) * scale
    if b >= nb - 1:
        return nb - 1
    if not b > 0.0:     # never below 0 for c in the node's bounds; a guard for the indexing
        return 0
    return int(b)


@_jit()
def _bin_add(cnt, bb, k, lo0, lo1, lo2, hi0, hi1, hi2):
    cnt[k] += 1
    bb[k, 0] = min(bb[k, 0], lo0)
    bb[k, 1] = min(bb[k, 1], lo1)
    bb[k, 2] = min(bb[k, 2], lo2)
    bb[k, 3] = max(bb[k, 3], hi0)
    bb[k, 4] = max(bb[k, 4], hi1)
    bb[k, 5] = max(bb[k, 5], hi2)


@_jit()
def _centroid(pb, i):
    """Twice the box centre, in float64 (exact for most inputs, never overflows)."""
    return (np.float64(pb[i, 0]) + np.float64(pb[i, 3]), np.float64(pb[i, 1]) + np.float64(pb[i, 4]),
            np.float64(pb[i, 2]) + np.float64(pb[i, 5]))


@_jit()
def _area(lo0, lo1, lo2, hi0, hi1, hi2):
    dx = max(np.float64(hi0) - np.float64(lo0), 0.0)
    dy = max(np.float64(hi1) - np.float64(lo1), 0.0)
    dz = max(np.float64(hi2) - np.float64(lo2), 0.0)
    return 2.0 * (dx * dy + dy * dz + dz * dx)


@_jit()
def _union(bb, k, lo0, lo1, lo2, hi0, hi1, hi2):
    """The box (lo, hi) grown by box k of bb."""
    return (min(lo0, bb[k, 0]), min(lo1, bb[k, 1]), min(lo2, bb[k, 2]), max(hi0, bb[k, 3]), max(hi1, bb[k, 4]),
            max(hi2, bb[k, 5]))


@_jit()
def _range_bounds(pb, begin, end, box, cb):
    """box (6,) float32: exact bounds of pb[begin:end]; cb (6,) float64: its centroid bounds."""
    for d in range(3):
        box[d] = np.inf
        box[3 + d] = -np.inf
        cb[d] = np.inf
        cb[3 + d] = -np.inf
    for i in range(begin, end):
        for d in range(3):
            lo = pb[i, d]
            hi = pb[i, 3 + d]
            box[d] = min(box[d], lo)
            box[3 + d] = max(box[3 + d], hi)
            c = np.float64(lo) + np.float64(hi)
            cb[d] = min(cb[d], c)
            cb[3 + d] = max(cb[3 + d], c)


@_jit()
def _grow(pb, i, cbox, ccb, s):
    """Add triangle i to the box and the centroid bounds of child s."""
    for d in range(3):
        lo = pb[i, d]
        hi = pb[i, 3 + d]
        cbox[s, d] = min(cbox[s, d], lo)
        cbox[s, 3 + d] = max(cbox[s, 3 + d], hi)
        c = np.float64(lo) + np.float64(hi)
        ccb[s, d] = min(ccb[s, d], c)
        ccb[s, 3 + d] = max(ccb[s, 3 + d], c)


@_jit()
def _swap(pb, idx, i, j):
    """Exchange triangles i and j (their boxes and indices)."""
    for d in range(6):
        t = pb[i, d]
        pb[i, d] = pb[j, d]
        pb[j, d] = t
    t2 = idx[i]
    idx[i] = idx[j]
    idx[j] = t2


@_jit()
def _partition_exact(pb, idx, begin, end, bax, cmin, sc, nb, bbin, cbox, ccb):
    """The partition of a node whose plane came from a sample: the children's boxes (cbox, set to
    empty boxes by the caller) are grown here, from every triangle, with their centroid bounds."""
    i = begin
    j = end - 1
    while True:
        while i <= j and _bin_of(np.float64(pb[i, bax]) + np.float64(pb[i, 3 + bax]), cmin, sc, nb) <= bbin:
            _grow(pb, i, cbox, ccb, 0)
            i += 1
        while i < j and _bin_of(np.float64(pb[j, bax]) + np.float64(pb[j, 3 + bax]), cmin, sc, nb) > bbin:
            _grow(pb, j, cbox, ccb, 1)
            j -= 1
        if i >= j:
            break
        _swap(pb, idx, i, j)
        _grow(pb, i, cbox, ccb, 0)
        _grow(pb, j, cbox, ccb, 1)
        i += 1
        j -= 1
    if i == j:
        _grow(pb, j, cbox, ccb, 1)
    return i


@_jit(inline="always")
def _process_node(pb, idx, begin, end, depth, nid, box, cb, cbox, ccb, size, nbox, bins, max_leaf,
                  ct, ci, max_depth, median_depth, max_sah_leaf, cnt, bb, scale, rarea):
    """Decide and, for a split, partition one node.  Writes node ``nid`` (its box; size: its
    triangle count, negated for a leaf) and returns the split
    position (-1 for a leaf); cbox (2, 6) / ccb (2, 6) receive the children's boxes and centroid
    bounds.  cnt (3 * bins,), bb (3 * bins, 6), scale (3,) and rarea (bins,) are scratch; bin b
    of axis a is row a * nb + b."""
    n = end - begin
    for d in range(6):
        nbox[nid, d] = box[d]
    if n <= max_leaf or depth >= max_depth:
        size[nid] = -n
        return -1
    # fewer bins for small nodes: the per-node sweep then stays below the per-triangle work
    nb = bins
    while nb > 4 and nb > n:
        nb //= 2
    for a in range(3):
        ext = cb[3 + a] - cb[a]
        scale[a] = nb / ext if ext > 0.0 else 0.0
    # big nodes choose their plane from an evenly strided sample (all of them if that finds none)
    step = n // _SAMPLE if n >= 2 * _SAMPLE else 1
    while True:
        for k in range(3 * nb):
            cnt[k] = 0
            for d in range(3):
                bb[k, d] = np.inf
                bb[k, 3 + d] = -np.inf
        # a degenerate axis (scale 0) puts everything in its bin 0, where no plane separates anything
        m0, m1, m2 = cb[0], cb[1], cb[2]
        s0, s1, s2 = scale[0], scale[1], scale[2]
        m = 0
        for i in range(begin, end, step):
            m += 1
            lo0, lo1, lo2 = pb[i, 0], pb[i, 1], pb[i, 2]
            hi0, hi1, hi2 = pb[i, 3], pb[i, 4], pb[i, 5]
            k0 = _bin_of(np.float64(lo0) + np.float64(hi0), m0, s0, nb)
            k1 = nb + _bin_of(np.float64(lo1) + np.float64(hi1), m1, s1, nb)
            k2 = 2 * nb + _bin_of(np.float64(lo2) + np.float64(hi2), m2, s2, nb)
            _bin_add(cnt, bb, k0, lo0, lo1, lo2, hi0, hi1, hi2)
            _bin_add(cnt, bb, k1, lo0, lo1, lo2, hi0, hi1, hi2)
            _bin_add(cnt, bb, k2, lo0, lo1, lo2, hi0, hi1, hi2)
        # SAH over the nb - 1 planes of each axis: suffix areas/counts, then a prefix sweep
        best = np.inf
        bax = -1
        bbin = -1
        for a in range(3):
            if scale[a] == 0.0:
                continue
            # an empty bin changes no box and no count: its suffix area is the next bin's, and the
            # plane after it costs what the plane before it did (never strictly less: skipped)
            r0 = r1 = r2 = np.inf
            r3 = r4 = r5 = -np.inf
            area = 0.0
            for b in range(nb - 1, 0, -1):
                k = a * nb + b
                if cnt[k] > 0:
                    r0, r1, r2, r3, r4, r5 = _union(bb, k, r0, r1, r2, r3, r4, r5)
                    area = _area(r0, r1, r2, r3, r4, r5)
                rarea[b] = area
            l0 = l1 = l2 = np.inf
            l3 = l4 = l5 = -np.inf
            nl = 0
            for b in range(nb - 1):
                k = a * nb + b
                if cnt[k] == 0:
                    continue
                l0, l1, l2, l3, l4, l5 = _union(bb, k, l0, l1, l2, l3, l4, l5)
                nl += cnt[k]
                nr = m - nl
                if nl == 0 or nr == 0:
                    continue
                cost = _area(l0, l1, l2, l3, l4, l5) * nl + rarea[b + 1] * nr
                if cost < best:
                    best = cost
                    bax = a
                    bbin = b
        if bax >= 0 or step == 1:
            break
        step = 1
    best *= n / m
    # leaf, SAH split or index halves (the rule of bvh._decide)
    valid = bax >= 0
    node_area = _area(box[0], box[1], box[2], box[3], box[4], box[5])
    if node_area > 0.0:
        split_cost = ct + ci * best / node_area
    else:
        split_cost = ct + ci * n
    if n <= max(max_sah_leaf, max_leaf) and (not valid or split_cost >= ci * n):
        size[nid] = -n
        return -1
    size[nid] = n
    for s in range(2):
        for d in range(3):
            cbox[s, d] = np.inf
            cbox[s, 3 + d] = -np.inf
            ccb[s, d] = np.inf
            ccb[s, 3 + d] = -np.inf
    if not valid or depth >= median_depth:
        mid = begin + n // 2
        for i in range(begin, end):
            _grow(pb, i, cbox, ccb, 0 if i < mid else 1)
        return mid
    if step > 1:
        return _partition_exact(pb, idx, begin, end, bax, cb[bax], scale[bax], nb, bbin, cbox, ccb)
    # child boxes exactly from the bins
    for b in range(nb):
        s = 0 if b <= bbin else 1
        for d in range(3):
            cbox[s, d] = min(cbox[s, d], bb[bax * nb + b, d])
            cbox[s, 3 + d] = max(cbox[s, 3 + d], bb[bax * nb + b, 3 + d])
    cmin = cb[bax]
    sc = scale[bax]
    # centroid bounds of the left (x0..x2 min, y0..y2 max) and right (u, v) children
    x0 = x1 = x2 = u0 = u1 = u2 = np.inf
    y0 = y1 = y2 = v0 = v1 = v2 = -np.inf
    i = begin
    j = end - 1
    while True:
        while i <= j:
            c0, c1, c2 = _centroid(pb, i)
            if _bin_of(c0 if bax == 0 else (c1 if bax == 1 else c2), cmin, sc, nb) > bbin:
                break
            x0, x1, x2 = min(x0, c0), min(x1, c1), min(x2, c2)
            y0, y1, y2 = max(y0, c0), max(y1, c1), max(y2, c2)
            i += 1
        while i < j:
            c0, c1, c2 = _centroid(pb, j)
            if _bin_of(c0 if bax == 0 else (c1 if bax == 1 else c2), cmin, sc, nb) <= bbin:
                break
            u0, u1, u2 = min(u0, c0), min(u1, c1), min(u2, c2)
            v0, v1, v2 = max(v0, c0), max(v1, c1), max(v2, c2)
            j -= 1
        if i >= j:
            break
        # pb[i] goes right and pb[j] left: swap them
        _swap(pb, idx, i, j)
        c0, c1, c2 = _centroid(pb, i)
        x0, x1, x2 = min(x0, c0), min(x1, c1), min(x2, c2)
        y0, y1, y2 = max(y0, c0), max(y1, c1), max(y2, c2)
        c0, c1, c2 = _centroid(pb, j)
        u0, u1, u2 = min(u0, c0), min(u1, c1), min(u2, c2)
        v0, v1, v2 = max(v0, c0), max(v1, c1), max(v2, c2)
        i += 1
        j -= 1
    # [begin, i) goes left; when the loops stopped on i == j that element was on the right
    if i == j:
        c0, c1, c2 = _centroid(pb, j)
        u0, u1, u2 = min(u0, c0), min(u1, c1), min(u2, c2)
        v0, v1, v2 = max(v0, c0), max(v1, c1), max(v2, c2)
    ccb[0, 0], ccb[0, 1], ccb[0, 2], ccb[0, 3], ccb[0, 4], ccb[0, 5] = x0, x1, x2, y0, y1, y2
    ccb[1, 0], ccb[1, 1], ccb[1, 2], ccb[1, 3], ccb[1, 4], ccb[1, 5] = u0, u1, u2, v0, v1, v2
    return i


@_jit()
def _build_subtree(pb, idx, begin, end, depth, nid, box, cb, size, nbox, bins, max_leaf, ct, ci,
                   max_depth, median_depth, max_sah_leaf, cbox, ccb, single):
    """The whole subtree of one node, depth first with an explicit stack; with ``single``, only
    the node itself: returns its split position (-1: a leaf), its children's boxes and centroid
    bounds in cbox / ccb (2, 6)."""
    cnt = np.zeros(3 * bins, np.int64)
    bb = np.empty((3 * bins, 6), np.float32)
    scale = np.empty(3)
    rarea = np.empty(bins)
    s_int = np.empty((_STACK, 4), np.int64)     # begin, end, depth, id
    s_box = np.empty((_STACK, 6), np.float32)
    s_cb = np.empty((_STACK, 6))
    cur_box = box.copy()
    cur_cb = cb.copy()
    top = 0
    while True:
        if end - begin <= max_leaf or depth >= max_depth:
            # _process_node's first rule, here: a call costs about what a small leaf does
            for d in range(6):
                nbox[nid, d] = cur_box[d]
            size[nid] = begin - end
            mid = -1
        else:
            mid = _process_node(pb, idx, begin, end, depth, nid, cur_box, cur_cb, cbox, ccb, size, nbox,
                                bins, max_leaf, ct, ci, max_depth, median_depth, max_sah_leaf, cnt, bb,
                                scale, rarea)
        if mid >= 0:
            left = nid + 1
            right = nid + 2 * (mid - begin)
            if single:
                return mid
            s_int[top, 0] = mid
            s_int[top, 1] = end
            s_int[top, 2] = depth + 1
            s_int[top, 3] = right
            for d in range(6):
                s_box[top, d] = cbox[1, d]
                s_cb[top, d] = ccb[1, d]
                cur_box[d] = cbox[0, d]
                cur_cb[d] = ccb[0, d]
            top += 1
            end = mid
            depth += 1
            nid = left
            continue
        if top == 0:
            return -1
        top -= 1
        begin = s_int[top, 0]
        end = s_int[top, 1]
        depth = s_int[top, 2]
        nid = s_int[top, 3]
        for d in range(6):
            cur_box[d] = s_box[top, d]
            cur_cb[d] = s_cb[top, d]


@_jit()
def _prim_boxes(V, F, pb, begin, end):
    for i in range(begin, end):
        for d in range(3):
            a = V[F[i, 0], d]
            b = V[F[i, 1], d]
            c = V[F[i, 2], d]
            pb[i, d] = min(a, min(b, c))
            pb[i, 3 + d] = max(a, max(b, c))


@_jit()
def _gather_triangles(V, F, order, out, begin, end):
    """out (T, 12) float32, the abi.TRIANGLE records: v0, v1, v2 of face order[i], w = 0."""
    for i in range(begin, end):
        f = order[i]
        for k in range(3):
            v = F[f, k]
            for d in range(3):
                out[i, 4 * k + d] = V[v, d]
            out[i, 4 * k + 3] = 0.0


def _scratch():
    """Room for a node's two children: boxes (float32) and centroid bounds (float64)."""
    return np.empty((2, 6), np.float32), np.empty((2, 6))


def thread_count() -> int:
    """Threads the build uses: the CPUs this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:      # not on Linux
        return max(1, os.cpu_count() or 1)


def _chunked(pool, n, fn, T, *args):
    """fn(*args, begin, end) over [0, T) in n chunks run by ``pool`` (or inline without one)."""
    if pool is None:
        fn(*args, 0, T)
        return
    bounds = [T * k // n for k in range(n + 1)]
    for f in [pool.submit(fn, *args, bounds[k], bounds[k + 1]) for k in range(n)]:
        f.result()


@_jit()
def _records(size, nbox, rec_f, rec_i, leaf_counts):
    """abi.BVH_NODE records of the inner nodes, numbered breadth first, left before right (rec_f /
    rec_i: float32 / int32 views (R, 16) of the same records); leaf_counts receives each leaf's
    size.  Node ``i``'s children are ``i + 1`` and ``i + 2 * n_left``, its first triangle is its
    parent's (left child) or the parent's first plus n_left (right child).  Returns the deepest
    leaf's depth and the two sums of bvh.sah_cost: of the records' areas and of leaf area * count."""
    R = rec_f.shape[0]
    queue = np.empty(R, np.int64)           # record r is node queue[r] ...
    first = np.empty(R, np.int64)           # ... whose triangles start at first[r]
    queue[0] = 0
    first[0] = 0
    tail = 1
    level_end = 1                           # records [.., level_end) lie at depth `depth`
    depth = 0
    record_area = 0.0
    for r in range(R):
        if r == level_end:
            depth += 1
            level_end = tail
        i = queue[r]
        record_area += _area(nbox[i, 0], nbox[i, 1], nbox[i, 2], nbox[i, 3], nbox[i, 4], nbox[i, 5])
        left = i + 1
        n_left = abs(size[left])
        for s in range(2):
            ch = left if s == 0 else i + 2 * n_left
            f = first[r] if s == 0 else first[r] + n_left
            o = 8 * s
            for d in range(3):
                rec_f[r, o + d] = nbox[ch, d]
                rec_f[r, o + 4 + d] = nbox[ch, 3 + d]
            if size[ch] < 0:
                rec_i[r, o + 3] = f
                rec_i[r, o + 7] = -size[ch]
            else:
                rec_i[r, o + 3] = tail
                rec_i[r, o + 7] = 0
                queue[tail] = ch
                first[tail] = f
                tail += 1
    nleaf = 0
    leaf_area = 0.0
    for i in range(size.shape[0]):
        if size[i] < 0:
            leaf_counts[nleaf] = -size[i]
            nleaf += 1
            leaf_area += _area(nbox[i, 0], nbox[i, 1], nbox[i, 2], nbox[i, 3], nbox[i, 4], nbox[i, 5]) * -size[i]
    return depth + 1, record_area, leaf_area


def build(V, F, max_leaf_size, bins, ct, ci, max_depth, median_depth, max_sah_leaf, threads=None):
    """Binned SAH BVH over the triangles V[F] (T >= 1) -> (abi.BVH_NODE records, or None when the
    whole mesh is one leaf; order; the reordered abi.TRIANGLE records as a (T, 12) float32 array;
    leaf sizes; deepest leaf depth; the SAH cost (bvh.sah_cost), None where the root has no
    area)."""
    T = len(F)
    bins = int(bins)
    threads = thread_count() if threads is None else max(1, int(threads))
    pool = ThreadPoolExecutor(threads) if threads > 1 and T >= _PARALLEL_MIN else None
    try:
        pb = np.empty((T, 6), np.float32)
        _chunked(pool, threads, _prim_boxes, T, V, F, pb)
        idx = np.arange(T, dtype=np.int32)
        M = 2 * T - 1
        # per node id: its triangle count (negated for a leaf; 0: an id no node took; calloc'd, so
        # untouched pages cost nothing) and box
        size = np.zeros(M, np.int32 if M < 2**31 else np.int64)
        nbox = np.empty((M, 6), np.float32)
        box = np.empty(6, np.float32)
        cb = np.empty(6)
        _range_bounds(pb, 0, T, box, cb)
        params = (bins, max_leaf_size, float(ct), float(ci), max_depth, median_depth, max_sah_leaf)
        if pool is None:
            _build_subtree(pb, idx, 0, T, 0, 0, box, cb, size, nbox, *params, *_scratch(), False)
        else:
            _build_tasks(pool, threads, pb, idx, T, box, cb, size, nbox, params)
        del pb
        if size[0] < 0:     # the whole mesh is one leaf
            nodes, leaf_counts, depth, sah = None, np.array([T]), 0, None
        else:
            nodes = np.zeros(int(np.count_nonzero(size > 0)), abi.BVH_NODE)
            raw = nodes.view(np.float32).reshape(len(nodes), 16)
            leaf_counts = np.empty(len(nodes) + 1, np.int64)
            depth, record_area, leaf_area = _records(size, nbox, raw, raw.view(np.int32), leaf_counts)
            d = np.maximum(nbox[0, 3:].astype(np.float64) - nbox[0, :3], 0.0)
            root_area = 2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])
            sah = (ct * record_area + ci * leaf_area) / root_area if root_area > 0 else None
        del size, nbox      # the node table is in the records: free it before the triangles are made
        tris = aligned_empty((T, 12), np.float32)  # read in place by a CPU device (device/host_memory.py)
        _chunked(pool, threads, _gather_triangles, T, V, F, idx, tris)
    finally:
        if pool is not None:
            pool.shutdown()
    return nodes, idx, tris, leaf_counts, int(depth), sah


def warm_up() -> float:
    """Compile the kernels, or load them from the on-disk cache, with a tiny build; returns the
    seconds it took."""
    start = time.perf_counter()
    V = np.random.default_rng(0).random((15, 3)).astype(np.float32)
    build(V, np.arange(15, dtype=np.int32).reshape(5, 3), 1, 16, 1.0, 1.0, 60, 48, 64, threads=1)
    return time.perf_counter() - start


def _build_tasks(pool, threads, pb, idx, T, box, cb, size, nbox, params):
    """Split the big nodes as single tasks, then build the subtrees below them as whole tasks."""
    big = max(T // (8 * threads), _BIG_MIN)

    def split(begin, end, depth, nid, nbox_, ncb):
        cbox, ccb = _scratch()
        mid = _build_subtree(pb, idx, begin, end, depth, nid, nbox_, ncb, size, nbox, *params, cbox, ccb, True)
        if mid < 0:
            return []
        left, right = nid + 1, nid + 2 * (mid - begin)
        return [(begin, mid, depth + 1, left, cbox[0], ccb[0]), (mid, end, depth + 1, right, cbox[1], ccb[1])]

    def subtree(begin, end, depth, nid, nbox_, ncb):
        _build_subtree(pb, idx, begin, end, depth, nid, nbox_, ncb, size, nbox, *params, *_scratch(), False)
        return []

    def submit(task):
        return pool.submit(split if task[1] - task[0] > big else subtree, *task)

    pending = {submit((0, T, 0, 0, box, cb))}
    while pending:
        done, pending = wait(pending, return_when=FIRST_COMPLETED)
        for future in done:
            for task in future.result():
                pending.add(submit(task))
