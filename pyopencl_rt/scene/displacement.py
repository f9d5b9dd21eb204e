"""Displaced meshes: pbrt-v4's plymesh with a "displacement" float texture (TriQuadMesh::Displace).

The mesh is refined, then displaced, on the host, before the BVH sees it:

* **Refine**: a triangle whose edges are not all shorter than ``edgelength`` (measured in the world,
  after the shape's transform) is split at the midpoint of its longest edge into (a, m, c) and
  (m, b, c), and each half in turn, until every edge is short enough.  A split edge's midpoint is
  made once and shared by the two triangles beside it (so no cracks open); its normal is the
  normalised sum of the edge's end normals, its uv their mean.
* **Displace**: each vertex moves along its (unit) normal by the texture's value at its uv.
* **Normals**: recomputed as the normalised sum of the unit normals of the faces around each vertex,
  unweighted (TriQuadMesh::ComputeNormals); also the normals of a mesh that came without any.

pbrt refines triangle by triangle, recursively; this does it in rounds over every triangle still too
large, which gives the same triangles (a triangle's halves do not depend on the order of the splits)
with the vertices numbered otherwise.
"""
from __future__ import annotations

import math

import numpy as np

from .meshops import _jit


def face_normal_sum(v, f) -> np.ndarray:
    """Per-vertex normals: the normalised sum of the unit normals of the faces around each vertex
    (faces of zero area add nothing; a vertex with none keeps a zero normal), float64; one pass over
    the faces in their order, as pbrt's ComputeNormals."""
    return _face_normal_sum(np.ascontiguousarray(v), np.ascontiguousarray(f))


@_jit()
def _face_normal_sum(v, f):
    n = np.zeros((v.shape[0], 3))
    for t in range(f.shape[0]):
        a, b, c = f[t, 0], f[t, 1], f[t, 2]
        e0 = (float(v[b, 0]) - v[a, 0], float(v[b, 1]) - v[a, 1], float(v[b, 2]) - v[a, 2])
        e1 = (float(v[c, 0]) - v[b, 0], float(v[c, 1]) - v[b, 1], float(v[c, 2]) - v[b, 2])
        x = e0[1] * e1[2] - e0[2] * e1[1]
        y = e0[2] * e1[0] - e0[0] * e1[2]
        z = e0[0] * e1[1] - e0[1] * e1[0]
        length = math.sqrt(x * x + y * y + z * z)
        if length > 0:
            for k in (a, b, c):
                n[k, 0] += x / length
                n[k, 1] += y / length
                n[k, 2] += z / length
    for i in range(n.shape[0]):
        length = math.sqrt(n[i, 0] * n[i, 0] + n[i, 1] * n[i, 1] + n[i, 2] * n[i, 2])
        if length > 0:
            n[i, 0], n[i, 1], n[i, 2] = n[i, 0] / length, n[i, 1] / length, n[i, 2] / length
    return n


def refine(v, f, uv, n, linear, max_edge, max_triangles=200_000_000):
    """(v, f, uv, n) with every edge shorter than max_edge after ``linear`` (3 x 3, the shape's
    transform without its translation, which distances do not see).  v (V, 3), uv (V, 2), n (V, 3)
    per vertex; f (F, 3).  pbrt's recursion, with an explicit stack (the first half first), so that
    the triangles and the midpoints come in pbrt's order; positions, uvs and normals in float32 as
    pbrt keeps them (kroken's carpet refines to 54M triangles), lengths in float64.  Raises ValueError
    past max_triangles (an edgelength far below the mesh's scale)."""
    v, uv, n = (np.ascontiguousarray(a, np.float32) for a in (v, uv, n))
    f = np.ascontiguousarray(f, np.int64)
    ok, *out = _refine(v, uv, n, f, np.ascontiguousarray(linear, np.float64), float(max_edge), int(max_triangles))
    if not ok:
        raise ValueError(f"refining to edges under {max_edge:g} makes over {max_triangles} triangles")
    return tuple(out)


@_jit()
def _grow(a, size):
    b = np.empty((max(2 * a.shape[0], size), a.shape[1]), a.dtype)
    b[:a.shape[0]] = a
    return b


@_jit()
def _edge_length(v, i, j, m):
    d0, d1, d2 = float(v[j, 0]) - v[i, 0], float(v[j, 1]) - v[i, 1], float(v[j, 2]) - v[i, 2]
    x = m[0, 0] * d0 + m[0, 1] * d1 + m[0, 2] * d2
    y = m[1, 0] * d0 + m[1, 1] * d1 + m[1, 2] * d2
    z = m[2, 0] * d0 + m[2, 1] * d1 + m[2, 2] * d2
    return math.sqrt(x * x + y * y + z * z)


