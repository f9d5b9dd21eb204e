"""The emitter table for next-event estimation: every emissive triangle and analytic shape, and the point,
spot, projector, directional and environment lights.  RenderSettings.light_sampler chooses how a
light is picked: "power" in proportion to its power (emitted radiance luminance x area x pi, x2
when two-sided), infinitely distant lights as pbrt-v4's BVH light sampler picks them
(:func:`selection_weights`); "bvh" as "power" for the infinitely distant lights, the others by
their importance to the shading point through the light BVH (render/light_tree.py); "uniform" each emitter with probability sampling_weight / sum, split
over its triangles by area (:func:`uniform_weights`: Mitsuba 3's rule).  The table's pmf is what
the kernels divide by and weigh MIS with (cl/render/path.h), so either choice is unbiased."""
from __future__ import annotations

import warnings
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ..device import abi
from ..device.host_memory import aligned_empty
from ..scene.lights import LUMINANCE, REGISTRY, light_type
from ..scene.lights.frames import record_rgb
from ..scene.meshops import bounds
from ..scene.model import LIGHT_SAMPLERS
from ..scene.shapes import bounds as shape_bounds, per_shape
from .sampling import fill_light_table


def build_lights(scene, bvh) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """Return (lights, tri_light, shape_light, light_nodes): the LIGHT records, per reordered
    triangle and per analytic shape the index of its light record (-1 when it does not emit), and the
    light BVH's LIGHT_NODE records (render/light_tree.py; none unless light_sampler is "bvh")."""
    mats = scene.materials
    emissive = np.array([m.is_emissive for m in mats] or [False])
    directional = np.array([m.emission_directional for m in mats] or [False])
    # mean_emission: emission x the mean of its texture (textured emitters are sampled by that power)
    luminance = np.array([float(np.dot(m.mean_emission(), LUMINANCE)) for m in mats] or [0.0])
    sides = np.array([2.0 if m.two_sided else 1.0 for m in mats] or [1.0])

    tri_mat = scene.face_materials[bvh.prim_ids] if len(bvh.prim_ids) else np.zeros(0, np.int32)
    tri_idx = np.nonzero(emissive[tri_mat])[0] if len(tri_mat) else np.zeros(0, np.int64)
    tri = bvh.triangles
    if len(tri_idx):
        p0, p1, p2 = (tri[k][tri_idx, :3].astype(np.float64) for k in ("v0", "v1", "v2"))
        tri_area = 0.5 * np.linalg.norm(np.cross(p1 - p0, p2 - p0), axis=1)
    else:
        tri_area = np.zeros(0)
    keep = tri_area > 0  # zero-area emitters cannot be sampled (and are never hit)
    with np.errstate(over="ignore"):
        too_big = keep & ~np.isfinite(tri_area.astype(np.float32))
    if too_big.any():  # an area beyond float32 (coordinates ~1e19 and up) cannot be sampled
        warnings.warn(f"{scene.source}: {int(too_big.sum())} emissive triangles have an area too large for "
                      "float32; they are left out of light sampling (still seen by BSDF sampling)", stacklevel=2)
        keep &= ~too_big
    tri_idx, tri_area = tri_idx[keep], tri_area[keep]

    sph_mat = scene.shape_materials
    sph_idx = np.nonzero(emissive[sph_mat])[0] if len(sph_mat) else np.zeros(0, np.int64)
    sph_area = per_shape(scene.shapes[sph_idx], "area") if len(sph_idx) else np.zeros(0)

    n = len(tri_idx) + len(sph_idx)
    lights = np.zeros(n, abi.LIGHT)
    lights["texture"] = -1
    tri_light = aligned_empty(len(bvh.prim_ids), np.int32)  # read in place by a CPU device (host_memory.py)
    tri_light[:] = -1
    shape_light = np.full(len(scene.shapes), -1, np.int32)
    k = len(tri_idx)
    lights["kind"][:k] = abi.LIGHT_TRIANGLE
    lights["prim"][:k] = tri_idx
    lights["material"][:k] = tri_mat[tri_idx]
    lights["area"][:k] = tri_area
    lights["kind"][k:] = abi.LIGHT_SHAPE
    lights["prim"][k:] = sph_idx
    lights["material"][k:] = sph_mat[sph_idx]
    lights["area"][k:] = sph_area
    tri_light[tri_idx] = np.arange(k, dtype=np.int32)
    shape_light[sph_idx] = np.arange(k, n, dtype=np.int32)
    mat = lights["material"]
    power = luminance[mat] * lights["area"].astype(np.float64) * np.pi * sides[mat] if n else np.zeros(0)
    beam = np.flatnonzero(directional[mat]) if n else np.zeros(0, np.int64)
    if len(beam):  # emitting along the normal alone: flux = radiance x area; never hit (no tri_light)
        lights["kind"][beam] = abi.LIGHT_DIRECTIONAL_AREA
        lights["rgb"][beam] = np.array([m.emission for m in mats], np.float64)[mat[beam]]
        power[beam] = luminance[mat[beam]] * lights["area"][beam].astype(np.float64)
        tri_light[tri_idx[beam]] = -1
    if n and not (power > 0).any():  # e.g. pure blue emitters have luminance; this guards all-zero
        power = lights["area"].astype(np.float64)
    # an infinite emission has infinite power: pick it as often as a finite table allows
    power = np.where(np.isfinite(power), power, np.finfo(np.float64).max / (n + 1)) if n else power
    extra, extra_power = other_lights(scene)
    lights = np.concatenate([lights, extra])
    power = np.concatenate([power, extra_power])
    no_tree = np.zeros(0, abi.LIGHT_NODE)
    lights["trail"] = -1
    if len(lights) == 0:
        return lights, tri_light, shape_light, no_tree
    if not (power > 0).any():  # only black lights (an environment map of zeros): any valid table
        power = np.ones(len(lights))
    sampler = getattr(getattr(scene, "settings", None), "light_sampler", "power")
    if sampler not in LIGHT_SAMPLERS:
        raise ValueError(f"unknown light sampler {sampler!r}: use one of {', '.join(LIGHT_SAMPLERS)}")
    if sampler == "uniform":
        weights = uniform_weights(scene, bvh, lights, power)
    else:
        weights = selection_weights(lights["kind"], power)
    fill_light_table(lights, weights)
    if sampler != "bvh":
        return lights, tri_light, shape_light, no_tree
    # the lights not infinitely far go in the tree, which the alias table's picks of any of them
    # enter (pbrt-v4's share for the infinite lights: selection_weights); their pmf: that share
    from .light_tree import build_light_tree, light_bounds

    bounded = np.flatnonzero(~np.isin(lights["kind"], INFINITE_LIGHTS) & (weights > 0))
    bounds = light_bounds(lights, bvh.triangles, scene.shapes, sides == 2.0, weights)  # phi: power, scaled
    nodes, lights["trail"] = build_light_tree(bounds, bounded)
    lights["pmf"][bounded] = np.float32(lights["pmf"][bounded].astype(np.float64).sum())
    return lights, tri_light, shape_light, nodes


