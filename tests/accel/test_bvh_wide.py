"""The 4-wide and 8-wide BVHs (pyopencl_rt/accel/bvh_wide.py, cl/accel/bvh_wide.h, bvh_wide8.h):
structural invariants, a float64 reference traversal of the wide trees against brute force, and the
OpenCL wide traversals against that reference and against the binary traversal.  The
Embree-agreement checks for the wide layouts are tests/accel/test_traversal.py's, parametrised over
every layout."""
import numpy as np
import pytest

from meshes import MESHES, coherent_rays, incoherent_rays
from pyopencl_rt import build_bvh, occluded, trace
from pyopencl_rt.accel.bvh_validate import validate
from pyopencl_rt.accel.bvh_wide import STACK_SIZE, build_wide, device_blob, max_wide_depth, wide_bvh
from pyopencl_rt.accel.bvh_wide_validate import reference_closest_hit, validate_wide
from pyopencl_rt.device import abi
from pyopencl_rt.errors import UserError
from pyopencl_rt.accel.device_bvh import LAYOUT_WIDTHS, bvh_layout

import harness

WIDE_LAYOUTS = ["wide", "wide8"]
WIDTHS = [4, 8]
STACKS = {4: abi.WIDE_STACK_SIZE, 8: abi.WIDE8_STACK_SIZE}


def soup_of(n, seed=0):
    rng = np.random.default_rng(seed)
    v = rng.normal(size=(3 * n, 3)).astype(np.float32)
    return v, np.arange(3 * n, dtype=np.int32).reshape(-1, 3)


