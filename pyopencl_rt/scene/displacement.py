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

import numpy as np


def face_normal_sum(v, f) -> np.ndarray:
    """Per-vertex normals: the normalised sum of the unit normals of the faces around each vertex
    (faces of zero area add nothing; a vertex with none keeps a zero normal), float64."""
    n = np.zeros((len(v), 3))
    step = 1 << 22  # faces a chunk (float64 temporaries of a whole 54M-face mesh took gigabytes)
    for lo in range(0, len(f), step):
        tri = np.asarray(v)[np.asarray(f[lo:lo + step])].astype(np.float64)
        fn = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 1])
        length = np.linalg.norm(fn, axis=1, keepdims=True)
        fn = np.divide(fn, length, out=np.zeros_like(fn), where=length > 0)
        for k in range(3):
            for c in range(3):
                n[:, c] += np.bincount(f[lo:lo + step, k], weights=fn[:, c], minlength=len(v))
    length = np.linalg.norm(n, axis=1, keepdims=True)
    return np.divide(n, length, out=np.zeros_like(n), where=length > 0)


def refine(v, f, uv, n, linear, max_edge, max_triangles=200_000_000):
    """(v, f, uv, n) with every edge shorter than max_edge after ``linear`` (3 x 3, the shape's
    transform without its translation, which distances do not see).  v (V, 3), uv (V, 2), n (V, 3)
    per vertex; f (F, 3).  Positions, uvs and normals are kept in float32 as pbrt keeps them (a carpet
    of kroken's refines to 54M triangles); the lengths are measured in float64.  Raises ValueError past
    max_triangles (an edgelength far below the mesh's scale)."""
    grow = _Growing(np.asarray(v, np.float32), np.asarray(uv, np.float32), np.asarray(n, np.float32))
    f = np.asarray(f, np.int64)
    linear = np.asarray(linear, np.float64)
    done = []
    count = 0
    edge_keys = np.zeros(0, np.int64)  # sorted keys of the edges split so far, and their midpoints
    edge_mids = np.zeros(0, np.int64)
    while len(f):
        p = grow.v
        lengths = [np.linalg.norm((p[f[:, j]].astype(np.float64) - p[f[:, i]]) @ linear.T, axis=1)
                   for i, j in ((0, 1), (1, 2), (2, 0))]
        d01, d12, d20 = lengths
        small = (d01 < max_edge) & (d12 < max_edge) & (d20 < max_edge)
        done.append(f[small].astype(np.int32))
        count += int(small.sum())
        f, d01, d12, d20 = f[~small], d01[~small], d12[~small], d20[~small]
        if count + 2 * len(f) > max_triangles:
            raise ValueError(f"refining to edges under {max_edge:g} makes over {max_triangles} triangles")
        if not len(f):
            break
        # the longest edge first (pbrt's comparisons, ties included): (a, b) is split, c is opposite
        first = np.where(d01 > d12, np.where(d01 > d20, 0, 2), np.where(d12 > d20, 1, 2))
        del d01, d12, d20, lengths
        rows = np.arange(len(f))
        a, b, c = f[rows, first], f[rows, (first + 1) % 3], f[rows, (first + 2) % 3]
        del rows, first, f
        keys = (np.minimum(a, b) << 32) | np.maximum(a, b)
        unique, inverse = np.unique(keys, return_inverse=True)
        del keys
        mids = np.empty(len(unique), np.int64)
        known = np.zeros(len(unique), bool)
        if len(edge_keys):
            at = np.minimum(np.searchsorted(edge_keys, unique), len(edge_keys) - 1)
            known = edge_keys[at] == unique
            mids[known] = edge_mids[at[known]]
        fresh = unique[~known]
        mids[~known] = grow.add_midpoints(fresh >> 32, fresh & 0xFFFFFFFF)
        at = np.searchsorted(edge_keys, fresh)  # both sorted, none shared: a merge, not a sort
        edge_keys, edge_mids = np.insert(edge_keys, at, fresh), np.insert(edge_mids, at, mids[~known])
        m = mids[inverse]
        f = np.concatenate([np.stack([a, m, c], 1), np.stack([m, b, c], 1)])
    out = np.concatenate(done) if done else np.zeros((0, 3), np.int32)
    return grow.v, out, grow.uv, grow.n


class _Growing:
    """Per-vertex arrays that grow by midpoints without a copy each round (capacity doubles)."""

    def __init__(self, v, uv, n):
        self.size = len(v)
        self._v, self._uv, self._n = v, uv, n

    v = property(lambda self: self._v[:self.size])
    uv = property(lambda self: self._uv[:self.size])
    n = property(lambda self: self._n[:self.size])

    def add_midpoints(self, lo, hi) -> np.ndarray:
        """Append the midpoints of edges (lo, hi): position and uv their means, normal the normalised sum
        (left as it is where the sum is 0).  -> their indices."""
        k = len(lo)
        if self.size + k > len(self._v):
            cap = max(2 * len(self._v), self.size + k)
            self._v, self._uv, self._n = (np.resize(a, (cap, a.shape[1])) for a in (self._v, self._uv, self._n))
        at = slice(self.size, self.size + k)
        self._v[at] = 0.5 * (self._v[lo] + self._v[hi])
        self._uv[at] = 0.5 * (self._uv[lo] + self._uv[hi])
        nn = self._n[lo] + self._n[hi]
        length = np.linalg.norm(nn, axis=1, keepdims=True)
        self._n[at] = np.divide(nn, length, out=nn, where=length > 0)
        start, self.size = self.size, self.size + k
        return np.arange(start, start + k)


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