def uniform_weights(scene, bvh, lights, power) -> np.ndarray:
    """Mitsuba 3's light picking (scene.cpp: an emitter by its sampling_weight; area.cpp and the
    shape's sample_position: a point uniformly by area): each emitter gets weight sampling_weight,
    shared by its triangles in proportion to their area.  An emitter is a Scene.face_emitters /
    shape_emitters index (a Mitsuba shape with an area emitter; weight Scene.emitter_weights), an
    emissive triangle or analytic shape without one (each is an emitter, weight 1: pbrt-v4's "uniform"
    sampler, whose triangles are lights one by one), or a point, spot, projector, directional or
    environment light (its sampling_weight).  Lights that emit nothing (power 0) get weight 0:
    unlike Mitsuba, no pick is spent on them (the estimate is the same, its variance lower)."""
    from ..scene.validate import check_emitters

    check_emitters(scene)  # the indices and weights below (an engine built without check_scene)
    n = len(lights)
    kind = lights["kind"]
    prim = lights["prim"].astype(np.int64)
    group = np.full(n, -1, np.int64)  # the emitter index of each row (-1: a row by itself)
    tri = np.nonzero(np.isin(kind, abi.TRIANGLE_LIGHTS))[0]
    sph = np.nonzero(kind == abi.LIGHT_SHAPE)[0]
    face_emitters = getattr(scene, "face_emitters", None)
    if face_emitters is not None and len(tri):
        group[tri] = np.asarray(face_emitters)[np.asarray(bvh.prim_ids)[prim[tri]]]  # the rows', no int64 copy of all
    shape_emitters = getattr(scene, "shape_emitters", None)
    if shape_emitters is not None and len(sph):
        group[sph] = np.asarray(shape_emitters, np.int64)[prim[sph]]
    table = np.asarray(list(getattr(scene, "emitter_weights", []) or []), np.float64)
    weight = np.ones(n)
    grouped = group >= 0
    if grouped.any():
        weight[grouped] = table[group[grouped]]
    n_area = len(tri) + len(sph)
    others = [*(getattr(scene, "lights", []) or [])]
    if getattr(scene, "environment", None) is not None:
        others.append(scene.environment)
    weight[n_area:] = [float(getattr(spec, "sampling_weight", 1.0)) for spec in others]
    # an emitter's weight split over its rows by area (rows by themselves: their whole weight)
    area = lights["area"].astype(np.float64)
    share = np.ones(n)
    if grouped.any():
        ids, inverse = np.unique(group[grouped], return_inverse=True)
        total = np.bincount(inverse, weights=area[grouped], minlength=len(ids))
        share[grouped] = area[grouped] / total[inverse]
    weights = np.where(np.asarray(power) > 0, weight * share, 0.0)
    if not (weights > 0).any():  # every weight 0 (sampling_weight 0 everywhere): any valid table
        weights = (np.asarray(power) > 0) * 1.0
    return weights