def brute_force(vertices, faces, o, d):
    """float64 Moller-Trumbore over every triangle: closest t > 0 (inf on a miss) and the
    smallest barycentric of that hit."""
    p = vertices[faces].astype(np.float64)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    best_t, best_m = np.full(len(o), np.inf), np.full(len(o), -np.inf)
    for chunk in np.array_split(np.arange(len(o)), max(1, len(o) // 50)):
        dd = d[chunk, None].astype(np.float64)
        pvec = np.cross(dd, e2[None])
        det = np.sum(e1[None] * pvec, -1)
        tv = o[chunk, None].astype(np.float64) - p[None, :, 0]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = np.sum(tv * pvec, -1) / det
            qv = np.cross(tv, e1[None])
            w = np.sum(dd * qv, -1) / det
            t = np.sum(e2[None] * qv, -1) / det
        m = np.minimum(np.minimum(u, w), 1 - u - w)
        t = np.where((m >= 0) & (t > 0), t, np.inf)
        j = np.argmin(t, 1)
        best_t[chunk] = t[np.arange(len(chunk)), j]
        best_m[chunk] = m[np.arange(len(chunk)), j]
    return best_t, best_m


def barycentric_margin(vertices, faces, prim, o, d):
    """float64: the smallest barycentric coordinate of ray i's crossing of triangle prim[i]'s plane."""
    p = vertices[faces[prim]].astype(np.float64)
    e1, e2 = p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]
    dd = d.astype(np.float64)
    pvec = np.cross(dd, e2)
    det = np.sum(e1 * pvec, 1)
    tv = o.astype(np.float64) - p[:, 0]
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.sum(tv * pvec, 1) / det
        w = np.sum(dd * np.cross(tv, e1), 1) / det
    return np.minimum(np.minimum(u, w), 1 - u - w)


# ---------------------------------------------------------------------------------------------
# structure
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("mesh", list(MESHES))
def test_validate_meshes(mesh, width):
    v, f = MESHES[mesh]()
    bvh = build_bvh(v, f)
    wide = build_wide(bvh, width)
    validate_wide(wide, bvh)
    assert wide.depth <= bvh.stats["depth"]
    assert 2.0 <= wide.stats["children_per_node"] <= width
    # the device copy: nodes then packets, boxes padded outwards, empty slots left empty
    blob = device_blob(wide)
    assert blob.nbytes == wide.nodes.nbytes + wide.packets.nbytes
    padded = blob[:wide.nodes.nbytes].view(wide.nodes.dtype)
    present = wide.nodes["count"] >= 0
    for c in "xyz":
        assert (padded[f"bmin_{c}"][present] < wide.nodes[f"bmin_{c}"][present]).all()
        assert (padded[f"bmax_{c}"][present] > wide.nodes[f"bmax_{c}"][present]).all()
        assert (padded[f"bmin_{c}"][~present] == np.inf).all()
    assert np.array_equal(blob[wide.nodes.nbytes:], wide.packets.view(np.uint8))


@pytest.mark.parametrize("width", WIDTHS)
@pytest.mark.parametrize("n", [0, 1, 2, 3, 4, 5, 9, 17])
def test_validate_small(n, width):
    v, f = soup_of(n, seed=n)
    bvh = build_bvh(v, f)
    wide = build_wide(bvh, width)
    validate_wide(wide, bvh)
    assert (wide.packets["tri"] >= 0).sum() == n
    if width == 8 and 0 < n <= 8:  # a mesh of up to 8 triangles is one leaf, one Tri8 packet
        assert len(wide.packets) == 1 and (wide.nodes["count"][0] > 0).sum() == 1


def test_validate_degenerate_and_deep():
    # all triangles degenerate (zero area; some collapsed to a point), many coincident
    rng = np.random.default_rng(1)
    a = rng.normal(size=(500, 3)).astype(np.float32)
    v = np.concatenate([a, a, 2 * a, np.zeros((1, 3), np.float32)])
    f = np.concatenate([np.stack([np.arange(500), np.arange(500) + 500, np.arange(500) + 1000], 1),
                        np.full((50, 3), 1500)]).astype(np.int32)
    bvh = build_bvh(v, f)
    validate(bvh)
    wide = build_wide(bvh)
    validate_wide(wide, bvh)
    # degenerate triangles are never hit
    o = rng.normal(size=(2000, 3)).astype(np.float32) * 3
    d = rng.normal(size=(2000, 3)).astype(np.float32)
    assert (reference_closest_hit(wide, o, d)[1] == -1).all()
    # a geometric series of sizes gives a deep binary BVH; the wide depth stays within the stack
    k = np.arange(2000)
    c = (1.02 ** k)[:, None] * np.array([1.0, 0.5, 0.25])
    tri = c[:, None, :] + np.array([[0, 0, 0], [1e-3, 0, 0], [0, 1e-3, 0]])[None] * (1.02 ** k)[:, None, None]
    bvh = build_bvh(tri.reshape(-1, 3).astype(np.float32), np.arange(6000, dtype=np.int32).reshape(-1, 3))
    for width in WIDTHS:
        wide = build_wide(bvh, width)
        validate_wide(wide, bvh)
        # every wide level descends log2(width) binary levels: the depth bound the stack relies on
        levels = {4: 2, 8: 3}[width]
        assert wide.depth <= -(-bvh.stats["depth"] // levels) <= max_wide_depth(width)
        assert (width - 1) * max_wide_depth(width) + 1 <= STACKS[width]
    assert 3 * max_wide_depth(4) + 1 <= STACK_SIZE


@pytest.mark.parametrize("width", WIDTHS)
def test_validate_catches_corruption(width):
    v, f = MESHES["soup"](n=500)
    bvh = build_bvh(v, f)
    wide = build_wide(bvh, width)
    validate_wide(wide, bvh)
    pad = np.argwhere(wide.packets["tri"] < 0)
    bad = build_wide(bvh, width)
    if len(pad):  # a padding lane holding a real triangle's vertices is not inert
        p, k = pad[0]
        for name in ("v0x", "v0y", "v0z", "v1x", "v1y", "v1z", "v2x", "v2y", "v2z"):
            bad.packets[name][p, k] = 0.0
        with pytest.raises(AssertionError, match="padding"):
            validate_wide(bad, bvh)
    bad = build_wide(bvh, width)
    leaf = np.argwhere(bad.nodes["count"] > 0)[0]
    bad.nodes["bmax_x"][tuple(leaf)] = np.nextafter(bad.nodes["bmax_x"][tuple(leaf)], np.float32(-np.inf))
    with pytest.raises(AssertionError, match="box"):
        validate_wide(bad, bvh)
    bad = build_wide(bvh, width)
    t = bad.packets["tri"]
    real = np.argwhere(t >= 0)
    t[tuple(real[0])] = t[tuple(real[1])]  # one triangle twice, one missing
    with pytest.raises(AssertionError, match="exactly once"):
        validate_wide(bad, bvh)


def test_collapse_is_fast():
    from pyopencl_rt.bench.workloads import bumpy_torus

    bvh = build_bvh(*bumpy_torus(100_000))
    for width in WIDTHS:
        wide = build_wide(bvh, width)
        assert wide.stats["build_seconds"] < 0.5   # ~0.03-0.07 s measured; 1M triangles ~0.3-0.6 s


# ---------------------------------------------------------------------------------------------
# the float64 reference traversal of the wide tree against brute force
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("mesh", ["icosphere", "soup", "slivers"])
def test_reference_traversal_matches_brute_force(mesh, rng):
    v, f = MESHES[mesh]()
    bvh = build_bvh(v, f)
    o, d = incoherent_rays(v, f, 600, rng)
    t_bf, m_bf = brute_force(v, f, o, d)
    for width in WIDTHS:
        t_ref, tri, margin = reference_closest_hit(build_wide(bvh, width), o, d)
        clear = np.minimum(np.abs(margin), np.abs(m_bf)) > 1e-9   # away from edges: no hit/miss ambiguity
        clear &= ~np.isfinite(t_bf) | (m_bf > 1e-9)
        assert np.array_equal(np.isfinite(t_ref)[clear], np.isfinite(t_bf)[clear])
        both = np.isfinite(t_ref) & np.isfinite(t_bf)
        assert np.allclose(t_ref[both], t_bf[both], rtol=1e-9)
        assert ((tri >= 0) == np.isfinite(t_ref)).all()
        assert 0.05 < np.isfinite(t_ref).mean() < 0.95


# ---------------------------------------------------------------------------------------------
# the OpenCL wide traversal
# ---------------------------------------------------------------------------------------------
@pytest.mark.parametrize("layout", WIDE_LAYOUTS)
@pytest.mark.parametrize("mesh", ["icosphere", "soup", "grid"])
def test_opencl_wide_matches_reference(device, mesh, layout, rng):
    v, f = MESHES[mesh]()
    bvh = build_bvh(v, f)
    o, d = incoherent_rays(v, f, 4000, rng)
    ours = trace(bvh, o, d, device=device, layout=layout)
    t_ref, tri, margin = reference_closest_hit(wide_bvh(bvh, LAYOUT_WIDTHS[layout]), o, d)
    hit = ours["prim_id"] >= 0
    ref_hit = tri >= 0
    # a hit/miss disagreement only where the hit (ours or the reference's) passes within 1e-4
    # (barycentric) of an edge of its triangle (float32 rounding alone puts the rays aimed at
    # vertices and edges, half of incoherent_rays, ~1e-5 off their target), or grazes it
    # (|cos| < 0.05: there the float64 barycentrics are ill-conditioned too)
    prim = np.where(hit, ours["prim_id"], np.where(ref_hit, bvh.prim_ids[np.maximum(tri, 0)], 0))
    m64 = barycentric_margin(v, f, prim, o, d)
    p = v[f[prim]].astype(np.float64)
    n = np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0])
    cos = np.abs(np.sum(n * d, 1)) / np.linalg.norm(n, axis=1) / np.linalg.norm(d, axis=1)
    ambiguous = (np.abs(m64) <= 1e-4) | (cos < 0.05)
    disagree = hit != ref_hit
    assert not (disagree & ~ambiguous).any()
    assert disagree.sum() <= 5e-3 * len(o)
    # where both hit away from edges, the same t; and the same triangle unless the two hits tie
    # (several triangles share the vertex)
    both = hit & ref_hit & (cos >= 0.05) & (np.abs(m64) > 1e-4) & (np.abs(margin) > 1e-4)
    assert np.allclose(ours["t"][both], t_ref[both], rtol=1e-5, atol=1e-6)
    tie = np.abs(ours["t"] - t_ref) <= 1e-5 * np.abs(t_ref)
    assert (ours["prim_id"][both & ~tie] == bvh.prim_ids[tri[both & ~tie]]).all()


