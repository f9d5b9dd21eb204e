"""The light BVH of RenderSettings.light_sampler "bvh" (Conty Estevez & Kulla 2018, "Importance
Sampling of Many Lights with Adaptive Tree Splitting"; pbrt-v4's BVHLightSampler is the design
followed): a binary tree over the lights that are not infinitely far, each node bounding its
lights by the sphere around their box, a cone of emission directions (axis, cos theta_o: the
normals' spread, cos theta_e: how far past a normal light leaves), their summed power phi and
whether any emits from both sides.  cl/render/light_tree.h descends it from the root, at each inner node taking a child
with probability proportional to its importance to the shading point p (and its normal n), so that
a light's pick probability is the product of the choices along its path; the path is stored per
light (Light.trail, bit d: the second child at depth d) so that the pmf of a light that a BSDF
sample hit is the same walk again.  The infinitely distant lights stay in the alias table, picked
with pbrt-v4's fixed share (render/lights.py selection_weights); the tree gets the rest, which
each bounded light's Light.pmf holds in this mode.

:func:`importance` and :func:`tree_pmfs` are the float64 references of the kernel's functions
(tests/render/test_light_tree.py)."""
from __future__ import annotations

import math

import numpy as np

from ..device import abi
from ..scene.shapes import bounds as shape_bounds, unit_rows as shape_unit_rows

BUCKETS = 12  # split candidates per axis (pbrt-v4's count)
MAX_DEPTH = 30  # Light.trail holds a leaf's path in the bits of an int32 (depth 0..30)
SAOH_MIN = 16  # fewer lights than this are split at the median (the heuristic's cost, in numpy, is per node)


def light_bounds(lights, triangles, shapes, two_sided_material, power) -> dict:
    """Per light (float64): lo, hi (its box), axis, cos_o, cos_e, phi, two_sided.  Triangles emit
    around their geometric normal cross(v1 - v0, v2 - v0) (cos_o 1, cos_e 0: a hemisphere); an
    analytic shape in the cone its type gives (a disk as a triangle, a sphere every direction);
    point, spot and projector lights in every direction (cos_o -1; a spot's cone is not used: its
    frame may be sheared, and a looser bound costs efficiency, not correctness)."""
    n = len(lights)
    kind = lights["kind"]
    lo = np.asarray(lights["p"], np.float64).copy()
    hi = lo.copy()
    axis = np.tile([0.0, 0.0, 1.0], (n, 1))
    cos_o = np.full(n, -1.0)
    cos_e = np.zeros(n)
    two_sided = np.zeros(n, bool)
    tri = np.flatnonzero(np.isin(kind, abi.TRIANGLE_LIGHTS))  # a directional area light: bounded as a triangle
    if len(tri):
        prim = lights["prim"][tri]
        v = [np.asarray(triangles[k][prim, :3], np.float64) for k in ("v0", "v1", "v2")]
        lo[tri] = np.minimum(np.minimum(v[0], v[1]), v[2])
        hi[tri] = np.maximum(np.maximum(v[0], v[1]), v[2])
        ng = np.cross(v[1] - v[0], v[2] - v[0])
        axis[tri] = ng / np.linalg.norm(ng, axis=1, keepdims=True)
        cos_o[tri] = 1.0
        two_sided[tri] = two_sided_material[lights["material"][tri]]
    sph = np.flatnonzero(kind == abi.LIGHT_SHAPE)
    if len(sph):
        emitting = np.asarray(shapes)[lights["prim"][sph]]
        lo[sph], hi[sph] = shape_bounds(emitting)
        for t, idx, p in shape_unit_rows(emitting):
            axis[sph[idx]], cos_o[sph[idx]] = t.emission_cone(p)
        two_sided[sph] = two_sided_material[lights["material"][sph]] & (cos_o[sph] > -1)
    return {"lo": lo, "hi": hi, "axis": axis, "cos_o": cos_o, "cos_e": cos_e,
            "phi": np.asarray(power, np.float64), "two_sided": two_sided}


