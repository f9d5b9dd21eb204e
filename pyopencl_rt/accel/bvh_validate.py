"""Every structural invariant of a binary BVH (:mod:`pyopencl_rt.accel.bvh`), checked on the host:
the tests and the BVH benchmark run it on every tree they build."""
from __future__ import annotations

import numpy as np

from ..device import abi
from .bvh import MAX_DEPTH, _record_walk, _record_boxes


def validate(bvh) -> None:
    """Check every structural invariant; raise AssertionError/ValueError with a message if broken."""
    nodes, tris, pid = bvh.nodes, bvh.triangles, np.asarray(bvh.prim_ids)
    V, F = np.asarray(bvh.vertices, np.float32), np.asarray(bvh.faces)
    T = len(F)
    if nodes.dtype != abi.BVH_NODE:
        raise ValueError("nodes must have dtype abi.BVH_NODE")
    if tris.dtype != abi.TRIANGLE:
        raise ValueError("triangles must have dtype abi.TRIANGLE")
    if len(nodes) < 1:
        raise AssertionError("BVH has no root record")
    if len(tris) != T or len(pid) != T:
        raise AssertionError(f"{len(tris)} triangles / {len(pid)} prim_ids for {T} faces")
    if pid.dtype != np.int32:
        raise AssertionError(f"prim_ids dtype is {pid.dtype}, expected int32")
    if T:
        if pid.min() < 0 or pid.max() >= T or np.bincount(pid, minlength=T).max() != 1:
            raise AssertionError("prim_ids is not a permutation of the face indices")
        tv = np.stack([tris["v0"], tris["v1"], tris["v2"]], axis=1)   # (T, 3, 4)
        if np.any(tv[:, :, 3] != 0):
            raise AssertionError("w component of a triangle vertex is not 0")
        if not np.array_equal(tv[:, :, :3], V[F[pid]]):
            raise AssertionError("reordered triangles differ from vertices[faces[prim_ids]]")
    for s in ("left", "right"):
        c = nodes[f"count_{s}"]
        absent = c == -1
        if np.any(absent & ~(np.all(nodes[f"bmin_{s}"] == np.inf, axis=1)
                             & np.all(nodes[f"bmax_{s}"] == -np.inf, axis=1))):
            raise AssertionError(f"absent {s} child without an empty box")
        present = ~absent
        if np.any(nodes[f"bmin_{s}"][present] > nodes[f"bmax_{s}"][present]):
            raise AssertionError(f"inverted {s} child box")
    rdepth, visits, (first, count, blo, bhi, ldepth) = _record_walk(nodes)
    if np.any(visits != 1):
        raise AssertionError(f"{int(np.sum(visits == 0))} records unreachable from the root")
    # absent children only at the root of a 0/1-leaf tree
    absent_any = (nodes["count_left"] == -1) | (nodes["count_right"] == -1)
    if T == 0:
        if not (len(nodes) == 1 and nodes["count_left"][0] == -1 and nodes["count_right"][0] == -1):
            raise AssertionError("an empty mesh must give one record with two absent children")
        return
    if np.any(absent_any[1:]) or (absent_any[0] and len(nodes) != 1):
        raise AssertionError("absent child below the root or in a multi-record tree")
    if np.any(nodes["count_left"] == -1):
        raise AssertionError("absent left child")
    # leaves tile [0, T) exactly once
    o = np.argsort(first, kind="stable")
    f, c = first[o].astype(np.int64), count[o].astype(np.int64)
    if f[0] != 0 or np.any(f[1:] != f[:-1] + c[:-1]) or f[-1] + c[-1] != T:
        raise AssertionError("leaf triangle ranges do not tile [0, T) exactly once")
    depth = int(ldepth.max()) if not (len(nodes) == 1) else 0
    if depth > MAX_DEPTH:
        raise AssertionError(f"depth {depth} exceeds {MAX_DEPTH}")
    # leaf boxes are the exact bounds of their triangles
    xyz = tv[:, :, :3]
    tlo, thi = xyz.min(axis=1), xyz.max(axis=1)
    elo = np.minimum.reduceat(tlo, f, axis=0)
    ehi = np.maximum.reduceat(thi, f, axis=0)
    if not (np.array_equal(elo, blo[o]) and np.array_equal(ehi, bhi[o])):
        bad = np.flatnonzero(np.any(elo != blo[o], axis=1) | np.any(ehi != bhi[o], axis=1))
        raise AssertionError(f"{len(bad)} leaf boxes are not the exact bounds of their triangles "
                             f"(first: leaf [{f[bad[0]]}, +{c[bad[0]]}))")
    # an inner child's box is exactly its record's box (union of its children), hence contained
    rlo, rhi = _record_boxes(nodes)
    for s in ("left", "right"):
        m = nodes[f"count_{s}"] == 0
        ch = nodes[f"child_{s}"][m]
        if not (np.array_equal(nodes[f"bmin_{s}"][m], rlo[ch])
                and np.array_equal(nodes[f"bmax_{s}"][m], rhi[ch])):
            raise AssertionError(f"a {s} inner child box is not the exact union of its children's boxes")
