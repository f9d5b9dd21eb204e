"""4-wide and 8-wide BVHs for CPU devices, collapsed from the binary BVH (compiled with numba).

PoCL runs each work-item as scalar code, so the binary traversal tests one box pair and one
triangle at a time.  This layout gives a single work-item SIMD-shaped work, as Embree's
single-ray kernels do: every node holds the boxes of up to four children in structure-of-arrays
form (one float4 slab test for all four), and leaves hold triangles in packets of four ("Tri4",
structure of arrays: one float4 watertight test for four triangles).  cl/accel/bvh_wide.h traverses it.

The 8-wide layout (``width=8``: :data:`abi.WIDE8_NODE`, :data:`abi.TRI8`, traversed by
cl/accel/bvh_wide8.h) is the same with eight lanes (float8: one AVX2 register), addressed in float8
(32-byte) units, so a node is again 8 units and a Tri8 packet 10.  As a Tri8 test costs about what
a Tri4 test does, any binary subtree of at most ``merge`` (8) triangles becomes one leaf: its
triangles are a contiguous range of the reordered array, so the leaf is that range (its box, the
union of the subtree's exact boxes, is their exact bounds), and the tree gets shallower.

Buffer layout
-------------
The device gets one buffer (the "blob"): every node (:data:`abi.WIDE_NODE`, 128 bytes), then
every packet (:data:`abi.TRI4`, 160 bytes), addressed in float4 (16-byte) units, so a node is 8
units and a packet 10.  For child slot ``i`` of a node:

    count[i] == 0    inner node at float4 offset child[i] (8 * node index)
    count[i] >  0    leaf: ``count[i]`` consecutive packets, the first at float4 offset child[i]
    count[i] == -1   no child: box min = +inf, max = -inf (misses every ray), child = 0

A packet holds triangles ``tri[k]`` (indices into the binary BVH's reordered triangle array, so
``prim_ids[tri]`` is the caller's face and cl/accel/bvh.h's ``triangle_normal(tris, tri)`` still
applies) with vertex coordinates v0x..v2z.  Padding lanes (a leaf of n triangles has
``4 * ceil(n / 4) - n`` of them, all in its last packet) have ``tri = -1`` and NaN vertices: every
comparison in the triangle test is false for NaN, so the test's "det != 0", written as
``det < 0 || det > 0``, rejects them whatever the ray (so would ``t > tmin && t < tmax``), and
U = V = W = NaN never takes the double-precision path, which only an exact 0 does.

Collapse
--------
Top-down and breadth first (one compiled pass over a queue of wide nodes): a wide node
starts as a binary record's two children; ``width - 2`` times, an inner child is replaced by its
own two children, the one of largest surface area (as Embree's and tinybvh's collapses do) among
the shallowest ones, giving up to ``width`` children.  "Shallowest first" makes every wide level
descend log2(width) binary levels (all inner children of the first log2(width) - 1 levels are
opened before any deeper one), so the wide depth is at most half (a third) of the binary depth
(:func:`max_wide_depth`: 30, 20), and the traversal stack (at most ``width - 1`` entries pushed per
level) is bounded by :data:`abi.WIDE_STACK_SIZE` (96 entries of 8 bytes) or
:data:`abi.WIDE8_STACK_SIZE` (144): PoCL keeps a private copy per work-item of a work-group, so
the stack must stay small.  Binary leaves (and merged subtrees) become wide leaves unchanged
(their triangles in ceil(n / packet width) packets), so every box is the binary BVH's exact box
(or the union of exact boxes) and the triangle order is the binary BVH's.

The device copy (:func:`device_blob`) pads every present box by 2^-20 of the scene's largest
coordinate, as :func:`pyopencl_rt.accel.device_bvh.padded_nodes` does for the binary layout (see
"Conservative on purpose" in cl/accel/intersect.h).
"""
from __future__ import annotations

import time
from dataclasses import dataclass, field

import numpy as np
from numba import njit, prange

from ..device import abi
from ..device.host_memory import aligned_empty
from .bvh import BVH, MAX_DEPTH

