"""Whole traversal (BVH + triangle test) against Embree in its robust (watertight) mode, and
against brute force in float64, on every available device and for every BVH layout (binary:
cl/accel/bvh.h; wide: cl/accel/bvh_wide.h; wide8: cl/accel/bvh_wide8.h), held to identical bounds."""
import numpy as np
import pytest

from meshes import MESHES, coherent_rays, incoherent_rays, moller_trumbore, ray_edge_distance
from pyopencl_rt import build_bvh, occluded, trace

N_COHERENT = 500_000
N_INCOHERENT = 500_000  # 1M rays per mesh in all


def edge_distance(vertices, faces, prim, o, d):
    """Relative distance from each ray to the nearest edge of triangle ``prim`` (see
    meshes.ray_edge_distance)."""
    return ray_edge_distance(o, d, vertices[faces[prim]])


def brute_force_hit(vertices, faces, o, d):
    """float64 Möller–Trumbore over every triangle: does each ray hit anything at t > 0, and how
    far inside its closest triangle does it pass (min barycentric)?"""
    p = vertices[faces].astype(np.float64)
    hit = np.zeros(len(o), bool)
    margin = np.full(len(o), -np.inf)
    for i in range(len(o)):
        t, _, _, inside = moller_trumbore(o[i], d[i], p)
        ok = (inside >= 0) & (t > 0)
        hit[i] = ok.any()
        if hit[i]:
            margin[i] = inside[ok][np.argmin(t[ok])]
    return hit, margin


@pytest.fixture(params=["binary", "wide", "wide8"])
def layout(request):
    return request.param


@pytest.fixture(scope="module")
def bvhs():
    return {name: (make(), build_bvh(*make())) for name, make in MESHES.items()}


# a second implementation (Intel's CPU runtime beside PoCL, tests/conftest.py) compiles the same traversal:
# in `make test` every layout on the random soup and the slivers (the meshes differ in data, not in code)
SECOND_IMPLEMENTATION = {"test_closest_hit_matches_embree": lambda params, device: params["mesh"] in ("soup", "slivers")}


