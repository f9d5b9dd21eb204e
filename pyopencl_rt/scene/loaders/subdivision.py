"""Loop subdivision of a triangle mesh, as pbrt-v4's ``loopsubdiv`` shape asks for it.

Each level splits every triangle into four: a new ("odd") vertex on each edge, at
3/8 (a + b) + 1/8 (c + d) for an edge a-b between the triangles a-b-c and b-a-d, at (a + b) / 2 on
a boundary edge; each old ("even") vertex v of valence k moves to (1 - k beta) v + beta (the sum of
its neighbours), beta = 3/16 for k = 3 and 3 / (8k) otherwise (Warren's weights, pbrt's), and a
boundary vertex to 3/4 v + 1/8 (its two boundary neighbours).  After the last level every vertex
is moved to its point on the limit surface (as pbrt-v4 does): (1 - k gamma) v + gamma (the sum of
the neighbours), gamma = 1 / (k + 3 / (8 beta)), and 2/3 v + 1/6 (the boundary neighbours) on a
boundary: the limit point of the cubic B-spline that the boundary rules make (a 3/5, 1/5, 1/5
mask, which pbrt-v3 used if memory serves and which we have not checked in pbrt-v4, is not that
curve's limit: a boundary vertex computed so moves again at the next level).  The limit point of a vertex is the same at
every further level, which the tests use.

A level takes V vertices, E edges, F faces to V + E, 2E + 3F, 4F (Euler's V - E + F kept); the
triangles keep their orientation and the new vertices are numbered after the old ones (vertex i
of one level is vertex i of the next).  An edge with more than two triangles (not a manifold) is
an error.
"""
from __future__ import annotations

import numpy as np


class SubdivisionError(ValueError):
    pass


def _edges(faces):
    """The unique undirected edges (sorted pairs), each half-edge's edge index, the number of
    triangles on each edge, and each half-edge's opposite vertex."""
    half = np.concatenate([faces[:, [0, 1]], faces[:, [1, 2]], faces[:, [2, 0]]])
    opposite = np.concatenate([faces[:, 2], faces[:, 0], faces[:, 1]])
    edges, index, count = np.unique(np.sort(half, axis=1), axis=0, return_inverse=True, return_counts=True)
    return edges, index.ravel(), count, opposite


def _rings(n_vertices, edges, count):
    """Per vertex: its valence, the sum of its neighbours, whether it is on a boundary, and the
    sum of its neighbours along boundary edges."""
    valence = np.bincount(edges.ravel(), minlength=n_vertices)
    boundary_edges = edges[count == 1]
    on_boundary = np.zeros(n_vertices, bool)
    on_boundary[boundary_edges.ravel()] = True
    return valence, on_boundary, boundary_edges


def _neighbour_sum(vertices, edges):
    total = np.zeros_like(vertices)
    np.add.at(total, edges[:, 0], vertices[edges[:, 1]])
    np.add.at(total, edges[:, 1], vertices[edges[:, 0]])
    return total


def _beta(valence):
    k = np.maximum(valence, 1).astype(np.float64)
    return np.where(valence == 3, 3.0 / 16.0, 3.0 / (8.0 * k))


def subdivide_once(vertices, faces):
    """One level of Loop subdivision: (vertices, faces) of the finer mesh."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    edges, index, count, opposite = _edges(f)
    if np.any(count > 2):
        raise SubdivisionError(f"{int(np.sum(count > 2))} edge(s) shared by more than two triangles "
                               "(Loop subdivision needs a manifold mesh)")
    opposite_sum = np.zeros((len(edges), 3))
    np.add.at(opposite_sum, index, v[opposite])
    ends = v[edges[:, 0]] + v[edges[:, 1]]
    odd = np.where((count == 2)[:, None], 3.0 / 8.0 * ends + 1.0 / 8.0 * opposite_sum, 0.5 * ends)

    valence, on_boundary, boundary_edges = _rings(len(v), edges, count)
    beta = _beta(valence)[:, None]
    even = (1.0 - valence[:, None] * beta) * v + beta * _neighbour_sum(v, edges)
    boundary_sum = _neighbour_sum(v, boundary_edges)
    even = np.where(on_boundary[:, None], 0.75 * v + 0.125 * boundary_sum, even)
    isolated = valence == 0
    even[isolated] = v[isolated]

    m = len(f)
    e01, e12, e20 = (len(v) + index[i * m:(i + 1) * m] for i in range(3))
    a, b, c = f[:, 0], f[:, 1], f[:, 2]
    finer = np.concatenate([np.stack([a, e01, e20], 1), np.stack([b, e12, e01], 1),
                            np.stack([c, e20, e12], 1), np.stack([e01, e12, e20], 1)])
    return np.concatenate([even, odd]), finer


def limit_positions(vertices, faces):
    """Each vertex moved to its point on the Loop limit surface of the mesh."""
    v = np.asarray(vertices, np.float64)
    edges, _, count, _ = _edges(np.asarray(faces, np.int64))
    valence, on_boundary, boundary_edges = _rings(len(v), edges, count)
    beta = _beta(valence)
    k = valence.astype(np.float64)
    with np.errstate(divide="ignore"):
        gamma = np.where(valence > 0, 1.0 / (k + 3.0 / (8.0 * beta)), 0.0)[:, None]
    limit = (1.0 - k[:, None] * gamma) * v + gamma * _neighbour_sum(v, edges)
    limit = np.where(on_boundary[:, None], 2.0 / 3.0 * v + 1.0 / 6.0 * _neighbour_sum(v, boundary_edges), limit)
    return limit


def vertex_normals(vertices, faces):
    """Unit vertex normals: the sum of the normals of the triangles around each vertex, each
    weighted by its angle at the vertex (0 where a vertex has none)."""
    v = np.asarray(vertices, np.float64)
    f = np.asarray(faces, np.int64)
    p = v[f]
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    n /= np.maximum(np.linalg.norm(n, axis=1, keepdims=True), 1e-300)
    out = np.zeros_like(v)
    for corner in range(3):
        e1 = p[:, (corner + 1) % 3] - p[:, corner]
        e2 = p[:, (corner + 2) % 3] - p[:, corner]
        cos = np.einsum("ij,ij->i", e1, e2) / np.maximum(np.linalg.norm(e1, axis=1) * np.linalg.norm(e2, axis=1),
                                                         1e-300)
        np.add.at(out, f[:, corner], n * np.arccos(np.clip(cos, -1.0, 1.0))[:, None])
    length = np.linalg.norm(out, axis=1, keepdims=True)
    return np.where(length > 0, out / np.maximum(length, 1e-300), 0.0)


def loop_subdivide(vertices, faces, levels: int, limit: bool = True):
    """``levels`` levels of Loop subdivision, then (``limit``) every vertex on the limit surface."""
    v, f = np.asarray(vertices, np.float64), np.asarray(faces, np.int64)
    for _ in range(levels):
        v, f = subdivide_once(v, f)
    if limit:
        v = limit_positions(v, f)
    return v, f
