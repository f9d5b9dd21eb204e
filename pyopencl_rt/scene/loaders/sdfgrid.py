"""Mitsuba 3's ``sdfgrid`` shape as triangles: the zero level set of a signed distance function
sampled on a grid (src/shapes/sdfgrid.cpp), meshed once at load time.

Mitsuba's grid spans the unit cube of the shape's object space, its n_x x n_y x n_z values at the
cell corners (a cell is 1 / (n - 1) wide along each axis), interpolated trilinearly; the surface
is where that field is 0, outside where it is positive, and Mitsuba intersects it by solving each
cell's cubic along the ray.  Here each cell is split into six tetrahedra about its main diagonal
(marching tetrahedra: no case tables, no ambiguous faces, a closed surface wherever the grid's
is) and the zero crossing of every tetrahedron edge whose corners differ in sign is a vertex (the
linear interpolation of the two values): the same zero set up to the field's curvature within a
cell, whose deviation is a small fraction of a cell (each cell is split into smaller ones first, REFINE_CELLS).  Triangles face the positive side; a vertex is
shared by every triangle through its edge, and its shading normal is the gradient of the
trilinear field there (Mitsuba's ``analytic`` normal, which its ``smooth`` one interpolates
between cells), so the surface shades smoothly.  Like Mitsuba's, the shape has no uv.
"""
from __future__ import annotations

import numpy as np

# the cube's corners as (dx, dy, dz) bits (corner k = x + 2 y + 4 z) and its six tetrahedra about
# the diagonal from corner 0 to corner 7 (each a path 0 -> a -> b -> 7 along the cube's edges)
_CORNERS = np.array([[k & 1, (k >> 1) & 1, (k >> 2) & 1] for k in range(8)])
_TETRAHEDRA = np.array([[0, 1, 3, 7], [0, 3, 2, 7], [0, 2, 6, 7], [0, 6, 4, 7], [0, 4, 5, 7], [0, 5, 1, 7]])
_TET_EDGES = [(0, 1), (0, 2), (0, 3), (1, 2), (1, 3), (2, 3)]
_EDGE_ID = np.full((4, 4), -1, np.int64)  # the index in _TET_EDGES of the edge between two corners
for _k, (_a, _b) in enumerate(_TET_EDGES):
    _EDGE_ID[_a, _b] = _EDGE_ID[_b, _a] = _k
_EDGES_OF = np.array([[k for k, e in enumerate(_TET_EDGES) if c in e] for c in range(4)])  # each corner's three


def trilinear(values, p) -> tuple[np.ndarray, np.ndarray]:
    """The trilinear field of the grid ``values`` ((nz, ny, nx), corners at (i, j, k) / (n - 1)) at the
    points ``p`` ((N, 3), in [0, 1]^3): (value (N,), gradient (N, 3)) per unit of object space."""
    nz, ny, nx = values.shape
    res = np.array([nx - 1, ny - 1, nz - 1], np.float64)
    g = np.clip(np.asarray(p, np.float64) * res, 0.0, res)
    i0 = np.minimum(np.floor(g).astype(np.int64), np.maximum(res.astype(np.int64) - 1, 0))
    f = g - i0
    out, grad = np.zeros(len(g)), np.zeros((len(g), 3))
    for c in _CORNERS:
        w = np.where(c, f, 1.0 - f)  # each axis' weight
        v = values[i0[:, 2] + c[2], i0[:, 1] + c[1], i0[:, 0] + c[0]]
        out += v * w.prod(1)
        for a in range(3):  # d/df_a of the product: the other two weights, signed
            others = np.prod(np.delete(w, a, axis=1), axis=1)
            grad[:, a] += v * others * (1.0 if c[a] else -1.0) * res[a]
    return out, grad


# Each cell is meshed as REFINE_CELLS^3 smaller ones (the trilinear field sampled at their corners):
# the flat triangles then follow the curved surface of Mitsuba's cells closely.  With the cell as it
# is, a sphere of 23 cells across rendered 2% brighter than Mitsuba's on its side lit by the sky
# alone (tests/scene/test_sdfgrid.py: tiles 6 sigma off); split in 3, within 1%.  Grids of more than
# REFINE_UP_TO cells along an axis are split less (their cells are small already).
REFINE_CELLS, REFINE_UP_TO = 4, 128