@pytest.mark.parametrize("mesh", list(MESHES))
def test_closest_hit_matches_embree(device, layout, bvhs, mesh, rng):
    (v, f), bvh = bvhs[mesh]
    o1, d1 = coherent_rays(v, N_COHERENT)
    o2, d2 = incoherent_rays(v, f, N_INCOHERENT, rng)
    o, d = np.concatenate([o1, o2]), np.concatenate([d1, d2])
    n = len(o)
    ours = trace(bvh, o, d, device=device, layout=layout)
    ref = trace(bvh, o, d, backend="embree")
    hit, ref_hit = ours["prim_id"] >= 0, ref["prim_id"] >= 0

    # 1. hit/miss: >= 99.999% agreement, and every disagreement within 1e-6 (relative) of an edge
    disagree = np.nonzero(hit != ref_hit)[0]
    # Rays aimed exactly at edges and vertices (half the incoherent set) may just graze a convex
    # corner: hit and miss are both right there, so the 99.999% bound applies to the other rays.
    aimed = np.zeros(n, bool)
    aimed[len(o1) + N_INCOHERENT // 2:] = True
    assert (~aimed[disagree]).sum() <= (~aimed).sum() * 1e-5, f"{mesh}: {len(disagree)} disagreements"
    if len(disagree):
        prim = np.where(hit[disagree], ours["prim_id"][disagree], ref["prim_id"][disagree])
        edge = edge_distance(v, f, prim, o[disagree], d[disagree])
        far = disagree[edge > 1e-6]
        # away from edges, float64 brute force decides, and we must be the one that is right
        truth, _ = brute_force_hit(v, f, o[far[:200]], d[far[:200]])
        assert len(far) <= 200 and (hit[far] == truth).all(), f"{mesh}: {len(far)} disagreements away from edges"
        embree_wrong = len(far)
    else:
        embree_wrong = 0
    print(f"{mesh}: {n} rays, {hit.sum()} hits, {len(disagree)} hit/miss disagreements: "
          f"{len(disagree) - embree_wrong} within 1e-6 of an edge, {embree_wrong} where float64 sides with us")

    # 2. t: relative error <= 1e-5, relative to the magnitude of the coordinates involved, for
    #    rays that are not grazing (|cos| >= 0.01: at grazing angles t is ill-conditioned, and
    #    where we looked, ours was the nearer of the two to float64)
    cos_all = np.abs(np.sum(ref["normal"] * d, axis=1)) / np.linalg.norm(d, axis=1)
    both = hit & ref_hit & (cos_all >= 0.01)
    scale = (np.abs(o[both]).max(1) + ref["t"][both] * np.linalg.norm(d[both], axis=1)) / np.linalg.norm(d[both], axis=1)
    t_err = np.abs(ours["t"][both] - ref["t"][both]) / scale
    off = np.nonzero(both)[0][t_err > 1e-5]
    if len(off):  # allowed only where one of the two hits grazes an edge (a different surface point)
        edge = np.minimum(edge_distance(v, f, ours["prim_id"][off], o[off], d[off]),
                          edge_distance(v, f, ref["prim_id"][off], o[off], d[off]))
        assert (edge <= 1e-6).all(), f"{mesh}: t error {t_err.max():.3g} away from edges"
    print(f"{mesh}: median t error {np.median(t_err):.2g}, {len(off)} edge-grazing rays with another t")

    # 3. the same triangle wherever the hit is unambiguous: a different prim_id is allowed only
    #    where the ray grazes an edge of either triangle, or where both are hit at the same t (a tie)
    diff = np.nonzero(both & (ours["prim_id"] != ref["prim_id"]))[0]
    if len(diff):
        edge = np.minimum(edge_distance(v, f, ref["prim_id"][diff], o[diff], d[diff]),
                          edge_distance(v, f, ours["prim_id"][diff], o[diff], d[diff]))
        tie = np.abs(ours["t"][diff] - ref["t"][diff]) / scale[np.searchsorted(np.nonzero(both)[0], diff)] <= 1e-5
        clear = (edge > 1e-6) & ~tie
        assert not clear.any(), f"{mesh}: {clear.sum()} unambiguous hits on a different triangle"
    # 4. normals and barycentrics of the same triangle agree
    # barycentrics against float64 on our triangle, off grazing angles (|cos| > 0.1), with a
    # tolerance for the triangle's conditioning: float32 coordinates of magnitude M move the hit
    # point by ~M * 1e-7, i.e. by that over the smallest height in barycentric terms
    steep = np.nonzero(hit & (np.abs(np.sum(ours["normal"] * d, axis=1)) / np.linalg.norm(d, axis=1) > 0.1))[0]
    p = v[f[ours["prim_id"][steep]]].astype(np.float64)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    dd, tv = d[steep].astype(np.float64), o[steep].astype(np.float64) - p[:, 0]
    pvec = np.cross(dd, e2)
    det = np.sum(e1 * pvec, 1)
    u64 = np.sum(tv * pvec, 1) / det
    v64 = np.sum(dd * np.cross(tv, e1), 1) / det
    double_area = np.linalg.norm(np.cross(e1, e2), axis=1)
    longest = np.max(np.stack([np.linalg.norm(e1, axis=1), np.linalg.norm(e2, axis=1),
                               np.linalg.norm(p[:, 2] - p[:, 1], axis=1)]), axis=0)
    min_height = double_area / longest
    magnitude = np.abs(o[steep]).max(1) + np.abs(p).max((1, 2))
    tol = 1e-4 + 1e-6 * magnitude / min_height
    assert (np.abs(ours["u"][steep] - u64) <= tol).all()
    assert (np.abs(ours["v"][steep] - v64) <= tol).all()


@pytest.mark.parametrize("mesh", ["torus", "grid"])
def test_any_hit_matches_embree(device, layout, bvhs, mesh, rng):
    (v, f), bvh = bvhs[mesh]
    o, d = incoherent_rays(v, f, 300_000, rng)
    tmax = rng.uniform(0, 3, len(o)).astype(np.float32)
    ours = occluded(bvh, o, d, tmax=tmax, device=device, layout=layout)
    ref = occluded(bvh, o, d, tmax=tmax, backend="embree")
    # rays whose closest hit lies within 1e-5 of tmax are a tie between "hit" and "miss"
    closest = trace(bvh, o, d, backend="embree")["t"]
    tie = np.abs(closest - tmax) <= 1e-5 * (1 + tmax)
    disagree = (ours != ref) & ~tie
    # the second half of the set is aimed exactly at edges and vertices, where grazing rays
    # may legitimately go either way (see test_closest_hit_matches_embree)
    half = len(o) // 2
    assert disagree[:half].sum() <= half * 1e-5
    assert disagree[half:].sum() <= half * 1e-2  # measured ~1.1e-3; a systematic fault gives far more
    assert 0.05 < ours.mean() < 0.95  # the set exercises both answers


def test_tmin_tmax_against_brute_force(device, layout, rng):
    """A small scene traced with random [tmin, tmax] windows: every answer equals a float64 brute
    force over all triangles (closest t inside the window)."""
    v, f = MESHES["soup"](n=300, seed=5)
    bvh = build_bvh(v, f)
    n = 20_000
    o = rng.uniform(-1.2, 1.2, (n, 3)).astype(np.float32)
    d = rng.normal(size=(n, 3)).astype(np.float32)
    tmin = rng.uniform(0, 1, n).astype(np.float32)
    tmax = (tmin + rng.uniform(0, 2, n)).astype(np.float32)
    ours = trace(bvh, o, d, tmin=tmin, tmax=tmax, device=device, layout=layout)
    p = v[f].astype(np.float64)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    best_t = np.full(n, np.inf)
    best_b = np.full(n, np.inf)  # distance to an edge of the best triangle, in barycentrics
    for chunk in np.array_split(np.arange(n), 20):
        dd = d[chunk, None, :].astype(np.float64)
        pvec = np.cross(dd, e2[None])
        det = np.sum(e1[None] * pvec, -1)
        tvec = o[chunk, None, :].astype(np.float64) - p[None, :, 0]
        u = np.sum(tvec * pvec, -1) / det
        qv = np.cross(tvec, e1[None])
        vv = np.sum(dd * qv, -1) / det
        t = np.sum(e2[None] * qv, -1) / det
        inside = np.minimum(np.minimum(u, vv), 1 - u - vv)
        ok = (inside >= 0) & (t > tmin[chunk, None]) & (t < tmax[chunk, None])
        t = np.where(ok, t, np.inf)
        j = np.argmin(t, axis=1)
        best_t[chunk] = t[np.arange(len(chunk)), j]
        best_b[chunk] = inside[np.arange(len(chunk)), j]
    ref_hit = np.isfinite(best_t)
    hit = ours["prim_id"] >= 0
    window_tie = (np.abs(best_t - tmin) < 1e-5) | (np.abs(best_t - tmax) < 1e-5)
    bad = (hit != ref_hit) & ~(np.abs(best_b) < 1e-6) & ~window_tie
    assert bad.sum() == 0
    both = hit & ref_hit
    assert np.allclose(ours["t"][both], best_t[both], rtol=1e-5, atol=1e-6)
    assert ((ours["t"][hit] > tmin[hit]) & (ours["t"][hit] < tmax[hit])).all()


def test_degenerate_trees(device, layout):
    """An empty mesh misses everything; a single triangle (one leaf at the root) is hit."""
    empty = build_bvh(np.zeros((0, 3), np.float32), np.zeros((0, 3), np.int32))
    res = trace(empty, [[0, 0, -1]], [[0, 0, 1]], device=device, layout=layout)
    assert res["prim_id"][0] == -1 and res["t"][0] == np.inf
    one = build_bvh(np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]], np.int32))
    res = trace(one, [[0.25, 0.25, -1]], [[0, 0, 1]], device=device, layout=layout)
    assert res["prim_id"][0] == 0 and res["t"][0] == 1.0
    assert res["u"][0] == 0.25 and res["v"][0] == 0.25
    assert res["normal"][0].tolist() == [0.0, 0.0, 1.0]
