"""Loop subdivision (pbrt-v4's ``loopsubdiv``): counts, watertightness, the limit surface."""
import math

import numpy as np
import pytest

from pyopencl_rt.scene.loaders.subdivision import (SubdivisionError, limit_normals, limit_positions,
                                                   loop_subdivide, subdivide_once, vertex_normals)

TETRA_V = np.array([[1, 1, 1], [1, -1, -1], [-1, 1, -1], [-1, -1, 1]], np.float64)
TETRA_F = np.array([[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])  # outward


def icosahedron():
    t = (1 + math.sqrt(5)) / 2
    v = np.array([[-1, t, 0], [1, t, 0], [-1, -t, 0], [1, -t, 0], [0, -1, t], [0, 1, t], [0, -1, -t], [0, 1, -t],
                  [t, 0, -1], [t, 0, 1], [-t, 0, -1], [-t, 0, 1]], np.float64)
    f = np.array([[0, 11, 5], [0, 5, 1], [0, 1, 7], [0, 7, 10], [0, 10, 11], [1, 5, 9], [5, 11, 4], [11, 10, 2],
                  [10, 7, 6], [7, 1, 8], [3, 9, 4], [3, 4, 2], [3, 2, 6], [3, 6, 8], [3, 8, 9], [4, 9, 5],
                  [2, 4, 11], [6, 2, 10], [8, 6, 7], [9, 8, 1]])
    return v / np.linalg.norm(v, axis=1, keepdims=True), f


def n_edges(f):
    return len(np.unique(np.sort(np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]]), axis=1), axis=0))


def volume(v, f):
    p = v[f]
    return np.einsum("ij,ij->i", p[:, 0], np.cross(p[:, 1], p[:, 2])).sum() / 6.0


def directed_edges(f):
    return np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])


@pytest.mark.parametrize("mesh", ["tetra", "icosahedron"])
def test_counts_and_watertight(mesh):
    v, f = (TETRA_V, TETRA_F) if mesh == "tetra" else icosahedron()
    for level in range(1, 5):
        v2, f2 = subdivide_once(v, f)
        e = n_edges(f)
        assert len(v2) == len(v) + e and len(f2) == 4 * len(f) and n_edges(f2) == 2 * e + 3 * len(f)
        assert len(v2) - n_edges(f2) + len(f2) == 2  # a sphere's Euler characteristic
        # watertight and consistently oriented: each directed edge once, and its reverse once
        d = directed_edges(f2)
        assert len(np.unique(d, axis=0)) == len(d)
        assert {tuple(x) for x in d} == {(b, a) for a, b in d}
        assert volume(v2, f2) > 0  # still facing outwards
        v, f = v2, f2


def test_tetrahedron_first_level_by_hand():
    v, f = subdivide_once(TETRA_V, TETRA_F)
    # every vertex has valence 3: beta = 3/16, so v' = (1 - 9/16) v + 3/16 (sum of the other three) = 7/16 v - 3/16 v
    # (the other three sum to -v, the centroid being 0)
    assert np.allclose(v[:4], (7 / 16 - 3 / 16) * TETRA_V)
    # the odd vertex of edge 0-1: 3/8 (v0 + v1) + 1/8 (v2 + v3)
    odd = 3 / 8 * (TETRA_V[0] + TETRA_V[1]) + 1 / 8 * (TETRA_V[2] + TETRA_V[3])
    assert any(np.allclose(x, odd) for x in v[4:])


@pytest.mark.parametrize("mesh", ["tetra", "icosahedron"])
def test_limit_points_do_not_move_with_more_levels(mesh):
    """A vertex's point on the limit surface is the same whichever level it is computed from."""
    v, f = (TETRA_V, TETRA_F) if mesh == "tetra" else icosahedron()
    levels = [loop_subdivide(v, f, n) for n in range(5)]
    for (va, _), (vb, _) in zip(levels, levels[1:]):
        assert np.allclose(vb[:len(va)], va, atol=1e-12)


def test_converges_to_the_limit_surface():
    """Without the final projection the mesh approaches the limit surface: the distance of the
    control vertices from their limit points shrinks about fourfold a level."""
    v, f = icosahedron()
    target = limit_positions(v, f)
    gaps = []
    for n in range(1, 6):
        vn, _ = loop_subdivide(v, f, n, limit=False)
        gaps.append(np.abs(vn[:len(v)] - target).max())
    ratios = [a / b for a, b in zip(gaps, gaps[1:])]
    assert all(2.5 < r < 6 for r in ratios), ratios
    # the limit of the unit icosahedron lies inside it and, by symmetry, on a sphere at its vertices
    radii = np.linalg.norm(target, axis=1)
    assert np.allclose(radii, radii[0]) and 0.7 < radii[0] < 1.0
    vl, fl = loop_subdivide(v, f, 4)
    assert volume(vl, fl) < volume(v, f)  # subdivision of a convex mesh shrinks it


