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
    v = np.asarray(v, np.float64)
    fn = np.cross(v[f[:, 1]] - v[f[:, 0]], v[f[:, 2]] - v[f[:, 1]])
    length = np.linalg.norm(fn, axis=1)
    fn = np.divide(fn, length[:, None], out=np.zeros_like(fn), where=length[:, None] > 0)
    n = np.zeros_like(v)
    for k in range(3):
        for c in range(3):
            n[:, c] += np.bincount(f[:, k], weights=fn[:, c], minlength=len(v))
    length = np.linalg.norm(n, axis=1)
    return np.divide(n, length[:, None], out=np.zeros_like(n), where=length[:, None] > 0)


def refine(v, f, uv, n, linear, max_edge, max_triangles=200_000_000):
    """(v, f, uv, n) with every edge shorter than max_edge after ``linear`` (3 x 3, the shape's
    transform without its translation, which distances do not see).  v (V, 3), uv (V, 2), n (V, 3)
    per vertex; f (F, 3).  Raises ValueError past max_triangles (an edgelength far below the mesh's
    scale)."""
    v, uv, n = (np.asarray(a, np.float64) for a in (v, uv, n))
    f = np.asarray(f, np.int64)
    linear = np.asarray(linear, np.float64)
    done = []
    count = 0
    edge_keys = np.zeros(0, np.int64)  # sorted keys of the edges split so far, and their midpoints
    edge_mids = np.zeros(0, np.int64)
    while len(f):
        p = v @ linear.T
        d01 = np.linalg.norm(p[f[:, 1]] - p[f[:, 0]], axis=1)
        d12 = np.linalg.norm(p[f[:, 2]] - p[f[:, 1]], axis=1)
        d20 = np.linalg.norm(p[f[:, 0]] - p[f[:, 2]], axis=1)
        small = (d01 < max_edge) & (d12 < max_edge) & (d20 < max_edge)
        done.append(f[small])
        count += int(small.sum())
        f, d01, d12, d20 = f[~small], d01[~small], d12[~small], d20[~small]
        if count + 2 * len(f) > max_triangles:
            raise ValueError(f"refining to edges under {max_edge:g} makes over {max_triangles} triangles")
        if not len(f):
            break
        # the longest edge first (pbrt's comparisons, ties included): (a, b) is split, c is opposite
        first = np.where(d01 > d12, np.where(d01 > d20, 0, 2), np.where(d12 > d20, 1, 2))
        rows = np.arange(len(f))
        a, b, c = f[rows, first], f[rows, (first + 1) % 3], f[rows, (first + 2) % 3]
        lo, hi = np.minimum(a, b), np.maximum(a, b)
        keys = (lo << 32) | hi
        unique, inverse = np.unique(keys, return_inverse=True)
        mids = np.empty(len(unique), np.int64)
        at = np.searchsorted(edge_keys, unique)
        known = (at < len(edge_keys)) & (edge_keys[np.minimum(at, len(edge_keys) - 1)] == unique) \
            if len(edge_keys) else np.zeros(len(unique), bool)
        mids[known] = edge_mids[at[known]]
        fresh = ~known
        ulo, uhi = unique[fresh] >> 32, unique[fresh] & 0xFFFFFFFF
        mids[fresh] = len(v) + np.arange(int(fresh.sum()))
        nn = n[ulo] + n[uhi]
        length = np.linalg.norm(nn, axis=1, keepdims=True)
        nn = np.divide(nn, length, out=nn.copy(), where=length > 0)
        v = np.concatenate([v, 0.5 * (v[ulo] + v[uhi])])
        uv = np.concatenate([uv, 0.5 * (uv[ulo] + uv[uhi])])
        n = np.concatenate([n, nn])
        order = np.argsort(np.concatenate([edge_keys, unique[fresh]]), kind="stable")
        edge_keys = np.concatenate([edge_keys, unique[fresh]])[order]
        edge_mids = np.concatenate([edge_mids, mids[fresh]])[order]
        m = mids[inverse]
        f = np.concatenate([np.stack([a, m, c], 1), np.stack([m, b, c], 1)])
    return v, np.concatenate(done) if done else np.zeros((0, 3), np.int64), uv, n


def displace(v, f, uv, n, linear, max_edge, height):
    """pbrt-v4's Displace: refine (above), move each vertex along its normal by height(uv) (a function
    of (V, 2) uvs giving (V,) heights), and recompute the normals.  n may be None (computed first).
    -> (v, f, uv, n), all per vertex."""
    if n is None:
        n = face_normal_sum(v, f)
    v, f, uv, n = refine(v, f, uv, n, linear, max_edge)
    h = np.asarray(height(uv), np.float64).reshape(-1)
    v = v + h[:, None] * n
    return v, f, uv, face_normal_sum(v, f)