def _cone(axis, cos_o, weights):
    """A cone holding the cones (axis_i, theta_o_i): around the weighted mean axis, theta_o the
    largest angle to it plus theta_o_i (pi: every direction, also when the mean is 0)."""
    mean = (axis * weights[:, None]).sum(0)
    length = np.linalg.norm(mean)
    if not length > 1e-9 or (cos_o <= -1).any():
        return np.array([0.0, 0.0, 1.0]), -1.0
    mean /= length
    theta = np.arccos(np.clip(axis @ mean, -1, 1)) + np.arccos(np.clip(cos_o, -1, 1))
    top = float(theta.max())
    return mean, (-1.0 if top >= math.pi else math.cos(top))


def _orientation_measure(theta_o, theta_e):
    """pbrt-v4's M_Omega (vectorised): the measure of the cone theta_o widened by theta_e."""
    theta_w = np.minimum(theta_o + theta_e, np.pi)
    sin_o, cos_o = np.sin(theta_o), np.cos(theta_o)
    return (2 * np.pi * (1 - cos_o)
            + np.pi / 2 * (2 * theta_w * sin_o - np.cos(theta_o - 2 * theta_w) - 2 * theta_o * sin_o + cos_o))


def _unit_rows(v):
    length = np.linalg.norm(v, axis=-1, keepdims=True)
    return np.where(length > 1e-12, v / np.where(length > 1e-12, length, 1.0), 0.0), length[..., 0] > 1e-12


def _sides(b, idx, bucket):
    """The cost terms phi M_Omega area of the lights below and above each of the BUCKETS - 1 cuts
    between buckets (vectorised over the cuts; a cut with an empty side costs inf).  A side's cone
    holds its buckets' cones (each around its phi-weighted mean axis), so it is a bounding cone,
    if not the tightest."""
    B = BUCKETS
    phi = b["phi"][idx]
    count = np.bincount(bucket, minlength=B)
    phis = np.bincount(bucket, phi, B)
    weighted = np.stack([np.bincount(bucket, b["axis"][idx, k] * phi, B) for k in range(3)], 1)
    lo, hi = np.full((B, 3), np.inf), np.full((B, 3), -np.inf)
    np.minimum.at(lo, bucket, b["lo"][idx])
    np.maximum.at(hi, bucket, b["hi"][idx])
    theta_e = np.zeros(B)
    np.maximum.at(theta_e, bucket, np.arccos(np.clip(b["cos_e"][idx], -1, 1)))
    mean, ok = _unit_rows(weighted)
    spread = (np.arccos(np.clip(np.einsum("ij,ij->i", b["axis"][idx], mean[bucket]), -1, 1))
              + np.arccos(np.clip(b["cos_o"][idx], -1, 1)))
    theta_b = np.zeros(B)
    np.maximum.at(theta_b, bucket, spread)
    theta_b[~ok & (count > 0)] = np.pi
    cost = np.zeros(B - 1)
    for below in (True, False):
        sel = (np.arange(B)[None, :] < np.arange(1, B)[:, None]) == below  # (cut, bucket)
        sel &= count[None, :] > 0
        n = sel.sum(1)
        side_mean, side_ok = _unit_rows(sel.astype(float) @ weighted)
        angle = np.arccos(np.clip(side_mean @ mean.T, -1, 1)) + theta_b[None, :]
        theta_o = np.where(sel, angle, 0.0).max(1)
        theta_o = np.where(side_ok & (theta_o < np.pi), theta_o, np.pi)
        th_e = np.where(sel, theta_e[None, :], 0.0).max(1)
        big = np.where(sel[:, :, None], hi[None], -np.inf).max(1)
        small = np.where(sel[:, :, None], lo[None], np.inf).min(1)
        d = np.where(n[:, None] > 0, big - small, 0.0)
        area = 2 * (d[:, 0] * d[:, 1] + d[:, 1] * d[:, 2] + d[:, 2] * d[:, 0])
        term = (sel.astype(float) @ phis) * _orientation_measure(theta_o, th_e) * area
        cost += np.where(n > 0, term, np.inf)
    return cost