# infinitely far: the environment and the registered types that say so (directional)
INFINITE_LIGHTS = (abi.LIGHT_ENVIRONMENT, *(t.kind for t in REGISTRY.values() if t.infinite))


def selection_weights(kinds, power) -> np.ndarray:
    """Light-picking weights: each of the n infinitely distant lights (directional, environment)
    with radiance is picked with probability 1 / (n + 1) and the lights in the scene together with
    1 / (n + 1), by power among them (pbrt-v4's BVH light sampler splits so).  A power estimate
    of an environment (its radiance over a disc of the scene's bounding radius) can dwarf a
    spot's or a small emitter's by orders of magnitude although both light the same points about
    equally: picked by power alone, a spot in a sky got 2.6% of the samples and 37x Mitsuba's
    variance (its uniform pick: 50%) on the suite's spot_light scene."""
    power = np.asarray(power, np.float64)
    infinite = np.isin(kinds, INFINITE_LIGHTS) & (power > 0)
    bounded = ~np.isin(kinds, INFINITE_LIGHTS) & (power > 0)
    if not infinite.any() or not bounded.any():
        return power
    share = 1.0 / (infinite.sum() + 1)
    weights = np.zeros_like(power)
    weights[infinite] = share
    weights[bounded] = share * power[bounded] / power[bounded].sum()
    return weights


# ----------------------------------------------------------------------------------------------
# Point, directional and environment lights (cl/render/lights.h).  Power, for picking lights in
# proportion to it (pbrt-v4's Light::Phi, with luminance for the RGB):
#   point        4 pi I
#   directional  pi r^2 E            (r: radius of the scene's bounding sphere)
#   environment  4 pi * pi r^2 * (radiance averaged over the sphere of directions)
# ----------------------------------------------------------------------------------------------

