"""Loop subdivision of a triangle mesh, as pbrt-v4's ``loopsubdiv`` shape asks for it.

Each level splits every triangle into four: a new ("odd") vertex on each edge, at
3/8 (a + b) + 1/8 (c + d) for an edge a-b between the triangles a-b-c and b-a-d, at (a + b) / 2 on
a boundary edge; each old ("even") vertex v of valence k moves to (1 - k beta) v + beta (the sum of
its neighbours), beta = 3/16 for k = 3 and 3 / (8k) otherwise (Warren's weights, pbrt's), and a
boundary vertex to 3/4 v + 1/8 (its two boundary neighbours).  After the last level every vertex
is moved to its point on the limit surface as pbrt-v4 moves it (src/pbrt/util/loopsubdiv.cpp):
(1 - k gamma) v + gamma (the sum of the neighbours), gamma = 1 / (k + 3 / (8 beta)), and
3/5 v + 1/5 (the two boundary neighbours) on a boundary (pbrt's mask; the cubic B-spline that the
boundary rules make has its limit at 2/3, 1/6, 1/6, so a boundary vertex of pbrt's mesh is not
quite on it).  The limit point of an interior vertex is the same at every further level, which
the tests use.  The shading normals are pbrt-v4's too (:func:`limit_normals`): the cross product of
the limit surface's two tangents, from the vertex's ordered one-ring.

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
    limit = np.where(on_boundary[:, None], 0.6 * v + 0.2 * _neighbour_sum(v, boundary_edges), limit)
    return limit


def _ordered_rings(n_vertices, faces):
    """(valence, on_boundary, rings): each vertex's neighbours in order around it (V x max valence,
    -1 past its valence), as pbrt's SDVertex::oneRing walks them: around the faces, and on a
    boundary from one boundary neighbour to the other."""
    f = np.asarray(faces, np.int64)
    centre = f.reshape(-1)
    first = np.roll(f, -1, axis=1).reshape(-1)  # in face (a, b, c) around a: b, then c
    then = np.roll(f, -2, axis=1).reshape(-1)
    n = np.int64(n_vertices)
    keys = centre * n + first
    order = np.argsort(keys, kind="stable")
    keys, after = keys[order], then[order]
    has_prev = np.isin(keys, centre * n + then)  # a neighbour that no face puts before another
    faces_at = np.bincount(centre, minlength=n_vertices)
    on_boundary = np.zeros(n_vertices, bool)
    on_boundary[centre[order][~has_prev]] = True
    valence = faces_at + on_boundary
    start = np.full(n_vertices, -1, np.int64)
    # interior: any neighbour (the first key of the vertex); boundary: the one without a predecessor
    start[centre[order][::-1]] = first[order][::-1]
    start[centre[order][~has_prev]] = first[order][~has_prev]
    rings = np.full((n_vertices, max(int(valence.max(initial=0)), 1)), -1, np.int64)
    rings[:, 0] = start
    ids = np.arange(n_vertices, dtype=np.int64)
    for j in range(1, rings.shape[1]):
        live = j < valence
        key = ids[live] * n + rings[live, j - 1]
        pos = np.minimum(np.searchsorted(keys, key), len(keys) - 1)
        rings[live, j] = np.where(keys[pos] == key, after[pos], -1)
    return valence, on_boundary, rings


def limit_normals(vertices, faces):
    """pbrt-v4's shading normals of a Loop mesh whose vertices are on the limit surface: S x T of
    the limit tangents from the ordered one-ring p_0 .. p_(k-1): interior S = sum cos(2 pi j / k)
    p_j, T = sum sin(2 pi j / k) p_j; on a boundary S = p_(k-1) - p_0 and T by the valence (2, 3,
    4, or pbrt's general mask).  Unit length, turned to the side of the triangles' normals (the
    ring's direction sets only the sign).  Exact on the control points; pbrt (and the loader)
    applies the masks to the points already on the limit surface, which tilts them slightly (0.23
    degrees at most on an icosahedron subdivided twice: tests/scene/test_subdivision.py)."""
    v = np.asarray(vertices, np.float64)
    valence, on_boundary, rings = _ordered_rings(len(v), faces)
    normals = np.zeros_like(v)
    for k in np.unique(valence):
        if k < 2:
            continue
        for boundary in (False, True):
            sel = np.nonzero((valence == k) & (on_boundary == boundary))[0]
            if len(sel) == 0:
                continue
            ring = v[rings[sel, :k]]  # len(sel) x k x 3
            p = v[sel]
            if not boundary:
                angle = 2.0 * np.pi * np.arange(k) / k
                s = np.einsum("j,ijk->ik", np.cos(angle), ring)
                t = np.einsum("j,ijk->ik", np.sin(angle), ring)
            else:
                s = ring[:, k - 1] - ring[:, 0]
                if k == 2:
                    t = ring[:, 0] + ring[:, 1] - 2.0 * p
                elif k == 3:
                    t = ring[:, 1] - p
                elif k == 4:
                    t = -ring[:, 0] + 2.0 * ring[:, 1] + 2.0 * ring[:, 2] - ring[:, 3] - 2.0 * p
                else:
                    theta = np.pi / (k - 1)
                    t = np.sin(theta) * (ring[:, 0] + ring[:, k - 1])
                    wt = (2.0 * np.cos(theta) - 2.0) * np.sin(np.arange(1, k - 1) * theta)
                    t = -(t + np.einsum("j,ijk->ik", wt, ring[:, 1:k - 1]))
            normals[sel] = np.cross(s, t)
    reference = vertex_normals(v, faces)
    normals *= np.where(np.einsum("ij,ij->i", normals, reference) < 0, -1.0, 1.0)[:, None]
    length = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.where(length > 0, normals / np.maximum(length, 1e-300), reference)


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