def _median(c, idx, extent):
    dim = int(np.argmax(extent))
    order = np.argsort(c[:, dim], kind="stable")
    return idx[order[: len(idx) // 2]], idx[order[len(idx) // 2:]]


def _split(b, idx, depth):
    """Where to cut idx (an array of light rows) in two: pbrt-v4's surface area orientation
    heuristic (SAOH) over BUCKETS buckets of the centroids per axis; the median along the widest
    axis for fewer than SAOH_MIN lights, when every centroid is the same or when the depth budget
    (MAX_DEPTH) asks for a balanced tree."""
    c = 0.5 * (b["lo"][idx] + b["hi"][idx])
    clo, chi = c.min(0), c.max(0)
    extent = chi - clo
    if (len(idx) < SAOH_MIN or depth + math.ceil(math.log2(len(idx))) >= MAX_DEPTH
            or not (extent > 0).any()):
        return _median(c, idx, extent)
    diag = b["hi"][idx].max(0) - b["lo"][idx].min(0)
    best = (math.inf, 0, 0)
    for dim in range(3):
        if extent[dim] <= 0:
            continue
        bucket = np.minimum((BUCKETS * (c[:, dim] - clo[dim]) / extent[dim]).astype(np.int64), BUCKETS - 1)
        cost = _sides(b, idx, bucket) * (diag.max() / diag[dim] if diag[dim] > 0 else 1.0)
        k = int(np.argmin(cost))
        if cost[k] < best[0]:
            best = (float(cost[k]), dim, k + 1)
    if not math.isfinite(best[0]):
        return _median(c, idx, extent)
    _, dim, cut = best
    bucket = np.minimum((BUCKETS * (c[:, dim] - clo[dim]) / extent[dim]).astype(np.int64), BUCKETS - 1)
    return idx[bucket < cut], idx[bucket >= cut]


def build_light_tree(b, rows) -> tuple[np.ndarray, np.ndarray]:
    """(nodes, trail): the LIGHT_NODE records (device/light_node.py) of the tree over the light rows ``rows`` (depth
    first: an inner node's first child follows it, `child` names the second; a leaf's `child` is
    -1 - its light), and per light of ``b`` its bit trail (-1: not in the tree)."""
    n_all = len(b["phi"])
    trail = np.full(n_all, -1, np.int64)
    rows = np.asarray(rows, np.int64)
    if not len(rows):
        return np.zeros(0, abi.LIGHT_NODE), trail.astype(np.int32)
    records = []

    def node_of(idx):
        rec = np.zeros((), abi.LIGHT_NODE)
        lo, hi = b["lo"][idx].min(0), b["hi"][idx].max(0)
        rec["centre"], rec["radius"] = 0.5 * (lo + hi), 0.5 * np.linalg.norm(hi - lo)
        axis, cos_o = _cone(b["axis"][idx], b["cos_o"][idx], b["phi"][idx])
        rec["axis"], rec["cos_o"], rec["cos_e"] = axis, cos_o, b["cos_e"][idx].min()
        rec["sin_o"] = math.sqrt(max(0.0, 1 - float(rec["cos_o"]) ** 2))
        rec["phi"] = b["phi"][idx].sum()
        rec["two_sided"] = int(b["two_sided"][idx].any())
        return rec

    stack = [(rows, 0, 0, -1)]  # (lights, depth, trail so far, parent record to point at this one)
    while stack:
        idx, depth, bits, parent = stack.pop()
        rec = node_of(idx)
        me = len(records)
        records.append(rec)
        if parent >= 0:
            records[parent]["child"] = me
        if len(idx) == 1:
            rec["child"] = -1 - idx[0]
            trail[idx[0]] = bits
            continue
        first, second = _split(b, idx, depth)
        # the first child is built next (popped first), right after its parent
        stack.append((second, depth + 1, bits | (1 << depth), me))
        stack.append((first, depth + 1, bits, -1))
    nodes = np.array(records, abi.LIGHT_NODE)
    assert trail.max() < 2**31
    return nodes, trail.astype(np.int32)


# -- float64 references of cl/render/light_tree.h -----------------------------------------------

def _cos_sub(sin_a, cos_a, sin_b, cos_b):
    """cos(max(0, a - b))"""
    return np.where(cos_a > cos_b, 1.0, cos_a * cos_b + sin_a * sin_b)


def _sin_sub(sin_a, cos_a, sin_b, cos_b):
    """sin(max(0, a - b))"""
    return np.where(cos_a > cos_b, 0.0, sin_a * cos_b - cos_a * sin_b)


def importance(node, p, n) -> np.ndarray:
    """The importance of the light node (a record) to points p (N, 3) with normals n (N, 3; rows
    of 0: a point in a medium, no cosine bound): pbrt-v4's LightBounds::Importance (the squared
    distance clamped below by the half diagonal, as pbrt clamps it)."""
    p = np.asarray(p, np.float64)
    n = np.asarray(n, np.float64)
    pc, axis = node["centre"].astype(np.float64), node["axis"].astype(np.float64)
    cos_o, sin_o, cos_e, phi = (float(node[k]) for k in ("cos_o", "sin_o", "cos_e", "phi"))
    r = float(node["radius"])
    r2 = r * r
    to = p - pc
    dist2 = np.einsum("ij,ij->i", to, to)
    inside = dist2 <= r2
    d2 = np.maximum(np.maximum(dist2, r), np.finfo(np.float32).tiny)
    wi = to / np.sqrt(np.where(dist2 > 0, dist2, 1.0))[:, None]
    cos_w = wi @ axis
    if node["two_sided"]:
        cos_w = np.abs(cos_w)
    sin_w = np.sqrt(np.maximum(0.0, 1 - cos_w * cos_w))
    cos_b = np.where(inside, -1.0, np.sqrt(np.maximum(0.0, 1 - r2 / np.where(inside, 1.0, dist2))))
    sin_b = np.sqrt(np.maximum(0.0, 1 - cos_b * cos_b))
    cos_x, sin_x = _cos_sub(sin_w, cos_w, sin_o, cos_o), _sin_sub(sin_w, cos_w, sin_o, cos_o)
    cos_p = _cos_sub(sin_x, cos_x, sin_b, cos_b)
    imp = np.where(cos_p > cos_e, phi * cos_p / d2, 0.0)
    has_n = np.einsum("ij,ij->i", n, n) > 0
    cos_i = np.abs(np.einsum("ij,ij->i", wi, n))
    sin_i = np.sqrt(np.maximum(0.0, 1 - cos_i * cos_i))
    imp = np.where(has_n, imp * _cos_sub(sin_i, cos_i, sin_b, cos_b), imp)
    return np.where(inside, np.where(cos_e < 1, phi / d2, 0.0), np.maximum(imp, 0.0))


def tree_pmfs(nodes, n_lights, p, n) -> np.ndarray:
    """(N, n_lights): the probability that the descent from the root picks each light at each
    point (rows of p, n), in float64 (the tree's share of the picks not included)."""
    p = np.atleast_2d(np.asarray(p, np.float64))
    n = np.atleast_2d(np.asarray(n, np.float64))
    out = np.zeros((len(p), n_lights))
    if not len(nodes):
        return out
    stack = [(0, np.ones(len(p)))]
    while stack:
        i, prob = stack.pop()
        node = nodes[i]
        if node["child"] < 0:  # a leaf
            out[:, -1 - int(node["child"])] = prob
            continue
        c0, c1 = i + 1, int(node["child"])
        i0, i1 = importance(nodes[c0], p, n), importance(nodes[c1], p, n)
        total = i0 + i1
        p0 = np.where(total > 0, i0 / np.where(total > 0, total, 1.0), 0.0)
        p1 = np.where(total > 0, 1 - p0, 0.0)
        stack.append((c0, prob * p0))
        stack.append((c1, prob * p1))
    return out