@pytest.mark.parametrize("layout", WIDE_LAYOUTS)
@pytest.mark.parametrize("mesh", list(MESHES))
def test_wide_equals_binary(device, mesh, layout, rng):
    """Per lane the Tri4 and Tri8 tests do the scalar test's arithmetic: wherever the two layouts
    report the same triangle, t, u, v and the normal are bit-identical; a different triangle only
    at a tie or an edge-grazing ray (a handful in 40k rays); any hit identical."""
    v, f = MESHES[mesh]()
    bvh = build_bvh(v, f)
    o1, d1 = coherent_rays(v, 20_000)
    o2, d2 = incoherent_rays(v, f, 20_000, rng)
    o, d = np.concatenate([o1, o2]), np.concatenate([d1, d2])
    a = trace(bvh, o, d, device=device, layout="binary")
    w = trace(bvh, o, d, device=device, layout=layout)
    same = a["prim_id"] == w["prim_id"]
    for k in ("t", "u", "v", "normal"):
        assert np.array_equal(a[k][same], w[k][same]), k
    assert (~same).sum() <= 2e-3 * len(o)
    with np.errstate(invalid="ignore"):  # inf - inf where both miss
        tie = np.abs(a["t"] - w["t"]) <= 1e-5 * (1 + np.abs(a["t"]))
    assert (~same & ~tie).sum() <= 2e-4 * len(o)
    tmax = rng.uniform(0, 3, len(o)).astype(np.float32)
    oa = occluded(bvh, o, d, tmax=tmax, device=device, layout="binary")
    ow = occluded(bvh, o, d, tmax=tmax, device=device, layout=layout)
    assert (oa != ow).sum() <= 1e-4 * len(o)