def scene_bounding_sphere(scene) -> tuple[np.ndarray, float]:
    """Centre and radius of the sphere around the bounding box of the triangles and analytic shapes."""
    lo, hi = np.full(3, np.inf), np.full(3, -np.inf)
    if len(scene.vertices):
        vlo, vhi = bounds(scene.vertices)
        lo, hi = np.minimum(lo, vlo), np.maximum(hi, vhi)
    if len(scene.shapes):
        s_lo, s_hi = shape_bounds(scene.shapes)
        lo, hi = np.minimum(lo, s_lo.min(0)), np.maximum(hi, s_hi.max(0))
    if not np.all(np.isfinite(lo)) or not np.all(np.isfinite(hi)):
        return np.zeros(3), 0.0
    return 0.5 * (lo + hi), float(0.5 * np.linalg.norm(hi - lo))


@dataclass(frozen=True)
class LightPlace:
    """What a light type's ``pack`` reads of the scene (scene/lights/__init__.py)."""

    centre: np.ndarray  # the scene's bounding sphere
    radius: float
    texture_index: Callable  # a Texture (or None) -> its index in the kernels' textures (-1)


ENV_ROWS = {"centred": lambda h: (float(h), -0.5), "poles": lambda h: (float(max(h - 1, 1)), 0.0)}


ENV_SAMPLING_CELLS = 1 << 22  # a map gets 2 x 2 to 4 x 4 sampling cells per texel while they stay below this


def environment_tables(image, rows: str = "centred", rotation=None,
                       compensated: bool = False) -> tuple[np.ndarray, np.ndarray, float, int]:
    """(env_map, env_cdf, mean radiance luminance over the sphere, cells) of an equirectangular map:
    env_map is the kernel's buffer (abi.ENV_MAP_HEADER floats: the world-to-map ``rotation`` and the
    ``rows`` layout, then the texels; negative and non-finite texels become 0).  The sampling
    density is constant over cells x cells cells per texel (S H x S W in all, S = cells: up to 4 on
    small maps, where the interpolated radiance varies most within a texel's solid angle).  env_cdf
    is the marginal CDF over the S H rows of cells (S H + 1 values from 0 to 1), then the
    conditional CDF of each row (S W + 1 values): a cell's weight is the bilinearly interpolated
    luminance averaged over it (4 x 4 points) times sin(theta) at the row centre, plus 1e-3 of the
    largest luminance of the texels around it, so that no cell where the radiance is positive has
    density 0; a row (or map) with nothing in it is uniform.

    ``compensated``: MIS compensation (Karlik et al. 2019, as pbrt-v4's image infinite lights with
    ``allowIncompletePDF``): a cell's weight is how far its luminance exceeds the map's mean over
    the sphere, so that light sampling spends no samples on the dim part of a sky, which BSDF
    sampling finds as well; cells at or below the mean get density 0, and BSDF samples toward them
    MIS weight 1 (their light pdf is 0).  For estimators that combine the two techniques by MIS
    only: light sampling alone needs the complete density.  A map without such excess (constant,
    or black) keeps the complete tables."""
    grid = _env_grid(image, rows)
    env_map, mean = _env_map_buffer(grid, rotation)
    return env_map, _env_cdf(grid, compensated), mean, grid["sub"]


def _env_grid(image, rows):
    """What both kinds of tables are made of: the map's texels made finite and non-negative, the
    luminance of its sampling cells (averaged over each), the largest texel luminance around each,
    sin(theta) of each row of cells, and the layout."""
    img = np.asarray(image, np.float64)
    if img.ndim != 3 or img.shape[2] < 3 or img.shape[0] < 1 or img.shape[1] < 1:
        raise ValueError(f"an environment map must be H x W x 3, got shape {img.shape}")
    if rows not in ENV_ROWS:
        raise ValueError(f"environment map rows must be one of {', '.join(ENV_ROWS)}, got {rows!r}")
    img = img[:, :, :3]
    img = np.where(np.isfinite(img), np.maximum(img, 0.0), 0.0)
    h, w = img.shape[:2]
    v_scale, v_offset = ENV_ROWS[rows](h)
    lum = img @ LUMINANCE
    sub = int(np.clip(np.floor(np.sqrt(ENV_SAMPLING_CELLS / (h * w))), 1, 4))
    cells = (_cell_means(sub * h, h, v_scale, v_offset, wrap=False)
             @ (_cell_means(sub * w, w, float(w), -0.5, wrap=True) @ lum.T).T)
    from scipy.ndimage import maximum_filter

    near = np.repeat(np.repeat(maximum_filter(lum, size=3, mode=("nearest", "wrap")), sub, 0), sub, 1)
    sin_t = np.sin(np.pi * (np.arange(sub * h) + 0.5) / (sub * h))
    return {"img": img, "cells": np.maximum(cells, 0.0), "near": near, "sin_t": sin_t, "sub": sub,
            "v_scale": v_scale, "v_offset": v_offset}