STACK_SIZE = abi.WIDE_STACK_SIZE               # 4-wide: >= 3 * max_wide_depth(4) + 1 (validate_wide checks)
_COORDS = ("x", "y", "z")
# per node width: node dtype, the packet dtype of each packet width, offset unit (bytes), the
# binary levels every wide level descends (log2 width), traversal stack size, leaf merge bound
_FORMATS = {
    4: dict(node=abi.WIDE_NODE, unit=16, levels=2, stack=abi.WIDE_STACK_SIZE, merge=0),
    8: dict(node=abi.WIDE8_NODE, unit=32, levels=3, stack=abi.WIDE8_STACK_SIZE, merge=8),
}
_PACKETS = {4: abi.TRI4, 8: abi.TRI8}

__all__ = ["WideBVH", "build_wide", "device_blob", "STACK_SIZE", "max_wide_depth"]


def max_wide_depth(width: int) -> int:
    """Deepest wide level: every wide level descends log2(width) binary levels, and binary records
    lie at depth <= MAX_DEPTH - 1 (their children at most MAX_DEPTH)."""
    return (MAX_DEPTH - 1) // _FORMATS[width]["levels"] + 1


@dataclass
class WideBVH:
    nodes: np.ndarray        # abi.WIDE_NODE / WIDE8_NODE, node 0 = root (child offsets in units of the blob)
    packets: np.ndarray      # abi.TRI4 / TRI8, after the nodes in the blob
    depth: int               # deepest wide level (root = 0)
    n_triangles: int
    stats: dict = field(default_factory=dict)
    width: int = 4           # children per node
    packet_width: int = 4    # triangles per packet
    storage: np.ndarray | None = None   # uint8: room for the nodes, then the packets (a view of its tail)

    @property
    def unit(self) -> int:
        """Bytes per offset unit of the blob (a float4 or a float8)."""
        return _FORMATS[self.width]["unit"]

    @property
    def node_units(self) -> int:
        return self.nodes.dtype.itemsize // self.unit

    @property
    def packet_units(self) -> int:
        return self.packets.dtype.itemsize // self.unit


def _child_arrays(nodes):
    """The binary records' 2R child slots (slot 2r = left, 2r + 1 = right of record r): box, child,
    count (binary encoding) and surface area (half of it: only its order matters)."""
    R = len(nodes)
    lo = np.empty((2 * R, 3), np.float32)
    hi = np.empty((2 * R, 3), np.float32)
    child = np.empty(2 * R, np.int32)      # int32 as in the records: the collapse's largest arrays
    count = np.empty(2 * R, np.int32)
    area = np.empty(2 * R)
    raw = np.ascontiguousarray(nodes).view(np.float32).reshape(R, 16)
    _child_slots(raw, raw.view(np.int32), lo, hi, child, count, area)
    return lo, hi, child, count, area


def _jit(parallel=False):
    """numba.njit (releasing the GIL), cached on disk where numba finds a writable place (else
    compiled in every process, as bvh_binned's kernels)."""
    def decorate(fn):
        try:
            return njit(parallel=parallel, nogil=True, cache=True)(fn)
        except RuntimeError:
            return njit(parallel=parallel, nogil=True)(fn)
    return decorate


# the binary records' raw words, per side: bmin xyz, child, bmax xyz, count
assert [abi.BVH_NODE.fields[f"{k}_{s}"][1] for s in ("left", "right") for k in ("bmin", "child", "bmax", "count")] \
    == [0, 12, 16, 28, 32, 44, 48, 60] and abi.BVH_NODE.itemsize == 64


@_jit()
def _extent(lo, hi):
    x = np.float64(hi) - np.float64(lo)
    return x if x > 0.0 and x < np.inf else 0.0


@_jit()
def _child_slots(rec_f, rec_i, lo, hi, child, count, area):
    """_child_arrays' loop; an extent that is not a positive finite number (an empty box) counts 0."""
    for r in range(rec_f.shape[0]):
        for k in range(2):
            s = 2 * r + k
            o = 8 * k
            child[s] = rec_i[r, o + 3]
            count[s] = rec_i[r, o + 7]
            for d in range(3):
                lo[s, d] = rec_f[r, o + d]
                hi[s, d] = rec_f[r, o + 4 + d]
            e0 = _extent(lo[s, 0], hi[s, 0])
            e1 = _extent(lo[s, 1], hi[s, 1])
            e2 = _extent(lo[s, 2], hi[s, 2])
            area[s] = e0 * e1 + e1 * e2 + e2 * e0