@pytest.mark.parametrize("layout", WIDE_LAYOUTS)
def test_padding_lanes_never_hit(device, layout):
    """One triangle per leaf packet (three or seven NaN lanes); rays from everywhere, aimed at the
    triangle's vertices, edges and at nothing: only the real lane ever answers."""
    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32)
    f = np.array([[0, 1, 2]], np.int32)
    bvh = build_bvh(v, f)
    width = LAYOUT_WIDTHS[layout]
    assert (build_wide(bvh, width).packets["tri"] == [[0] + [-1] * (width - 1)]).all()
    rng = np.random.default_rng(3)
    n = 50_000
    target = rng.uniform(-0.5, 1.5, (n, 3)) * [1, 1, 0]
    target[: n // 4] = v[rng.integers(0, 3, n // 4)]
    d = rng.normal(size=(n, 3))
    o = (target - 3 * d).astype(np.float32)
    res = trace(bvh, o, d.astype(np.float32), device=device, layout=layout)
    assert set(np.unique(res["prim_id"])) <= {-1, 0}
    inside = (target[:, 0] > 1e-3) & (target[:, 1] > 1e-3) & (target[:, 0] + target[:, 1] < 1 - 1e-3)
    assert (res["prim_id"][inside] == 0).all() and (res["prim_id"][~inside & (np.arange(n) >= n // 4)] == -1).mean() > 0.99


def test_layout_selection(device, monkeypatch):
    import pyopencl as cl

    monkeypatch.delenv("PYOPENCL_RT_BVH_LAYOUT", raising=False)
    expect = "wide8" if device.type & cl.device_type.CPU else "binary"  # 8-wide won on CPUs (docs/BENCHMARKS.md)
    assert bvh_layout(device) == expect
    assert bvh_layout(device, "binary") == "binary"
    monkeypatch.setenv("PYOPENCL_RT_BVH_LAYOUT", "binary")
    assert bvh_layout(device) == "binary"
    assert bvh_layout(device, "wide") == "wide"     # the argument wins over the environment
    assert bvh_layout(device, "wide8") == "wide8"
    monkeypatch.setenv("PYOPENCL_RT_BVH_LAYOUT", "wide")
    assert bvh_layout(device) == "wide"
    monkeypatch.setenv("PYOPENCL_RT_BVH_LAYOUT", "quad")
    with pytest.raises(UserError):
        bvh_layout(device)


def test_small_subtrees_merged():
    """8-wide: every binary subtree of at most 8 triangles is one leaf (one Tri8 packet), so no inner
    node holds 8 triangles or fewer, and every leaf of more than 8 triangles is a binary leaf (the
    builder's SAH leaves, up to 64 triangles), i.e. leaves are never split or merged beyond that."""
    v, f = MESHES["torus"]()
    bvh = build_bvh(v, f)
    wide = build_wide(bvh, 8)
    validate_wide(wide, bvh)
    N = len(wide.nodes)
    count = wide.nodes["count"].astype(np.int64)
    child = wide.nodes["child"].astype(np.int64)
    real = (wide.packets["tri"] >= 0).sum(1)
    pk = np.where(count > 0, (child - wide.node_units * N) // wide.packet_units, 0)
    leaf_tris = np.zeros(count.shape, np.int64)
    for k in range(int(count.max())):   # triangles of each leaf slot: real lanes of its packets
        leaf_tris += np.where(count > k, real[np.minimum(pk + k, len(real) - 1)], 0)
    # triangles below each node, bottom-up (children have larger indices: BFS order)
    below = np.zeros(N, np.int64)
    inner = count == 0
    for n in range(N - 1, -1, -1):
        below[n] = leaf_tris[n].sum() + below[child[n][inner[n]] // wide.node_units].sum()
    assert below[0] == len(f)
    assert (below[1:] > 8).all()                       # an inner node of <= 8 triangles was not merged
    binary_leaves = set(bvh.stats["leaf_size_histogram"])
    big = leaf_tris[count > 0]
    assert set(big[big > 8].tolist()) <= binary_leaves
    assert 0.6 < wide.stats["lane_fill"] <= 1.0


SORT = harness.Kernels(r'''
#include "accel/bvh_wide8.h"
__kernel void h_sort8(__global const float8 *keys, __global float8 *out_keys, __global int8 *out_lanes)
{
    const int i = get_global_id(0);
    float8 k = keys[i];
    int8 l = (int8)(0, 1, 2, 3, 4, 5, 6, 7);
    sort8(&k, &l);
    out_keys[i] = k; out_lanes[i] = l;
}
__kernel void h_sort4(__global const float4 *keys, __global float4 *out_keys, __global int4 *out_lanes)
{
    const int i = get_global_id(0);
    float4 k = keys[i];
    int4 l = (int4)(0, 1, 2, 3);
    sort4(&k, &l);
    out_keys[i] = k; out_lanes[i] = l;
}
__kernel void h_bits8(__global const int8 *m, __global int *bits, __global int *any)
{
    const int i = get_global_id(0);
    bits[i] = mask_bits8(m[i]); any[i] = any8(m[i]);
}
''', defines={"BVH_WIDE8": True})


@pytest.mark.parametrize("width", WIDTHS)
def test_sorting_networks(runtime, width):
    """sort4 / sort8 (the closest-hit child order) return the keys ascending and their lanes as a
    permutation with key[lane] equal to the sorted key, with ties and +inf (missed children)."""
    rng = np.random.default_rng(5)
    n = 4096
    keys = rng.integers(0, 6, (n, width)).astype(np.float32)     # many ties
    keys[rng.random((n, width)) < 0.3] = np.inf
    keys[: n // 2] = rng.normal(size=(n // 2, width)).astype(np.float32)
    out_k, out_l = SORT(runtime, f"h_sort{width}", n, keys.ravel(), out_keys=n * width, out_lanes=n * width)
    out_k, out_l = out_k.reshape(n, width), out_l.reshape(n, width)
    assert np.array_equal(out_k, np.sort(keys, axis=1))
    assert (np.sort(out_l, axis=1) == np.arange(width)).all()
    assert np.array_equal(np.take_along_axis(keys, out_l, 1), out_k)


def test_mask_bits8(runtime):
    rng = np.random.default_rng(6)
    m = -(rng.random((2048, 8)) < 0.3).astype(np.int32)
    m[:8] = 0
    bits, anyset = SORT(runtime, "h_bits8", len(m), m.ravel(), bits=len(m), any=len(m))
    assert np.array_equal(bits, (m != 0).astype(np.int64) @ (1 << np.arange(8)))
    assert np.array_equal(anyset != 0, (m != 0).any(1))