def refinement(shape) -> int:
    """How many parts each cell of a grid of ``shape`` ((nz, ny, nx) corners) is split into per axis."""
    return int(max(1, min(REFINE_CELLS, REFINE_UP_TO // max(max(shape) - 1, 1))))


def sdf_mesh(values, refine: int | None = None) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(vertices (V, 3) in the unit cube, faces (F, 3) facing the positive side, per-corner unit
    normals (F, 3, 3)) of the zero level set of ``values`` ((nz, ny, nx) float), each cell split
    ``refine`` times per axis first (default: :func:`refinement`)."""
    original = np.asarray(values, np.float64)
    k = refinement(original.shape) if refine is None else int(refine)
    values = original
    if k > 1 and min(original.shape) >= 2:  # the trilinear field at k x the corners: linear along each axis in turn
        for axis in range(3):
            n = values.shape[axis]
            g = np.arange((n - 1) * k + 1) / k
            i = np.minimum(g.astype(np.int64), n - 2)
            f = (g - i).reshape([-1 if a == axis else 1 for a in range(3)])
            values = np.take(values, i, axis) * (1.0 - f) + np.take(values, i + 1, axis) * f
    nz, ny, nx = values.shape
    if min(nx, ny, nz) < 2:
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64), np.zeros((0, 3, 3))
    cells = np.stack(np.meshgrid(np.arange(nx - 1), np.arange(ny - 1), np.arange(nz - 1), indexing="ij"), -1)
    cells = cells.reshape(-1, 3)  # (x, y, z) of each cell's corner 0
    corner = cells[:, None, :] + _CORNERS[None, :, :]  # (C, 8, 3)
    flat = (corner[..., 2] * ny + corner[..., 1]) * nx + corner[..., 0]  # the corners' grid indices
    vals = values.reshape(-1)[flat]
    keep = (vals.min(1) <= 0) & (vals.max(1) > 0)  # cells the surface crosses
    tet_ids = flat[keep][:, _TETRAHEDRA].reshape(-1, 4)  # (T, 4) grid indices of each tetrahedron
    tv = values.reshape(-1)[tet_ids]
    inside = tv <= 0
    n_in = inside.sum(1)
    tet_ids, tv, inside, n_in = (a[(n_in > 0) & (n_in < 4)] for a in (tet_ids, tv, inside, n_in))
    # every edge of every tetrahedron that the surface crosses: a vertex per grid edge
    ea = np.array([e[0] for e in _TET_EDGES])
    eb = np.array([e[1] for e in _TET_EDGES])
    a_idx, b_idx = tet_ids[:, ea], tet_ids[:, eb]  # (T, 6)
    crossing = inside[:, ea] != inside[:, eb]
    lo, hi = np.minimum(a_idx, b_idx), np.maximum(a_idx, b_idx)
    keys = lo.astype(np.int64) * values.size + hi
    uniq, vertex_of = np.unique(keys[crossing], return_inverse=True)
    edge_vertex = np.full(keys.shape, -1, np.int64)
    edge_vertex[crossing] = vertex_of
    ga, gb = uniq // values.size, uniq % values.size
    va, vb = values.reshape(-1)[ga], values.reshape(-1)[gb]
    t = va / (va - vb)

    def position(g):
        z, rest = np.divmod(g, nx * ny)
        y, x = np.divmod(rest, nx)
        return np.stack([x, y, z], 1) / np.array([nx - 1, ny - 1, nz - 1], np.float64)

    pa, pb = position(ga), position(gb)
    vertices = pa + t[:, None] * (pb - pa)
    faces = []
    # one inside corner (or one outside): a triangle on its three edges; two: a quad on the four
    for count in (1, 3):
        sel = n_in == count
        lone = np.argmax(inside[sel] if count == 1 else ~inside[sel], axis=1)  # the corner alone on its side
        tri = np.take_along_axis(edge_vertex[sel], _EDGES_OF[lone], axis=1)
        faces.append(tri)
    sel = n_in == 2
    if sel.any():
        ev = edge_vertex[sel]
        order = np.argsort(~inside[sel], axis=1, kind="stable")  # the two inside corners, then the two outside
        i0, i1, o0, o1 = order.T
        # the four crossing edges in order around the quad: (i0, o0), (i0, o1), (i1, o1), (i1, o0)
        quad_edges = np.stack([_EDGE_ID[i0, o0], _EDGE_ID[i0, o1], _EDGE_ID[i1, o1], _EDGE_ID[i1, o0]], 1)
        q = np.take_along_axis(ev, quad_edges, axis=1)
        faces.append(q[:, [0, 1, 2]])
        faces.append(q[:, [0, 2, 3]])
    faces = np.concatenate(faces) if faces else np.zeros((0, 3), np.int64)
    # drop the triangles that collapse (a corner exactly at 0 shared by crossing edges), face the positive side
    v = vertices[faces]
    n = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    area2 = np.linalg.norm(n, axis=1)
    faces, n = faces[area2 > 1e-14], n[area2 > 1e-14]
    _, grad = trilinear(original, vertices)
    outward = grad[faces].sum(1)
    flip = np.einsum("ij,ij->i", n, outward) < 0
    faces[flip] = faces[flip][:, ::-1]
    length = np.linalg.norm(grad, axis=1, keepdims=True)
    normals = np.where(length > 0, grad / np.where(length > 0, length, 1.0), 0.0)
    return vertices, faces, normals[faces]
