"""The full-sweep SAH builder behind ``build_bvh(method="sweep")``: the quality reference that the
binned builder of :mod:`pyopencl_rt.accel.bvh` is measured against.

Full-sweep SAH: every split position between centroids sorted along each of the three
axes.  Also level-synchronous: three per-axis sorted index lists are kept and partitioned
stably; the segmented prefix/suffix box scans use ``np.minimum.accumulate`` after adding a
per-segment offset (float64, normalised coordinates).  Slower; the quality reference.
"""
from __future__ import annotations

import numpy as np

from .bvh import _Tree, _advance, _area, _compact, _decide, _exact_boxes, _partition, _route


def _seg_scan(x, seg, nseg, op, reverse):
    """Segmented inclusive scan (min or max) of float64 values in [0, 1] grouped by seg."""
    if reverse:
        x, seg = x[::-1], seg[::-1]
    # restart the running min/max at each new segment by a per-segment offset of 2*seg
    if op is np.minimum:
        off = 2.0 * (seg if reverse else (nseg - 1 - seg))
    else:
        off = 2.0 * ((nseg - 1 - seg) if reverse else seg)
    r = op.accumulate(x + off) - off
    return r[::-1] if reverse else r


def _build_sweep(lo0, hi0, max_leaf_size, ct, ci):
    T = lo0.shape[1]
    tree = _Tree(T)
    order = np.empty(T, np.int64)
    root_box = np.concatenate([lo0.min(axis=1, initial=np.inf), hi0.max(axis=1, initial=-np.inf)])[None]
    root_leaf = T <= max_leaf_size
    tree.add(root_box, np.array([T]), np.array([0]), 0, np.array([root_leaf]))
    if root_leaf:
        order[:] = np.arange(T)
        return tree, order
    # normalised float64 coordinates (uniform scale keeps area ratios)
    gmin = root_box[0, :3].astype(np.float64)
    gext = float(np.max(root_box[0, 3:].astype(np.float64) - gmin))
    gext = gext if gext > 0 else 1.0
    nlo = (lo0.astype(np.float64) - gmin[:, None]) / gext
    nhi = (hi0.astype(np.float64) - gmin[:, None]) / gext
    cen = nlo + nhi
    lists = [np.argsort(cen[a], kind="stable").astype(np.intp) for a in range(3)]
    node = dict(ids=np.array([0]), off=np.array([0], np.intp), cnt=np.array([T], np.intp),
                start=np.array([0], np.intp), box=root_box)
    depth = 0
    flag_tri = np.zeros(T, bool)
    while len(node["cnt"]):
        cnt, start, box = node["cnt"], node["start"], node["box"]
        K, n = len(cnt), len(lists[0])
        seg = np.repeat(np.arange(K, dtype=np.intp), cnt)
        local = np.arange(n, dtype=np.intp) - start[seg]
        last = local == (cnt[seg] - 1)
        nl = (local + 1).astype(np.float64)
        nr = (cnt[seg] - local - 1).astype(np.float64)
        costs = np.empty((3, n))
        for a in range(3):
            L = lists[a]
            plo = np.stack([_seg_scan(nlo[d][L], seg, K, np.minimum, False) for d in range(3)])
            phi = np.stack([_seg_scan(nhi[d][L], seg, K, np.maximum, False) for d in range(3)])
            slo = np.stack([_seg_scan(nlo[d][L], seg, K, np.minimum, True) for d in range(3)])
            shi = np.stack([_seg_scan(nhi[d][L], seg, K, np.maximum, True) for d in range(3)])
            al = _area(plo, phi)
            ar = np.empty(n)
            ar[:-1] = _area(slo[:, 1:], shi[:, 1:])
            ar[-1] = 0.0
            c = al * nl + ar * nr
            c[last] = np.inf
            costs[a] = c
            if a == 0:
                node_area_n = al[start + cnt - 1]   # area of the whole node, normalised
        segmin = np.minimum.reduceat(costs, start, axis=1)   # (3, K)
        bax = np.argmin(segmin, axis=0)
        best = segmin[bax, np.arange(K)]
        decision = _decide(cnt, node_area_n, best, depth, max_leaf_size, ct, ci)
        # split position: first element of the chosen list reaching the minimum
        bpos = np.zeros(K, np.intp)
        for a in range(3):
            mk = (costs[a] == best[seg]) & (bax[seg] == a)
            hit = np.flatnonzero(mk)
            if len(hit):
                s_u, first = np.unique(seg[hit], return_index=True)
                bpos[s_u] = local[hit[first]]
        med = decision == 2
        bpos[med] = cnt[med] // 2 - 1
        # longest node axis for median splits
        ext = box[:, 3:] - box[:, :3]
        bax = np.where(med, np.argmax(ext, axis=1), bax)
        for a in range(3):
            mk = (bax[seg] == a)
            L = lists[a]
            flag_tri[L[mk]] = local[mk] <= bpos[seg[mk]]
        dn = decision[seg]
        # exact child boxes from list 0 order
        g0 = flag_tri[lists[0]] | (dn == 1)
        slot = 2 * seg + (~g0)
        child_box = _exact_boxes(slot, 2 * K, lo0[:, lists[0]], hi0[:, lists[0]])
        _, nl = _partition(seg, start, cnt, g0)
        slot_base, slot_out, nxt = _advance(tree, node["ids"], node["off"], cnt, nl, decision, depth,
                                            child_box, max_leaf_size)
        n_next = int(nxt["cnt"].sum())
        new_lists = []
        for a in range(3):
            L = lists[a]
            g = flag_tri[L] | (dn == 1)
            dest, out_m = _route(seg, start, cnt, g, slot_base, slot_out)
            if a == 0:
                order[dest[out_m]] = L[out_m]
            (Ln,), _ = _compact(dest, out_m, n_next, [L], [])
            new_lists.append(Ln)
        lists = new_lists
        node = nxt
        depth += 1
    return tree, order


# ---------------------------------------------------------------------------------------------
# records
# ---------------------------------------------------------------------------------------------
