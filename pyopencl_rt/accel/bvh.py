"""BVH construction on the host.

Two top-down surface-area-heuristic (SAH) builders produce the same output, a binary BVH stored
in the Aila & Laine layout of :data:`pyopencl_rt.abi.BVH_NODE` (each record holds both
children's boxes):

``method="binned"`` (the default)
    Binned SAH over all three axes, compiled with numba and run on every CPU of the process
    (:mod:`pyopencl_rt.accel.bvh_binned`): node by node, in place, child boxes exactly from the
    bins.  About 0.6 CPU s for 1M triangles, Embree's build time at 2M (docs/BENCHMARKS.md,
    "BVH build"), within about 1-4% of the sweep's SAH cost.  The first build in a process
    compiles the kernels (or loads them from numba's on-disk cache).

``method="sweep"``
    Full-sweep SAH, the quality reference (:mod:`pyopencl_rt.accel.bvh_sweep`).

Both builders stop splitting a node when it holds ``<= max_leaf_size`` triangles, or when the SAH
says a leaf is cheaper (such leaves hold at most :data:`MAX_SAH_LEAF` triangles).  Nodes whose
centroids all coincide are split into index halves, and from depth :data:`_MEDIAN_DEPTH` on every
split is an index-halves (object median) split, so the depth never exceeds :data:`MAX_DEPTH`
(nodes reaching it become leaves whatever their size).

Node boxes are exact: each stored child box is the float32 min/max of the vertices of the
triangles below it (checked by :func:`validate`).

SAH cost of a finished tree (:func:`sah_cost`): every ``BVH_NODE`` record is an inner node
(its box is the union of its two children's boxes), every child with ``count > 0`` a leaf::

    sum_records area(record)/area(root) * C_trav + sum_leaves area(leaf)/area(root) * count * C_isect

so a mesh that fits in one leaf costs ``C_trav + T * C_isect`` (the kernel still fetches record 0).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field
from types import SimpleNamespace

import numpy as np

from ..device import abi
from ..device.host_memory import aligned_empty
from ..errors import UsageError

MAX_DEPTH = 60          # deepest leaf (root = 0); one traversal stack entry per level
assert MAX_DEPTH + 1 <= abi.BVH_STACK_SIZE
MAX_SAH_LEAF = 64       # largest leaf the SAH may choose (bigger nodes are always split)
_MEDIAN_DEPTH = 48      # from this depth on, split by index halves (bounds the depth)
_EMPTY_MIN = np.float32(np.inf)
_EMPTY_MAX = np.float32(-np.inf)

__all__ = ["BVH", "build_bvh", "sah_cost", "validate", "MAX_DEPTH", "MAX_SAH_LEAF"]


@dataclass
class BVH:
    nodes: np.ndarray        # abi.BVH_NODE records, node 0 = root
    triangles: np.ndarray    # abi.TRIANGLE, reordered so that every leaf is a contiguous range
    prim_ids: np.ndarray     # int32 (T,): original face index of each reordered triangle
    vertices: np.ndarray     # float32 (V, 3) as given
    faces: np.ndarray        # int32 (F, 3) as given
    stats: dict = field(default_factory=dict)

    @property
    def bounds(self) -> np.ndarray:
        """(2, 3) float32 scene box (min row, max row); +inf/-inf for an empty mesh."""
        n = self.nodes[0]
        lo = np.minimum(n["bmin_left"], n["bmin_right"])
        hi = np.maximum(n["bmax_left"], n["bmax_right"])
        return np.stack([lo, hi]).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# helpers
# ---------------------------------------------------------------------------------------------
def _area(lo, hi):
    """Surface area of boxes given as (3, ...) min and max arrays; empty boxes have area 0."""
    d = np.maximum(np.asarray(hi, np.float64) - np.asarray(lo, np.float64), 0.0)
    d = np.nan_to_num(d, nan=0.0, posinf=0.0, neginf=0.0) if not np.all(np.isfinite(d)) else d
    return 2.0 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])


def _prepare(vertices, faces):
    V = np.ascontiguousarray(np.asarray(vertices, dtype=np.float32).reshape(-1, 3))
    F = np.ascontiguousarray(np.asarray(faces).reshape(-1, 3))
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise UsageError("faces index outside the vertex array")
    F = F.astype(np.int32, copy=False)
    if not np.all(np.isfinite(V)):
        raise UsageError("vertices must be finite (in float32)")
    return V, F


class _Tree:
    """Tree nodes as parallel arrays, filled level by level (ids are in BFS order)."""

    def __init__(self, T):
        M = max(2 * T, 1)
        self.box = np.empty((M, 6), np.float32)     # lo xyz, hi xyz
        self.leaf = np.zeros(M, bool)
        self.cnt = np.zeros(M, np.int64)
        self.off = np.zeros(M, np.int64)
        self.left = np.full(M, -1, np.int64)
        self.right = np.full(M, -1, np.int64)
        self.depth = np.zeros(M, np.int64)
        self.n = 0

    def add(self, box, cnt, off, depth, leaf):
        k = len(cnt)
        ids = np.arange(self.n, self.n + k)
        self.box[ids] = box
        self.cnt[ids] = cnt
        self.off[ids] = off
        self.depth[ids] = depth
        self.leaf[ids] = leaf
        self.n += k
        return ids


def _decide(cnt, node_area, best, depth, max_leaf_size, ct, ci):
    """Per-node choice: 0 = SAH split, 1 = leaf, 2 = index-halves split.

    ``best`` is the best sum area(child)*count(child) (inf where no split separates anything).
    """
    valid = np.isfinite(best)
    with np.errstate(divide="ignore", invalid="ignore"):
        split_cost = ct + ci * np.where(node_area > 0, best / np.where(node_area > 0, node_area, 1.0),
                                        cnt.astype(np.float64))
    leaf_cost = ci * cnt
    small = cnt <= max(MAX_SAH_LEAF, max_leaf_size)
    leaf = small & (~valid | (split_cost >= leaf_cost)) | (depth >= MAX_DEPTH) | (cnt <= max_leaf_size)
    decision = np.zeros(len(cnt), np.int8)
    decision[leaf] = 1
    decision[~leaf & (~valid | (depth >= _MEDIAN_DEPTH))] = 2
    return decision


def _partition(seg, start, cnt, goleft):
    """Stable two-way partition inside each segment.  Returns (rank within child, nleft)."""
    n = len(goleft)
    cf = np.cumsum(goleft, dtype=np.intp)
    excl = cf - goleft
    ends = np.append(excl, cf[-1] if n else 0)
    base = ends[start]
    nl = ends[start + cnt] - base
    rl = excl - base[seg]
    local = np.arange(n, dtype=np.intp) - start[seg]
    rank = np.where(goleft, rl, local - rl)
    return rank, nl


def _exact_boxes(key, nkeys, lo, hi, sel=None):
    """Exact (nkeys, 6) boxes of the elements grouped by key (optionally a subset sel)."""
    out = np.empty((6, nkeys), np.float32)
    out[:3] = np.inf
    out[3:] = -np.inf
    if sel is not None:
        key = key[sel]
    for d in range(3):
        np.minimum.at(out[d], key, lo[d] if sel is None else lo[d][sel])
        np.maximum.at(out[3 + d], key, hi[d] if sel is None else hi[d][sel])
    return out.T


# ---------------------------------------------------------------------------------------------
# shared level step: turn decisions into children, write finished leaves, compact the rest
# ---------------------------------------------------------------------------------------------
def _advance(tree, ids, off, cnt, nl, decision, depth, child_box, max_leaf_size):
    """Apply one level of decisions to the tree.

    ids/off/cnt/nl: per active node (nl = elements flagged left; all of them for a node that
    becomes a leaf).  child_box: (2K, 6) boxes of the left/right children (rows of leaf-decided
    nodes unused).  Returns (slot_base, slot_out, next-level node arrays), where slot 2k / 2k+1 is
    the left / right part of node k: an element of slot s with rank r inside it goes to
    ``order[slot_base[s] + r]`` if ``slot_out[s]`` (a finished leaf), else to position
    ``slot_base[s] + r`` of the next level's arrays.
    """
    K = len(cnt)
    is_leaf = decision == 1
    tree.leaf[ids[is_leaf]] = True
    s_idx = np.flatnonzero(~is_leaf)
    ccnt = np.empty((len(s_idx), 2), np.int64)
    ccnt[:, 0] = nl[s_idx]
    ccnt[:, 1] = cnt[s_idx] - nl[s_idx]
    coff = np.empty_like(ccnt)
    coff[:, 0] = off[s_idx]
    coff[:, 1] = off[s_idx] + nl[s_idx]
    cbox = child_box.reshape(K, 2, 6)[s_idx]
    cleaf = (ccnt <= max_leaf_size) | (depth + 1 >= MAX_DEPTH)
    cids = tree.add(cbox.reshape(-1, 6), ccnt.ravel(), coff.ravel(), depth + 1, cleaf.ravel())
    cids = cids.reshape(-1, 2)
    tree.left[ids[s_idx]] = cids[:, 0]
    tree.right[ids[s_idx]] = cids[:, 1]
    slot_out = np.zeros((K, 2), bool)
    slot_base = np.zeros((K, 2), np.intp)
    slot_out[is_leaf, 0] = True
    slot_base[is_leaf, 0] = off[is_leaf]
    slot_out[s_idx] = cleaf
    active_c = ~cleaf                      # (S, 2)
    nxt_cnt = ccnt[active_c].astype(np.intp)
    nxt_start = np.concatenate([[0], np.cumsum(nxt_cnt)[:-1]]).astype(np.intp)
    base_s = np.where(cleaf, coff, 0)
    base_s[active_c] = nxt_start
    slot_base[s_idx] = base_s
    nxt = dict(ids=cids[active_c], off=coff[active_c], cnt=nxt_cnt, start=nxt_start,
               box=cbox[active_c])
    return slot_base.ravel(), slot_out.ravel(), nxt


def _route(seg, start, cnt, goleft, slot_base, slot_out):
    """Destinations of the elements of one (node-grouped) array after a level step."""
    rank, nl = _partition(seg, start, cnt, goleft)
    slot = 2 * seg + (~goleft)
    return slot_base[slot] + rank, slot_out[slot]


def _compact(dest, out_m, n_next, arrays_1d, arrays_2d):
    keep = np.flatnonzero(~out_m)
    src = np.empty(n_next, np.intp)
    src[dest[keep]] = keep
    return [a[src] for a in arrays_1d], [np.take(a, src, axis=1) for a in arrays_2d]


# ---------------------------------------------------------------------------------------------
# full-sweep SAH
# ---------------------------------------------------------------------------------------------
def _to_records(tree, T):
    if T == 0:
        rec = np.zeros(1, abi.BVH_NODE)
        for s in ("left", "right"):
            rec[f"bmin_{s}"] = _EMPTY_MIN
            rec[f"bmax_{s}"] = _EMPTY_MAX
            rec[f"child_{s}"] = 0
            rec[f"count_{s}"] = -1
        return rec
    n = tree.n
    leaf = tree.leaf[:n]
    if leaf[0]:
        rec = np.zeros(1, abi.BVH_NODE)
        rec["bmin_left"] = tree.box[0, :3]
        rec["bmax_left"] = tree.box[0, 3:]
        rec["child_left"] = tree.off[0]
        rec["count_left"] = tree.cnt[0]
        rec["bmin_right"] = _EMPTY_MIN
        rec["bmax_right"] = _EMPTY_MAX
        rec["child_right"] = 0
        rec["count_right"] = -1
        return rec
    inner = np.flatnonzero(~leaf)
    rec_of = np.full(n, -1, np.int64)
    rec_of[inner] = np.arange(len(inner))
    rec = np.zeros(len(inner), abi.BVH_NODE)
    for s, ch in (("left", tree.left[inner]), ("right", tree.right[inner])):
        rec[f"bmin_{s}"] = tree.box[ch, :3]
        rec[f"bmax_{s}"] = tree.box[ch, 3:]
        is_leaf = leaf[ch]
        rec[f"child_{s}"] = np.where(is_leaf, tree.off[ch], rec_of[ch])
        rec[f"count_{s}"] = np.where(is_leaf, tree.cnt[ch], 0)
    return rec


def _record_walk(nodes):
    """BFS over records: (record depth array, list of leaf (first, count, box_lo, box_hi, depth))."""
    R = len(nodes)
    rdepth = np.full(R, -1, np.int64)
    visits = np.zeros(R, np.int64)
    frontier = np.array([0])
    visits[0] = 1
    rdepth[0] = 0
    d = 0
    leaves = []
    while len(frontier):
        nxt = []
        for s in ("left", "right"):
            c = nodes[f"count_{s}"][frontier]
            ch = nodes[f"child_{s}"][frontier]
            inner = c == 0
            if np.any(c < -1):
                raise ValueError(f"record has count < -1 on the {s}")
            kids = ch[inner]
            if len(kids) and (kids.min() < 0 or kids.max() >= R):
                raise ValueError("inner child index out of range")
            nxt.append(kids)
            lm = c > 0
            leaves.append((ch[lm], c[lm], nodes[f"bmin_{s}"][frontier[lm]],
                           nodes[f"bmax_{s}"][frontier[lm]], np.full(lm.sum(), d + 1)))
        frontier = np.concatenate(nxt)
        if len(frontier):
            np.add.at(visits, frontier, 1)
            if np.any(visits[frontier] > 1):
                raise ValueError("a record is reachable more than once (not a tree)")
            rdepth[frontier] = d + 1
        d += 1
        if d > 10 * (R + 2):
            raise ValueError("cycle in the BVH")
    cat = [np.concatenate([l[i] for l in leaves]) for i in range(5)]
    return rdepth, visits, cat


def _record_boxes(nodes):
    lo = np.minimum(nodes["bmin_left"], nodes["bmin_right"])
    hi = np.maximum(nodes["bmax_left"], nodes["bmax_right"])
    return lo, hi


# ---------------------------------------------------------------------------------------------
# public API
# ---------------------------------------------------------------------------------------------
def sah_cost(bvh, traversal_cost=1.0, intersection_cost=1.0) -> float:
    """SAH cost of a finished BVH (see the module docstring for the formula)."""
    nodes = bvh.nodes
    rlo, rhi = _record_boxes(nodes)
    root_area = float(_area(rlo[0], rhi[0]))
    if not np.isfinite(rlo[0]).all():      # empty mesh
        return 0.0
    rec_area = _area(rlo.T, rhi.T)
    total = traversal_cost * rec_area.sum()
    leaf_sum = 0.0
    for s in ("left", "right"):
        c = nodes[f"count_{s}"]
        m = c > 0
        leaf_sum += float((_area(nodes[f"bmin_{s}"][m].T, nodes[f"bmax_{s}"][m].T) * c[m]).sum())
    total += intersection_cost * leaf_sum
    if root_area > 0:
        return float(total / root_area)
    # degenerate scene (a point or a segment): every box has area 0; count each term once
    n_leaf_tris = sum(int(nodes[f"count_{s}"][nodes[f"count_{s}"] > 0].sum()) for s in ("left", "right"))
    return float(traversal_cost * len(nodes) + intersection_cost * n_leaf_tris)


def _one_leaf(V, F):
    """The tree of a mesh (T >= 1) kept in one leaf, as _to_records reads it."""
    tv = V[F].reshape(-1, 3)
    box = np.concatenate([tv.min(axis=0), tv.max(axis=0)])[None]
    return SimpleNamespace(n=1, leaf=np.array([True]), box=box, off=np.array([0]), cnt=np.array([len(F)]),
                           left=np.array([-1]), right=np.array([-1]))


def _leaf_stats(nodes):
    _, _, (first, count, blo, bhi, ldepth) = _record_walk(nodes)
    if len(nodes) == 1 and nodes["count_right"][0] == -1:
        ldepth = np.zeros_like(ldepth)     # the whole mesh is one leaf: depth 0
    return first, count, ldepth


def build_bvh(vertices, faces, *, method="binned", max_leaf_size=4, bins=16,
              traversal_cost=1.0, intersection_cost=1.0, threads=None) -> BVH:
    """Build a BVH over triangles ``vertices[faces]`` (see the module docstring).  ``threads``:
    how many threads the binned builder uses (default: the CPUs this process may run on); the
    tree does not depend on it."""
    t0 = time.perf_counter()
    if max_leaf_size < 1:
        raise ValueError("max_leaf_size must be >= 1")
    if method not in ("binned", "sweep"):
        raise ValueError(f"unknown method {method!r} (binned or sweep)")
    if int(bins) < 2:
        raise ValueError("bins must be >= 2")
    V, F = _prepare(vertices, faces)
    T = len(F)
    tris = np.zeros(T, abi.TRIANGLE)
    if method == "binned" and T > max_leaf_size:
        from .bvh_binned import build

        nodes, order, tris12, count, depth, sah = build(V, F, max_leaf_size, bins, traversal_cost,
                                                        intersection_cost, MAX_DEPTH, _MEDIAN_DEPTH, MAX_SAH_LEAF,
                                                        threads=threads)
        tris = tris12.view(abi.TRIANGLE).reshape(T)
        if nodes is None:       # the SAH kept the whole mesh in one leaf
            nodes = _to_records(_one_leaf(V, F), T)
    else:
        tv = V[F]                                              # (T, 3, 3)
        if method == "sweep":
            from .bvh_sweep import _build_sweep

            lo = np.ascontiguousarray(tv.min(axis=1).T)            # (3, T)
            hi = np.ascontiguousarray(tv.max(axis=1).T)
            tree, order = _build_sweep(lo, hi, max_leaf_size, traversal_cost, intersection_cost)
        else:                   # binned, at most one leaf's worth of triangles: nothing to compile
            tree, order = (_one_leaf(V, F) if T else None), np.arange(T)
        nodes = _to_records(tree, T)
        tv_r = tv[order]
        for i in range(3):
            tris[f"v{i}"][:, :3] = tv_r[:, i]
        count, depth, sah = np.zeros(0, np.int64), 0, None
        if T:
            _, count, ldepth = _leaf_stats(nodes)
            depth = int(ldepth.max())
    build_seconds = time.perf_counter() - t0
    prim_ids = aligned_empty(len(order), np.int32)  # read in place by a CPU device (device/host_memory.py)
    prim_ids[:] = order
    bvh = BVH(nodes=nodes, triangles=tris, prim_ids=prim_ids, vertices=V, faces=F)
    freq = np.bincount(count)
    bvh.stats = dict(
        method=method,
        triangles=T,
        sah_cost=sah if sah is not None else sah_cost(bvh, traversal_cost, intersection_cost),
        node_count=len(nodes),
        inner_nodes=len(nodes),
        leaves=int(len(count)),
        depth=depth,
        leaf_size_histogram={int(s): int(f) for s, f in zip(np.flatnonzero(freq), freq[freq > 0])},
        build_seconds=build_seconds,
    )
    return bvh