@_jit()
def _merge_small_subtrees(child, count, lo, hi, merge):
    """Turn every inner child slot whose subtree holds <= ``merge`` triangles into a leaf of the
    subtree's triangle range (in place).  A subtree's triangles are contiguous in the reordered
    array (top-down build, stable partitions), so the range is [first, first + total)."""
    R = len(child) // 2
    total = np.empty(2 * R, np.int64)
    first = np.empty(2 * R, np.int64)
    for s in range(2 * R):
        total[s] = count[s] if count[s] > 0 else 0
        first[s] = child[s] if count[s] > 0 else np.iinfo(np.int64).max
    queue = np.empty(R, np.int64)                         # records reachable from the root, breadth first
    queue[0] = 0
    tail = 1
    for q in range(R):
        if q >= tail:
            break
        for s in (2 * queue[q], 2 * queue[q] + 1):
            if count[s] == 0:
                queue[tail] = child[s]
                tail += 1
    rec_total = np.zeros(R, np.int64)
    rec_first = np.zeros(R, np.int64)
    for q in range(tail - 1, -1, -1):                     # children (later in the queue) first
        r = queue[q]
        for s in (2 * r, 2 * r + 1):
            if count[s] == 0:
                total[s] = rec_total[child[s]]
                first[s] = rec_first[child[s]]
        rec_total[r] = total[2 * r] + total[2 * r + 1]
        rec_first[r] = min(first[2 * r], first[2 * r + 1])
    for s in range(2 * R):
        if count[s] == 0 and total[s] <= merge:
            child[s] = first[s]
            count[s] = total[s]
    if rec_total[0] <= merge:                             # the whole mesh: one leaf at the root
        child[0], count[0] = rec_first[0], rec_total[0]
        child[1], count[1] = 0, -1
        for d in range(3):                                # (+inf, -inf) if absent
            lo[0, d] = min(lo[0, d], lo[1, d])
            hi[0, d] = max(hi[0, d], hi[1, d])


@_jit()
def _collapse(cchild, ccount, carea, width, max_depth):
    """The wide nodes, numbered breadth first: (n_nodes, width) binary child-slot ids (-1 empty)
    and the deepest wide level.  Each starts as a binary record's two children and, ``width - 2``
    times, opens the inner child of largest area among the shallowest ones (first on ties)."""
    R = len(cchild) // 2
    slots = np.full((max(R, 1), width), -1, np.int32)
    record = np.empty(max(R, 1), np.int32)                # binary record of each wide node
    depth = np.zeros(max(R, 1), np.int32)
    level = np.empty(width, np.int64)                     # binary levels below the wide node
    record[0] = 0
    n_nodes = 1
    head = 0
    while head < n_nodes:
        r = record[head]
        s = slots[head]
        s[0] = 2 * r if ccount[2 * r] >= 0 else -1        # absent children (0/1-leaf trees)
        s[1] = 2 * r + 1 if ccount[2 * r + 1] >= 0 else -1
        level[0] = 1
        level[1] = 1
        for n in range(2, width):
            shallowest = np.iinfo(np.int64).max
            for j in range(n):
                if s[j] >= 0 and ccount[s[j]] == 0:
                    shallowest = min(shallowest, level[j])
            pick = -1
            best = -1.0
            for j in range(n):
                if s[j] >= 0 and ccount[s[j]] == 0 and level[j] == shallowest and carea[s[j]] > best:
                    best = carea[s[j]]
                    pick = j
            if pick < 0:
                continue
            rec = cchild[s[pick]]
            s[pick] = 2 * rec
            s[n] = 2 * rec + 1
            level[pick] += 1
            level[n] = level[pick]
        for j in range(width):
            if s[j] >= 0 and ccount[s[j]] == 0:
                record[n_nodes] = cchild[s[j]]
                depth[n_nodes] = depth[head] + 1
                if depth[n_nodes] > max_depth:
                    raise AssertionError("wide BVH deeper than the binary depth bound")
                n_nodes += 1
        head += 1
    return slots[:n_nodes].copy(), depth[n_nodes - 1]  # a copy: the room for R nodes goes


