"""The invariants of a wide BVH (:mod:`pyopencl_rt.accel.bvh_wide`), checked on the host, and a
float64 closest-hit walk over its nodes and packets: the tests run both on every layout they build,
as :mod:`pyopencl_rt.accel.bvh_validate` does for the binary BVH."""
from __future__ import annotations

import numpy as np

from .bvh import BVH
from .bvh_wide import _COORDS, _FORMATS, _PACKETS, WideBVH, max_wide_depth

__all__ = ["validate_wide", "reference_closest_hit"]


def _decode(wide):
    """Per node slot: kind (0 inner, 1 leaf, -1 empty), target node index or first packet, count."""
    n_nodes = len(wide.nodes)
    child, count = wide.nodes["child"].astype(np.int64), wide.nodes["count"].astype(np.int64)
    inner, leaf = count == 0, count > 0
    node_idx = np.where(inner, child // wide.node_units, -1)
    pk = np.where(leaf, (child - wide.node_units * n_nodes) // wide.packet_units, -1)
    return inner, leaf, node_idx, pk, count


def _boxes(wide):
    lo = np.stack([wide.nodes[f"bmin_{c}"] for c in _COORDS], -1)   # (N, width, 3)
    hi = np.stack([wide.nodes[f"bmax_{c}"] for c in _COORDS], -1)
    return lo, hi


def _packet_vertices(packets):
    """(P, W, 3, 3): packet, lane, vertex, coordinate."""
    return np.stack([np.stack([packets[f"v{v}{c}"] for c in _COORDS], -1) for v in range(3)], 2)


def validate_wide(wide: WideBVH, bvh: BVH | None = None) -> None:
    """Check the wide BVH's invariants; raise AssertionError with a message if one is broken.

    Tree: every node reachable exactly once from the root, child offsets decode to whole nodes or
    packets, depth <= max_wide_depth(width), (width - 1) * depth + 1 <= the kernel's stack size.
    Leaves: every triangle in exactly one lane, leaves' packet ranges disjoint and covering every packet, padding lanes only at the end of a leaf's last packet
    with tri = -1 and NaN vertices.  Boxes: empty slots are (+inf, -inf) with count -1; a leaf's
    box is exactly the float32 bounds of its triangles; an inner slot's box is exactly the union
    of its node's present children's boxes (so every box contains its subtree).  With ``bvh``:
    each lane's vertices equal ``bvh.triangles[tri]``."""
    nodes, packets = wide.nodes, wide.packets
    fmt = _FORMATS.get(wide.width)
    if fmt is None or nodes.dtype != fmt["node"] or packets.dtype != _PACKETS.get(wide.packet_width):
        raise AssertionError("wrong dtypes")
    N, P, T = len(nodes), len(packets), wide.n_triangles
    if N < 1:
        raise AssertionError("no root node")
    inner, leaf, node_idx, pk, count = _decode(wide)
    empty = count == -1
    if np.any(~(inner | leaf | empty)):
        raise AssertionError("count < -1")
    lo, hi = _boxes(wide)
    if np.any(empty & ~(np.all(lo == np.inf, -1) & np.all(hi == -np.inf, -1))):
        raise AssertionError("empty slot without an empty (+inf, -inf) box")
    if np.any((lo > hi)[~empty]):
        raise AssertionError("inverted box in a present slot")
    child = nodes["child"].astype(np.int64)
    if np.any(inner & ((child % wide.node_units != 0) | (node_idx < 1) | (node_idx >= N))):
        raise AssertionError("inner child offset is not a node (or points at the root)")
    if np.any(leaf & (((child - wide.node_units * N) % wide.packet_units != 0) | (pk < 0) | (pk + count > P))):
        raise AssertionError("leaf offset/count outside the packet array")
    # a tree: each non-root node referenced exactly once, and reachable (BFS with depth)
    refs = np.bincount(node_idx[inner], minlength=N)
    if refs[0] != 0 or np.any(refs[1:] != 1):
        raise AssertionError("a node is referenced zero or several times")
    depth = np.full(N, -1)
    depth[0] = 0
    frontier, d = np.array([0]), 0
    while len(frontier):
        kids = node_idx[frontier][inner[frontier]]
        d += 1
        if len(kids):
            if np.any(depth[kids] >= 0):
                raise AssertionError("cycle")
            depth[kids] = d
        frontier = kids
    if np.any(depth < 0):
        raise AssertionError("unreachable node")
    if (depth.max() != wide.depth or wide.depth > max_wide_depth(wide.width)
            or (wide.width - 1) * wide.depth + 1 > fmt["stack"]):
        raise AssertionError(f"depth {depth.max()} (recorded {wide.depth}) beyond the stack bound")
    # leaves: packet ranges disjoint and covering
    lf = np.flatnonzero(leaf.ravel())
    starts, cnts = pk.ravel()[lf], count.ravel()[lf]
    cover = np.zeros(P + 1, np.int64)
    np.add.at(cover, starts, 1)
    np.add.at(cover, starts + cnts, -1)
    if P and np.any(np.cumsum(cover)[:P] != 1):
        raise AssertionError("leaf packet ranges overlap or leave packets out")
    tri = packets["tri"].astype(np.int64)                          # (P, W)
    real = tri >= 0
    if T:
        if real.sum() != T or np.bincount(tri[real], minlength=T).max() != 1 or tri[real].max() >= T:
            raise AssertionError("the lanes do not hold every triangle exactly once")
    elif real.any():
        raise AssertionError("lanes hold triangles of an empty mesh")
    verts = _packet_vertices(packets)                              # (P, 4, 3, 3)
    if np.any(~np.isnan(verts[~real])):
        raise AssertionError("a padding lane has a non-NaN vertex (padding lanes must be inert)")
    if np.any(np.isnan(verts[real])):
        raise AssertionError("a triangle lane has a NaN vertex")
    # padding only at the end of a leaf's last packet
    last_of_leaf = np.zeros(P, bool)
    if len(cnts):
        last_of_leaf[starts + cnts - 1] = True
    if np.any(~real[~last_of_leaf]):
        raise AssertionError("padding lane in a packet that is not a leaf's last")
    if np.any(real[:, 1:] & ~real[:, :-1]):
        raise AssertionError("padding lane before a triangle lane")
    if bvh is not None and T:
        ref = np.stack([bvh.triangles[f"v{v}"][:, :3] for v in range(3)], 1)   # (T, 3, 3)
        if not np.array_equal(verts[real], ref[tri[real]]):
            raise AssertionError("lane vertices differ from bvh.triangles[tri]")
    # boxes: leaf boxes exact, inner boxes the exact union of their node's children
    if len(lf):
        plo = np.where(real[..., None], verts.min(2), np.inf).min(1)     # (P, 3) packet bounds
        phi = np.where(real[..., None], verts.max(2), -np.inf).max(1)
        llo = np.minimum.reduceat(plo, np.sort(starts), axis=0)
        lhi = np.maximum.reduceat(phi, np.sort(starts), axis=0)
        o = np.argsort(starts)
        blo, bhi = lo.reshape(-1, 3)[lf][o], hi.reshape(-1, 3)[lf][o]
        if not (np.array_equal(llo, blo) and np.array_equal(lhi, bhi)):
            raise AssertionError("a leaf box is not the exact bounds of its triangles")
    nlo, nhi = lo.min(1), hi.max(1)                                  # node boxes (N, 3)
    ii = np.flatnonzero(inner.ravel())
    if not (np.array_equal(lo.reshape(-1, 3)[ii], nlo[node_idx.ravel()[ii]])
            and np.array_equal(hi.reshape(-1, 3)[ii], nhi[node_idx.ravel()[ii]])):
        raise AssertionError("an inner slot's box is not the union of its node's children")
    if N > 1 and np.any((~empty[1:]).sum(1) < 2):
        raise AssertionError("a non-root node with fewer than two children")


def reference_closest_hit(wide: WideBVH, origins, directions, tmin=0.0, tmax=np.inf, rel_pad=1e-9):
    """Closest hit by walking the wide BVH in numpy, float64 throughout (no culling by the hit
    distance: every (ray, node) pair whose box is hit is expanded, level by level).

    Boxes are widened by ``rel_pad`` of the scene's largest coordinate (float64 rounding only).
    Triangles: float64 Moller-Trumbore, hit when all barycentrics >= 0.  Returns (t, tri, margin),
    t = inf and tri = -1 on a miss, margin = the smallest barycentric of the chosen hit."""
    o = np.asarray(origins, np.float64).reshape(-1, 3)
    d = np.asarray(directions, np.float64).reshape(-1, 3)
    n = len(o)
    tmin = np.broadcast_to(np.asarray(tmin, np.float64), (n,))
    tmax = np.broadcast_to(np.asarray(tmax, np.float64), (n,))
    best_t, best_tri, best_m = np.full(n, np.inf), np.full(n, -1), np.full(n, -np.inf)
    if wide.n_triangles == 0 or n == 0:
        return best_t, best_tri, best_m
    inner, leaf, node_idx, pk, count = _decode(wide)
    lo, hi = (b.astype(np.float64) for b in _boxes(wide))
    fin = np.isfinite(lo)
    pad = rel_pad * max(np.abs(lo[fin]).max(), np.abs(hi[np.isfinite(hi)]).max())
    lo, hi = lo - pad, hi + pad
    verts = _packet_vertices(wide.packets).astype(np.float64)
    tri = wide.packets["tri"]
    with np.errstate(divide="ignore", invalid="ignore", over="ignore"):
        inv = 1.0 / d
        ray, node = np.arange(n), np.zeros(n, np.int64)
        leaf_ray, leaf_pk = [], []
        while len(ray):
            t0 = (lo[node] - o[ray, None]) * inv[ray, None]            # (M, 4, 3)
            t1 = (hi[node] - o[ray, None]) * inv[ray, None]
            t0 = np.where(np.isnan(t0), -np.inf, t0)                 # 0 * inf: ray in the slab plane
            t1 = np.where(np.isnan(t1), np.inf, t1)
            enter = np.maximum(np.minimum(t0, t1).max(-1), tmin[ray, None])
            leave = np.minimum(np.maximum(t0, t1).min(-1), tmax[ray, None])
            hit = enter <= leave
            r_i, s_i = np.nonzero(hit & leaf[node])
            for k in range(int(count.max(initial=1))):
                sel = count[node[r_i], s_i] > k
                leaf_ray.append(ray[r_i[sel]])
                leaf_pk.append(pk[node[r_i[sel]], s_i[sel]] + k)
            r_i, s_i = np.nonzero(hit & inner[node])
            ray, node = ray[r_i], node_idx[node[r_i], s_i]
        lr, lp = np.concatenate(leaf_ray), np.concatenate(leaf_pk)
        for chunk in np.array_split(np.arange(len(lr)), max(1, len(lr) // 200_000)):
            r, p = lr[chunk], lp[chunk]
            v = verts[p]                                             # (M, 4, 3, 3)
            e1, e2 = v[:, :, 1] - v[:, :, 0], v[:, :, 2] - v[:, :, 0]
            dd = d[r][:, None]
            pvec = np.cross(dd, e2)
            det = np.sum(e1 * pvec, -1)
            tv = o[r][:, None] - v[:, :, 0]
            u = np.sum(tv * pvec, -1) / det
            qv = np.cross(tv, e1)
            w = np.sum(dd * qv, -1) / det
            t = np.sum(e2 * qv, -1) / det
            m = np.minimum(np.minimum(u, w), 1 - u - w)
            ok = (m >= 0) & (t > tmin[r, None]) & (t < tmax[r, None]) & (tri[p] >= 0)
            t = np.where(ok, t, np.inf)
            lane = np.argmin(t, 1)
            tt = t[np.arange(len(r)), lane]
            # per ray, the minimum over its (ray, packet) pairs
            order = np.lexsort((tt, r))
            r_s, t_s = r[order], tt[order]
            firsts = np.concatenate([[True], r_s[1:] != r_s[:-1]])
            rr, tb = r_s[firsts], t_s[firsts]
            better = tb < best_t[rr]
            src = order[firsts][better]
            best_t[rr[better]] = tb[better]
            best_tri[rr[better]] = tri[p[src], lane[src]]
            best_m[rr[better]] = m[src, lane[src]]
    return best_t, best_tri, best_m