def _env_map_buffer(grid, rotation) -> tuple[np.ndarray, float]:
    """The kernel's env_map buffer (header and texels) and the mean luminance over the sphere."""
    cells, sin_t = grid["cells"], grid["sin_t"]
    h, w = cells.shape
    mean = float((cells * sin_t[:, None]).sum() * (np.pi / h) * (2 * np.pi / w) / (4 * np.pi))
    header = np.zeros(abi.ENV_MAP_HEADER, np.float32)
    rot = np.eye(3) if rotation is None else np.asarray(rotation, np.float64)
    header[[0, 1, 2, 4, 5, 6, 8, 9, 10]] = rot.reshape(-1)
    header[3], header[7] = grid["v_scale"], grid["v_offset"]
    return np.concatenate([header, grid["img"].astype(np.float32).reshape(-1)]), mean


def _env_cdf(grid, compensated) -> np.ndarray:
    """env_cdf (environment_tables) of the complete or the compensated cell weights."""
    cells, sin_t = grid["cells"], grid["sin_t"]
    f = None
    if compensated:
        excess = np.maximum(cells - (cells * sin_t[:, None]).sum() / (sin_t.sum() * cells.shape[1]), 0.0)
        f = excess * sin_t[:, None] if excess.any() else None
    if f is None:
        f = (cells + 1e-3 * grid["near"]) * sin_t[:, None]

    def cdf_rows(weights):  # (R, N) -> (R, N + 1), each row from 0 to 1
        total = weights.sum(1, keepdims=True)
        c = np.concatenate([np.zeros((len(weights), 1)), np.cumsum(weights, 1)], 1)
        uniform = np.broadcast_to(np.linspace(0.0, 1.0, weights.shape[1] + 1), c.shape)
        c = np.where(total > 0, c / np.where(total > 0, total, 1.0), uniform)
        c[:, -1] = 1.0
        return np.maximum.accumulate(np.clip(c, 0.0, 1.0), axis=1)

    cond = cdf_rows(f)
    marg = cdf_rows(f.sum(1)[None, :])[0]
    return np.concatenate([marg, cond.reshape(-1)]).astype(np.float32)


def environment_radiance(env, directions) -> np.ndarray:
    """(N, 3) float64 radiance of the Environment ``env`` along unit world ``directions`` (N, 3),
    as cl/render/lights.h computes it (the map's frame, then bilinear interpolation): the host's
    reference of the kernel's lookup."""
    d = np.asarray(directions, np.float64)
    scale = np.asarray(env.radiance, np.float64)
    if env.image is None:
        return np.broadcast_to(scale, d.shape).copy()
    if env.rotation is not None:
        d = d @ np.asarray(env.rotation, np.float64).T
    img = np.asarray(env.image, np.float64)[:, :, :3]
    img = np.where(np.isfinite(img), np.maximum(img, 0.0), 0.0)
    u = np.mod(np.arctan2(-d[:, 0], d[:, 2]) / (2 * np.pi), 1.0)
    v = np.arccos(np.clip(d[:, 1], -1.0, 1.0)) / np.pi
    from ..scene.loaders.builder import bilinear_wrap

    return bilinear_wrap(img, u, v, *ENV_ROWS[env.rows](img.shape[0])) * scale