@_jit()
def _leaf_layout(slots, cchild, ccount, T, packet_width, node_units, packet_units):
    """Child offsets and counts of the wide nodes (the blob's encoding) and each packet lane's
    triangle (-1 empty): the leaves' packets in triangle order (leaf ranges tile [0, T))."""
    n_nodes, width = slots.shape
    npk_at = np.zeros(T + 1, np.int32)                    # packets of the leaf starting at triangle t
    for i in range(n_nodes):
        for j in range(width):
            k = slots[i, j]
            if k >= 0 and ccount[k] > 0:
                npk_at[cchild[k]] = (ccount[k] + packet_width - 1) // packet_width
    n_packets = 0
    for t in range(T + 1):                                # exclusive prefix: the leaf's first packet
        c = npk_at[t]
        npk_at[t] = n_packets
        n_packets += c
    lane_tri = np.full((n_packets, packet_width), -1, np.int32)
    child = np.zeros((n_nodes, width), np.int64)
    count = np.full((n_nodes, width), -1, np.int64)
    inner = 0
    for i in range(n_nodes):
        for j in range(width):
            k = slots[i, j]
            if k < 0 or ccount[k] < 0:
                continue
            if ccount[k] == 0:
                inner += 1                                # node ids in the order inner slots appear
                child[i, j] = node_units * inner
                count[i, j] = 0
                continue
            first = cchild[k]
            pk = npk_at[first]
            child[i, j] = node_units * n_nodes + packet_units * pk
            count[i, j] = (ccount[k] + packet_width - 1) // packet_width
            for m in range(ccount[k]):
                lane_tri[pk + m // packet_width, m % packet_width] = first + m
    return child, count, lane_tri


@_jit(parallel=True)
def _gather_packets(V, F, prim_ids, lane_tri, raw):
    """raw[p, 3 v + c, l] = coordinate c of vertex v of reordered triangle lane_tri[p, l] (face
    prim_ids[t] of the mesh V, F: what its abi.TRIANGLE record holds), NaN where lane_tri < 0."""
    nan = np.float32(np.nan)
    for p in prange(lane_tri.shape[0]):
        for lane in range(lane_tri.shape[1]):
            t = lane_tri[p, lane]
            for v in range(3):
                for c in range(3):
                    raw[p, 3 * v + c, lane] = V[F[prim_ids[t], v], c] if t >= 0 else nan


@_jit(parallel=True)
def _node_boxes(slots, clo, chi, lx, ly, lz, hx, hy, hz):
    """The wide nodes' boxes: slot s of node i holds binary child slot slots[i, s]'s box, or
    (+inf, -inf) where it is empty (< 0)."""
    inf = np.float32(np.inf)
    for i in prange(slots.shape[0]):
        for s in range(slots.shape[1]):
            k = slots[i, s]
            if k >= 0:
                lx[i, s], ly[i, s], lz[i, s] = clo[k, 0], clo[k, 1], clo[k, 2]
                hx[i, s], hy[i, s], hz[i, s] = chi[k, 0], chi[k, 1], chi[k, 2]
            else:
                lx[i, s], ly[i, s], lz[i, s] = inf, inf, inf
                hx[i, s], hy[i, s], hz[i, s] = -inf, -inf, -inf


def build_wide(bvh: BVH, width: int = 4, packet_width: int | None = None, merge: int | None = None,
               consume: bool = False) -> WideBVH:
    """Collapse a binary BVH into a ``width``-wide BVH (4 or 8) with packets of ``packet_width``
    triangles (default: the width), binary subtrees of at most ``merge`` triangles (default: 0 for
    width 4, 8 for width 8) made single leaves (see the module docstring).  ``consume`` (a
    renderer's own BVH, whose blob is all it needs): the binary records are dropped from ``bvh``
    once read, and the nodes are made in the blob's head (``nodes`` is that view: device_blob
    pads it in place), so that neither has a second copy at the peak of a big scene's memory."""
    t0 = time.perf_counter()
    fmt = _FORMATS[width]
    packet_width = width if packet_width is None else packet_width
    merge = fmt["merge"] if merge is None else merge
    node_dtype, packet_dtype = fmt["node"], _PACKETS[packet_width]
    node_units, packet_units = node_dtype.itemsize // fmt["unit"], packet_dtype.itemsize // fmt["unit"]
    max_depth = max_wide_depth(width)
    T = len(bvh.prim_ids)
    clo, chi, cchild, ccount, carea = _child_arrays(bvh.nodes)
    if consume:
        bvh.nodes = None
    if merge > 0 and T:
        _merge_small_subtrees(cchild, ccount, clo, chi, merge)

    all_slots, depth = _collapse(cchild, ccount, carea, width, max_depth)
    del carea
    n_nodes = len(all_slots)
    child, count, lane_tri = _leaf_layout(all_slots, cchild, ccount, T, packet_width, node_units, packet_units)
    del cchild, ccount
    n_packets = len(lane_tri)
    if n_nodes * node_units + n_packets * packet_units >= 2**31:
        raise ValueError("wide BVH too large for 32-bit offsets")

    # --- node records, then the binary child arrays go (before the packets are made: the peak
    # memory of a scene of millions of triangles is here) ---------------------------------------
    head = n_nodes * node_dtype.itemsize
    storage = aligned_empty(head + n_packets * packet_dtype.itemsize, np.uint8)  # pages made as written
    if consume:
        nodes = storage[:head].view(node_dtype)
        nodes.view(np.uint8)[...] = 0
    else:
        nodes = np.zeros(n_nodes, node_dtype)
    # each slot's box, (+inf, -inf) in an empty one
    _node_boxes(all_slots, clo, chi, *(nodes[f"bmin_{c}"] for c in _COORDS),
                *(nodes[f"bmax_{c}"] for c in _COORDS))
    nodes["child"] = child
    nodes["count"] = count
    children_per_node = float((all_slots >= 0).sum() / max(n_nodes, 1))
    del clo, chi, all_slots, child, count

    # the packets live at the tail of the device blob's buffer (device_blob writes the padded nodes
    # at its head), so that the blob is no second copy of them
    packets = storage[head:].view(packet_dtype)
    raw = packets.view(np.float32).reshape(n_packets, 10, packet_width)
    # row 3 v + c of a packet: coordinate c of vertex v of each lane's triangle (NaN in empty lanes)
    # from the mesh, not the triangle records: a renderer has no more use for those here (the
    # packets hold the vertices) and may have freed them
    _gather_packets(bvh.vertices, bvh.faces, bvh.prim_ids, lane_tri, raw)
    packets["tri"] = lane_tri
    lane_fill = float((lane_tri >= 0).mean()) if n_packets else 0.0
    del lane_tri

    depth = int(depth)
    wide = WideBVH(nodes=nodes, packets=packets, depth=depth, n_triangles=T, width=width, packet_width=packet_width,
                   storage=storage)
    wide.stats = dict(
        width=width, packet_width=packet_width, merge=merge, nodes=n_nodes, packets=n_packets, depth=depth,
        lane_fill=lane_fill, children_per_node=children_per_node,
        bytes=int(nodes.nbytes + packets.nbytes),
        build_seconds=time.perf_counter() - t0,
    )
    return wide


def wide_bvh(bvh: BVH, width: int = 4) -> WideBVH:
    """The ``width``-wide BVH of ``bvh`` (default packets and merging), built once and cached on it."""
    cache = bvh.__dict__.setdefault("_wide", {})
    if width not in cache:
        cache[width] = build_wide(bvh, width)
    return cache[width]


def device_blob(wide: WideBVH) -> np.ndarray:
    """The buffer cl/accel/bvh_wide.h (bvh_wide8.h) reads: padded nodes then packets, as uint8 (the
    wide BVH's own storage, whose tail already holds the packets).

    Present boxes grow by 2^-20 of the scene's largest coordinate (then one more ulp outwards), the
    same padding as :func:`pyopencl_rt.trace.padded_nodes`; empty slots keep (+inf, -inf)."""
    head = wide.nodes.nbytes
    blob = wide.storage
    if blob is None or blob.nbytes != head + wide.packets.nbytes:
        blob = np.empty(head + wide.packets.nbytes, np.uint8)
        blob[head:] = wide.packets.view(np.uint8).ravel()
    nodes = blob[:head].view(wide.nodes.dtype)
    nodes[...] = wide.nodes
    if wide.n_triangles:
        present = nodes["count"] >= 0
        scale = 0.0
        for c in _COORDS:
            scale = max(scale, float(np.abs(nodes[f"bmin_{c}"][present]).max()),
                        float(np.abs(nodes[f"bmax_{c}"][present]).max()))
        pad = np.float32(scale * abi.BOX_PAD_RELATIVE)
        for c in _COORDS:
            lo, hi = nodes[f"bmin_{c}"], nodes[f"bmax_{c}"]
            lo[present] = np.nextafter(lo[present] - pad, np.float32(-np.inf))
            hi[present] = np.nextafter(hi[present] + pad, np.float32(np.inf))
    return blob