@_jit()
def _slot(keys, key):
    """The open-addressing slot of ``key`` in ``keys`` (-1 marks an empty one)."""
    mask = keys.shape[0] - 1
    at = ((key * np.int64(-7046029254386353131)) >> 20) & mask  # Fibonacci hashing, wrapped
    while keys[at] != -1 and keys[at] != key:
        at = (at + 1) & mask
    return at


@_jit()
def _refine(v0, uv0, n0, f, m, max_edge, max_triangles):
    nv = v0.shape[0]
    v, uv, n = v0.copy(), uv0.copy(), n0.copy()
    out = np.empty((max(16, 2 * f.shape[0]), 3), np.int32)
    count = 0
    cap = 1 << 16
    keys = np.full(cap, -1, np.int64)
    mids = np.empty(cap, np.int64)
    used = 0
    stack = np.empty((4096, 3), np.int64)
    for t in range(f.shape[0]):
        stack[0, 0], stack[0, 1], stack[0, 2] = f[t, 0], f[t, 1], f[t, 2]
        top = 1
        while top > 0:
            top -= 1
            a, b, c = stack[top, 0], stack[top, 1], stack[top, 2]
            d01, d12, d20 = _edge_length(v, a, b, m), _edge_length(v, b, c, m), _edge_length(v, c, a, m)
            if d01 < max_edge and d12 < max_edge and d20 < max_edge:
                if count == out.shape[0]:
                    if count >= max_triangles:
                        return False, v[:0], out[:0], uv[:0], n[:0]
                    out = _grow(out, count + 1)
                out[count, 0], out[count, 1], out[count, 2] = a, b, c
                count += 1
                continue
            if d01 > d12:  # the longest edge first, pbrt's comparisons (ties included)
                x, y, z = (a, b, c) if d01 > d20 else (c, a, b)
            else:
                x, y, z = (b, c, a) if d12 > d20 else (c, a, b)
            key = (min(x, y) << 32) | max(x, y)
            at = _slot(keys, key)
            if keys[at] == key:
                mid = mids[at]
            else:
                if nv == v.shape[0]:
                    v, uv, n = _grow(v, nv + 1), _grow(uv, nv + 1), _grow(n, nv + 1)
                for k in range(3):
                    v[nv, k] = (v[x, k] + v[y, k]) / np.float32(2)
                for k in range(2):
                    uv[nv, k] = (uv[x, k] + uv[y, k]) / np.float32(2)
                s0, s1, s2 = n[x, 0] + n[y, 0], n[x, 1] + n[y, 1], n[x, 2] + n[y, 2]
                length = math.sqrt(float(s0) * s0 + float(s1) * s1 + float(s2) * s2)
                if length > 0:
                    s0, s1, s2 = s0 / length, s1 / length, s2 / length
                n[nv, 0], n[nv, 1], n[nv, 2] = s0, s1, s2
                keys[at], mids[at] = key, nv
                mid = nv
                nv += 1
                used += 1
                if 2 * used > cap:  # rehash at half full
                    old_keys, old_mids = keys, mids
                    cap *= 2
                    keys = np.full(cap, -1, np.int64)
                    mids = np.empty(cap, np.int64)
                    for i in range(old_keys.shape[0]):
                        if old_keys[i] != -1:
                            j = _slot(keys, old_keys[i])
                            keys[j], mids[j] = old_keys[i], old_mids[i]
            if top + 2 > stack.shape[0]:
                stack = _grow(stack, top + 2)
            stack[top, 0], stack[top, 1], stack[top, 2] = mid, y, z  # pbrt's second half, after
            stack[top + 1, 0], stack[top + 1, 1], stack[top + 1, 2] = x, mid, z  # the first
            top += 2
    return True, v[:nv].copy(), out[:count].copy(), uv[:nv].copy(), n[:nv].copy()


def displace(v, f, uv, n, linear, max_edge, height):
    """pbrt-v4's Displace: refine (above), move each vertex along its normal by height(uv) (a function
    of (V, 2) uvs giving (V,) heights), and recompute the normals.  n may be None (computed first).
    -> (v, f, uv, n), all per vertex."""
    if n is None:
        n = face_normal_sum(v, f)
    v, f, uv, n = refine(v, f, uv, n, linear, max_edge)
    h = np.asarray(height(uv), np.float32).reshape(-1)
    v = v + h[:, None] * n
    return v, f, uv, face_normal_sum(v, f).astype(np.float32)