def test_boundary_rules():
    """An open mesh: boundary vertices move along the boundary only (3/4, 1/8, 1/8), boundary edges
    split at their midpoints, a flat mesh stays in its plane, and a boundary vertex's limit point
    is pbrt-v4's 3/5 v + 1/5 (its boundary neighbours) (loopsubdiv.cpp, weightBoundary(v, 1/5))."""
    v = np.array([[0, 0, 0], [1, 0, 0], [1, 1, 0], [0, 1, 0]], np.float64)
    f = np.array([[0, 1, 2], [0, 2, 3]])
    v2, f2 = subdivide_once(v, f)
    assert np.allclose(v2[0], 0.75 * v[0] + 0.125 * (v[1] + v[3]))
    assert any(np.allclose(x, [0.5, 0, 0]) for x in v2[4:])
    vl, fl = loop_subdivide(v, f, 3)
    assert np.allclose(vl[:, 2], 0) and len(fl) == 2 * 64
    assert np.allclose(loop_subdivide(v, f, 0)[0][0], 0.6 * v[0] + 0.2 * (v[1] + v[3]))
    assert np.allclose(vertex_normals(vl, fl), [0, 0, 1]) and np.allclose(limit_normals(vl, fl), [0, 0, 1])


def test_limit_normals_of_an_affine_mesh_are_its_plane_s():
    """pbrt's tangent masks (interior cos / sin, boundary by valence) have weights that sum to 0, so
    on a mesh whose points lie on a plane both tangents lie in it: the normal is the plane's
    exactly, at every vertex, interior or boundary, whatever its valence."""
    rng = np.random.default_rng(3)
    xy = np.array([[0, 0], [1, 0], [2, 0], [0, 1], [1, 1], [2, 1], [0, 2], [1, 2], [2, 2], [1.4, 0.6]], np.float64)
    f = np.array([[0, 1, 4], [0, 4, 3], [1, 2, 5], [1, 5, 9], [1, 9, 4], [9, 5, 4], [3, 4, 7], [3, 7, 6],
                  [4, 5, 8], [4, 8, 7]])
    xy += rng.uniform(-0.1, 0.1, xy.shape)
    plane = np.array([0.3, -0.7, 1.0])  # z = 0.3 x - 0.7 y
    v = np.column_stack([xy, xy @ np.array([0.3, -0.7])])
    for levels in (0, 1, 2):
        vl, fl = loop_subdivide(v, f, levels)
        n = limit_normals(vl, fl)
        expected = np.array([-0.3, 0.7, 1.0]) / np.linalg.norm([-0.3, 0.7, 1.0])
        assert np.allclose(n, expected, atol=1e-9), levels


def test_limit_normals_are_the_limit_of_finer_vertex_normals():
    """Vertex i of one level is vertex i of the next: the normals of a finer level's triangles
    around it approach the limit surface's normal, which the tangent masks give exactly when they
    are applied to the control points (before the limit projection; pbrt applies them after it,
    as the loader does, which tilts them by up to 0.23 degrees here)."""
    control, f2 = loop_subdivide(*icosahedron(), 2, limit=False)
    v6, f6 = loop_subdivide(*icosahedron(), 6)
    fine = vertex_normals(v6, f6)[:len(control)]

    def angles(n):
        return np.degrees(np.arccos(np.clip(np.einsum("ij,ij->i", n, fine), -1, 1)))

    assert angles(limit_normals(control, f2)).max() < 0.01
    projected = limit_positions(control, f2)
    assert 0.1 < angles(limit_normals(projected, f2)).max() < 0.3
    assert angles(vertex_normals(projected, f2)).max() > 0.5  # what the loader used before


def test_non_manifold_is_an_error():
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, -1, 0], [0, 0, 1]], np.float64)
    with pytest.raises(SubdivisionError, match="more than two triangles"):
        subdivide_once(v, np.array([[0, 1, 2], [1, 0, 3], [0, 1, 4]]))


def test_normals_point_out_of_a_sphere_like_limit():
    v, f = loop_subdivide(*icosahedron(), 3)
    n = vertex_normals(v, f)
    radial = v / np.linalg.norm(v, axis=1, keepdims=True)
    assert np.einsum("ij,ij->i", n, radial).min() > 0.95