def _cell_means(n_cells: int, n: int, scale: float, offset: float, wrap: bool):
    """(n_cells x n) sparse: the linear interpolation of n texels at coordinate t * scale + offset,
    averaged over 4 points of each of n_cells equal cells of t in [0, 1]; the texels wrap around or
    are clamped at the ends."""
    from scipy.sparse import csr_matrix

    k = 4
    t = (np.arange(n_cells)[:, None] + (np.arange(k)[None, :] + 0.5) / k) / n_cells
    f = t * scale + offset
    i0 = np.floor(f)
    a = f - i0
    i0 = i0.astype(np.int64)
    i1 = i0 + 1
    i0, i1 = (i0 % n, i1 % n) if wrap else (np.clip(i0, 0, n - 1), np.clip(i1, 0, n - 1))
    rows = np.repeat(np.arange(n_cells), 2 * k)
    cols = np.stack([i0, i1], 2).reshape(-1)
    data = np.stack([1 - a, a], 2).reshape(-1) / k
    return csr_matrix((data, (rows, cols)), shape=(n_cells, n))


def _env_tables(env, compensated=False):
    """environment_tables of env.image (its rows and rotation), computed once per Environment and
    kind of tables."""
    if env.image is None:
        return None
    key = (id(env.image), getattr(env, "rows", "centred"), None if env.rotation is None else env.rotation.tobytes())
    cached = getattr(env, "_tables", None)
    if cached is None or cached[0] != key:
        grid = _env_grid(env.image, env.rows)
        cached = (key, grid, _env_map_buffer(grid, env.rotation), {})
        env._tables = cached
    _, grid, (env_map, mean), cdfs = cached
    if compensated not in cdfs:  # the grid is shared: the second kind costs only its CDFs
        cdfs[compensated] = _env_cdf(grid, compensated)
    return env_map, cdfs[compensated], mean, grid["sub"]


def environment_buffers(scene, compensated=False) -> tuple[np.ndarray, np.ndarray]:
    """The env_map and env_cdf kernel arguments (dummies without a map); ``compensated``: the
    sampling tables of MIS compensation (environment_tables), for the MIS estimator."""
    env = getattr(scene, "environment", None)
    tables = _env_tables(env, compensated) if env is not None else None
    if tables is None:
        return np.zeros(abi.ENV_MAP_HEADER, np.float32), np.zeros(4, np.float32)
    return tables[0], tables[1]


def other_lights(scene) -> tuple[np.ndarray, np.ndarray]:
    """LIGHT records and powers of the scene's lights of registered types (scene/lights/: point,
    directional, spot, projector) and its environment."""
    specs = list(getattr(scene, "lights", []) or [])
    env = getattr(scene, "environment", None)
    recs = np.zeros(len(specs) + (env is not None), abi.LIGHT)
    power = np.zeros(len(recs))
    if not len(recs):
        return recs, power
    centre, radius = scene_bounding_sphere(scene)
    recs["texture"] = -1
    index = {id(t): i for i, t in enumerate(scene.textures())} if hasattr(scene, "textures") else {}
    place = LightPlace(centre, radius, lambda t: -1 if t is None else index[id(t)])
    for i, spec in enumerate(specs):
        kind = light_type(spec)
        recs[i]["material"] = 0
        recs[i]["kind"] = kind.kind
        power[i] = kind.pack(spec, recs[i], place)
    if env is not None:
        r = recs[-1]
        r["kind"] = abi.LIGHT_ENVIRONMENT
        r["p"], r["radius"] = centre, radius
        r["rgb"] = record_rgb(env.radiance)
        tables = _env_tables(env)
        mean = 1.0
        if tables is not None:
            h, w = np.asarray(env.image).shape[:2]
            r["prim"], r["material"], r["cells"] = w, h, tables[3]
            mean = tables[2]
        power[-1] = 4 * np.pi * np.pi * radius**2 * float(r["rgb"] @ LUMINANCE) * mean
    power = np.where(np.isfinite(power), power, np.finfo(np.float64).max / (len(power) + 1))
    return recs, power
