"""BVH construction on the host (numpy only).

Two top-down surface-area-heuristic (SAH) builders produce the same output, a binary BVH stored
in the Aila & Laine layout of :data:`pyopencl_rt.abi.BVH_NODE` (each record holds both
children's boxes):

``method="binned"``
    Binned SAH over all three axes, **level-synchronous**: every node of a tree level is handled
    by the same few whole-array numpy calls (``np.bincount`` for bin counts, the numpy-2 fast
    ``np.minimum.at`` / ``np.maximum.at`` for per-(node, axis, bin) bounds, stored bin-major
    ``(axis, bin, node)`` so the prefix/suffix sweeps are ``bins`` vector ops over all nodes, and
    a stable partition by ``cumsum`` of the side flags).  Nodes holding more than ``_SAMPLE`` triangles (only the top few levels)
    evaluate the SAH on an evenly strided sample of ``_SAMPLE`` of their triangles; the split
    itself and the child boxes always use every triangle.  ``bins`` is the number of bins per
    axis while nodes are big; on levels whose mean node size is small it drops to the power of
    two below that mean (at least ``_MIN_BINS``), so the per-node SAH work stays below the
    per-triangle work.  Child boxes come exactly from the bins (float32 min/max, no arithmetic).

    Speed (2-core machine): ~0.6 s for 100k triangles, ~7.5-10 s for 1M; the 2 s / 1M goal is
    not met.  Most of the time is ~60 whole-array passes per level (binning keys, 18 ``ufunc.at``
    passes, partition, compaction) times ~20 levels.  A Morton-sorted, fixed-order variant
    (splits only at octree-cell boundaries of the Morton order, SAH-chosen, reduceat boxes, no
    partition) was tried: ~4 s for 1M but 8-15% worse SAH than the sweep, so it was dropped.

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

import numpy as np

from ..device import abi

MAX_DEPTH = 60          # deepest leaf (root = 0); one traversal stack entry per level
assert MAX_DEPTH + 1 <= abi.BVH_STACK_SIZE
MAX_SAH_LEAF = 64       # largest leaf the SAH may choose (bigger nodes are always split)
_MEDIAN_DEPTH = 48      # from this depth on, split by index halves (bounds the depth)
_SAMPLE = 4096          # binned: nodes with more triangles evaluate the SAH on this many samples
_ALL_AXES_MEAN = 0    # binned: levels whose mean node size is below this bin only the longest axis (0 = never;
                      # 48 is ~30% faster but up to 9% worse SAH on slivers)
_MIN_BINS = 4         # binned: fewest bins per axis on levels of small nodes
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


def _area32(lo, hi):
    """Float32 surface area of (3, ...) boxes; empty boxes (inf, -inf) give 0."""
    d = np.maximum(hi - lo, np.float32(0))
    return 2 * (d[0] * d[1] + d[1] * d[2] + d[2] * d[0])


def _prepare(vertices, faces):
    V = np.ascontiguousarray(np.asarray(vertices, dtype=np.float32).reshape(-1, 3))
    F = np.ascontiguousarray(np.asarray(faces).reshape(-1, 3))
    if F.size and (F.min() < 0 or F.max() >= len(V)):
        raise ValueError("faces index outside the vertex array")
    F = F.astype(np.int32, copy=False)
    if not np.all(np.isfinite(V)):
        raise ValueError("vertices must be finite")
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
# binned SAH
# ---------------------------------------------------------------------------------------------
def _build_binned(lo0, hi0, max_leaf_size, bins, ct, ci):
    T = lo0.shape[1]
    B = int(bins)
    if B < 2:
        raise ValueError("bins must be >= 2")
    tree = _Tree(T)
    order = np.empty(T, np.int64)
    root_box = np.concatenate([lo0.min(axis=1, initial=np.inf), hi0.max(axis=1, initial=-np.inf)])[None]
    root_leaf = T <= max_leaf_size
    tree.add(root_box, np.array([T]), np.array([0]), 0, np.array([root_leaf]))
    if root_leaf:
        order[:] = np.arange(T)
        return tree, order
    idx = np.arange(T, dtype=np.intp)
    lo, hi = lo0, hi0
    node = dict(ids=np.array([0]), off=np.array([0], np.intp), cnt=np.array([T], np.intp),
                start=np.array([0], np.intp), box=root_box)
    depth = 0
    while len(node["cnt"]):
        cnt, start, box = node["cnt"], node["start"], node["box"]
        K, n = len(cnt), len(idx)
        seg = np.repeat(np.arange(K, dtype=np.intp), cnt)
        # binning range: the centroid bounds, in "2 x centroid" space (c = lo + hi)
        c3 = lo + hi
        cmin = np.minimum.reduceat(c3, start, axis=1)   # (3, K)
        cmax = np.maximum.reduceat(c3, start, axis=1)
        ext = (cmax - cmin).astype(np.float64)
        with np.errstate(divide="ignore", over="ignore"):
            scale64 = np.where(ext > 0, B / np.where(ext > 0, ext, 1.0), 0.0)
        scale64[scale64 > 3e38] = 0.0
        scale = scale64.astype(np.float32)             # (3, K); 0 = degenerate axis
        # sampling for big nodes (only the top levels)
        sampled = cnt > _SAMPLE
        if sampled.any():
            m = np.minimum(cnt, _SAMPLE)
            eseg = np.repeat(np.arange(K, dtype=np.intp), m)
            j = np.arange(len(eseg), dtype=np.intp) - np.repeat(np.cumsum(m) - m, m)
            epos = start[eseg] + (j * cnt[eseg]) // m[eseg]
            elo, ehi, ec = lo[:, epos], hi[:, epos], c3[:, epos]
        else:
            m = cnt
            eseg, elo, ehi, ec = seg, lo, hi, c3
        # bins per level: all three axes while nodes are big, the longest centroid axis and
        # fewer bins once they are small (keeps the per-node SAH work below the per-triangle work)
        mean = n / K
        kk = np.arange(K)
        Bl = int(min(B, max(_MIN_BINS, 2 ** int(np.log2(max(mean, 1.0))))))
        if mean >= _ALL_AXES_MEAN:
            A = 3
            ax_tab = np.broadcast_to(np.arange(3), (K, 3))
        else:
            A = 1
            ax_tab = np.argmax(ext, axis=0)[:, None]
        sc_l = (scale * (Bl / B)).astype(np.float32)   # same rounding in the split step below
        nkey = K * A * Bl
        sampled_any = bool(sampled.any())
        if not sampled_any:
            binarr = np.empty((A, n), np.int16)
        counts = np.zeros(nkey, np.float64)
        bmin = np.full((3, nkey), np.inf, np.float32)
        bmax = np.full((3, nkey), -np.inf, np.float32)
        for p in range(A):
            if A == 3:
                b = ec[p] - cmin[p][eseg]
                b *= sc_l[p][eseg]
            else:
                axn = ax_tab[:, 0]
                b = np.take_along_axis(ec, axn[eseg][None], axis=0)[0]
                b -= cmin[axn, kk][eseg]
                b *= sc_l[axn, kk][eseg]
            np.minimum(b, Bl - 1, out=b)
            bint = b.astype(np.intp)
            if not sampled_any:
                binarr[p] = bint
            key = (p * Bl) * K + bint * K + eseg        # bin-major: (A, Bl, K)
            counts += np.bincount(key, minlength=nkey)
            for d in range(3):
                np.minimum.at(bmin[d], key, elo[d])
                np.maximum.at(bmax[d], key, ehi[d])
        counts = counts.reshape(A, Bl, K)
        bmin = bmin.reshape(3, A, Bl, K)
        bmax = bmax.reshape(3, A, Bl, K)
        # prefix / suffix boxes over the bins (bin axis outermost: each step is one vector op)
        pmin, pmax, smin, smax = bmin.copy(), bmax.copy(), bmin.copy(), bmax.copy()
        for j in range(1, Bl):
            np.minimum(pmin[:, :, j - 1], pmin[:, :, j], out=pmin[:, :, j])
            np.maximum(pmax[:, :, j - 1], pmax[:, :, j], out=pmax[:, :, j])
            np.minimum(smin[:, :, Bl - j], smin[:, :, Bl - 1 - j], out=smin[:, :, Bl - 1 - j])
            np.maximum(smax[:, :, Bl - j], smax[:, :, Bl - 1 - j], out=smax[:, :, Bl - 1 - j])
        nl = np.cumsum(counts, axis=1)[:, :-1]
        nr = nl[:, -1:] + counts[:, -1:] - nl
        w = (cnt / m).astype(np.float32)                  # sample -> node count
        cost = _area32(pmin[:, :, :-1], pmax[:, :, :-1]) * nl.astype(np.float32)
        cost += _area32(smin[:, :, 1:], smax[:, :, 1:]) * nr.astype(np.float32)
        cost *= w
        cost[(nl == 0) | (nr == 0)] = np.inf
        degen = (sc_l[ax_tab, kk[:, None]] == 0).T[:, None, :]   # degenerate axis: nothing to split
        cost[np.broadcast_to(degen, cost.shape)] = np.inf
        flat = cost.reshape(A * (Bl - 1), K)
        bi = np.argmin(flat, axis=0)
        best = flat[bi, kk].astype(np.float64)
        bslot, bbin = bi // (Bl - 1), bi % (Bl - 1)
        bax = ax_tab[kk, bslot]
        node_area = _area(box[:, :3].T, box[:, 3:].T)
        decision = _decide(cnt, node_area, best, depth, max_leaf_size, ct, ci)

        # side of every triangle: recompute its bin on the chosen axis exactly as above
        dn = decision[seg]
        if not sampled_any:
            bsel = binarr[0] if A == 1 else np.take_along_axis(binarr, bax[seg][None], axis=0)[0]
            goleft = bsel <= bbin[seg]
        else:
            b = np.take_along_axis(c3, bax[seg][None], axis=0)[0]
            b -= cmin[bax, kk][seg]
            b *= sc_l[bax, kk][seg]
            np.minimum(b, Bl - 1, out=b)
            goleft = b.astype(np.intp) <= bbin[seg]
        med = decision == 2
        if med.any():
            local = np.arange(n, dtype=np.intp) - start[seg]
            goleft = np.where(dn == 2, local < (cnt // 2)[seg], goleft)
        goleft |= dn == 1
        # child boxes: exact from the bins for full-data SAH splits, else recomputed
        child_box = np.empty((K, 2, 6), np.float32)
        child_box[:, 0, :3] = pmin[:, bslot, bbin, kk].T
        child_box[:, 0, 3:] = pmax[:, bslot, bbin, kk].T
        child_box[:, 1, :3] = smin[:, bslot, bbin + 1, kk].T
        child_box[:, 1, 3:] = smax[:, bslot, bbin + 1, kk].T
        redo = (decision == 2) | ((decision == 0) & sampled)
        if redo.any():
            sel = np.flatnonzero(redo[seg])
            slot = 2 * seg[sel] + (~goleft[sel])
            rows = np.flatnonzero(np.repeat(redo, 2))
            bx = _exact_boxes(slot, 2 * K, lo[:, sel], hi[:, sel])
            child_box.reshape(2 * K, 6)[rows] = bx[rows]
        rank, nl = _partition(seg, start, cnt, goleft)
        slot_base, slot_out, nxt = _advance(tree, node["ids"], node["off"], cnt, nl, decision, depth,
                                            child_box.reshape(2 * K, 6), max_leaf_size)
        slot = 2 * seg + (~goleft)
        dest, out_m = slot_base[slot] + rank, slot_out[slot]
        order[dest[out_m]] = idx[out_m]
        n_next = int(nxt["cnt"].sum())
        (idx,), (lo, hi) = _compact(dest, out_m, n_next, [idx], [lo, hi])
        node = nxt
        depth += 1
    return tree, order


# ---------------------------------------------------------------------------------------------
# full-sweep SAH
# ---------------------------------------------------------------------------------------------
def _to_records(tree, T):
    n = tree.n
    leaf = tree.leaf[:n]
    if T == 0:
        rec = np.zeros(1, abi.BVH_NODE)
        for s in ("left", "right"):
            rec[f"bmin_{s}"] = _EMPTY_MIN
            rec[f"bmax_{s}"] = _EMPTY_MAX
            rec[f"child_{s}"] = 0
            rec[f"count_{s}"] = -1
        return rec
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


def _leaf_stats(nodes):
    _, _, (first, count, blo, bhi, ldepth) = _record_walk(nodes)
    if len(nodes) == 1 and nodes["count_right"][0] == -1:
        ldepth = np.zeros_like(ldepth)     # the whole mesh is one leaf: depth 0
    return first, count, ldepth


def build_bvh(vertices, faces, *, method="binned", max_leaf_size=4, bins=16,
              traversal_cost=1.0, intersection_cost=1.0) -> BVH:
    """Build a BVH over triangles ``vertices[faces]`` (see the module docstring)."""
    t0 = time.perf_counter()
    if max_leaf_size < 1:
        raise ValueError("max_leaf_size must be >= 1")
    V, F = _prepare(vertices, faces)
    T = len(F)
    tv = V[F]                                              # (T, 3, 3)
    lo = np.ascontiguousarray(tv.min(axis=1).T)            # (3, T)
    hi = np.ascontiguousarray(tv.max(axis=1).T)
    if method == "binned":
        tree, order = _build_binned(lo, hi, max_leaf_size, bins, traversal_cost, intersection_cost)
    elif method == "sweep":
        from .bvh_sweep import _build_sweep

        tree, order = _build_sweep(lo, hi, max_leaf_size, traversal_cost, intersection_cost)
    else:
        raise ValueError(f"unknown method {method!r} (binned or sweep)")
    nodes = _to_records(tree, T)
    tris = np.zeros(T, abi.TRIANGLE)
    tv_r = tv[order]
    for i in range(3):
        tris[f"v{i}"][:, :3] = tv_r[:, i]
    build_seconds = time.perf_counter() - t0
    bvh = BVH(nodes=nodes, triangles=tris, prim_ids=order.astype(np.int32), vertices=V, faces=F)
    first, count, ldepth = _leaf_stats(nodes) if T else (np.zeros(0), np.zeros(0, np.int64), np.zeros(1))
    sizes, freq = np.unique(count, return_counts=True)
    bvh.stats = dict(
        method=method,
        triangles=T,
        sah_cost=sah_cost(bvh, traversal_cost, intersection_cost),
        node_count=len(nodes),
        inner_nodes=len(nodes),
        leaves=int(len(count)),
        depth=int(ldepth.max()) if len(ldepth) else 0,
        leaf_size_histogram={int(s): int(f) for s, f in zip(sizes, freq)},
        build_seconds=build_seconds,
    )
    return bvh
