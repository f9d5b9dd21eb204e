"""The pixel reconstruction filters on the host: their profiles, integrals and the tables from which
the camera samples its pixel offsets (cl/render/filter.h).

Filter importance sampling (as pbrt-v4 does it): a pixel's value is the filter-weighted average
I = int f(s) L(p + s) ds / int f(s) ds over the offsets s from its centre.  Each camera sample draws
its offset s with a density proportional to |f(s)| and carries the weight
w(s) = sign f(s) * int |f| / int f, so that E[w L] = I: the sample still belongs to its own pixel
(the film only averages), and every schedule stays as it is.  Every filter is separable,
f(x, y) = f_x(x) f_y(y), so s is drawn axis by axis and the weight is the product of the axes'.
Filters without negative lobes (box, tent, gaussian) give w = 1 exactly.

How each axis is drawn (FILTER_* in the Camera record):

* box: uniform over [-r, r] (r = 0.5: the jitter is the sample itself, bit for bit as before);
* tent: its CDF inverted in closed form;
* gaussian, mitchell, lanczos (FILTER_TABULATED): per axis, the filter's stretches of one sign
  (segments, split where f changes sign) are cut into cells of equal mass of |f| (:data:`CELLS` in
  all, each segment at least 4; the knots are quantiles of the exact CDF of |f|, integrated by
  Gauss-Legendre of order 16 on 65536 sub-cells), so that the sample u picks its segment by
  comparison with a few uniform values and its cell by multiplication, without a search; within
  the cell the offset inverts |f| interpolated linearly between the cell's knots.  The density
  drawn has each cell's exact mass and, inside a cell, a linear shape: the response to a step
  deviates from the filter's by at most 1e-4 of the step (measured: 3e-5 for Mitsuba's gaussian,
  6e-6 for pbrt's, 4e-5 for Mitchell, 5e-5 and 9e-5 for Lanczos of radius 3 and 4).  This is the
  gaussian's "inversion" too: an exact one needs erf in every lane, which costs more than the rest
  of the camera ray, for a difference below these figures; the weights stay exactly 1.  A binary
  search of a table uniform in x (513 knots) was as accurate but 6 times slower: 444 ns against
  72 ns a call for 8 lanes (box: 7 ns; AMD EPYC Zen 3, PoCL); the lane megakernel computes camera
  rays for all its lanes whenever one starts a path, so the search cost 16% of mitsuba-cbox's
  samples/s at 256 x 256, the table here 4% (within the shared machine's noise).

The table buffer (kernel parameter ``filter_cdf``) holds, per axis at
``axis * (FILTER_MAX_SEGMENTS * FILTER_SEGMENT_FLOATS + 2 * knots)``: FILTER_MAX_SEGMENTS records
(u where the segment starts, its cells per unit of u, its first and last cell, 1 where f < 0),
then the knots as (x, f) pairs (x in pixels from the pixel's centre, f signed).
"""
from __future__ import annotations

import math

import numpy as np

from ..device import abi
from ..errors import UsageError
from ..scene.pixel_filter import PixelFilter

CELLS = 4096  # cells per axis of a tabulated filter (of equal mass within each of its segments)
_GAUSS_ORDER = 16


def radius(flt: PixelFilter, axis: int) -> float:
    return float(flt.radius[axis])


def profile(flt: PixelFilter, x, axis: int = 0) -> np.ndarray:
    """The filter along ``axis`` at offsets ``x`` (pixels), float64; 0 beyond its radius."""
    x = np.asarray(x, np.float64)
    r = radius(flt, axis)
    ax = np.abs(x)
    inside = ax <= r
    if flt.type == "box":
        v = np.ones_like(x)
    elif flt.type == "tent":
        v = np.maximum(0.0, 1.0 - ax / r)
    elif flt.type == "gaussian":
        a = -0.5 / (flt.sigma * flt.sigma)
        v = np.maximum(0.0, np.exp(a * x * x) - math.exp(a * r * r))
    elif flt.type == "mitchell":
        t = 2.0 * ax / r  # Mitchell-Netravali over [-2, 2], scaled to [-r, r] (pbrt-v4)
        b, c = flt.b, flt.c
        near = ((12 - 9 * b - 6 * c) * t ** 3 + (-18 + 12 * b + 6 * c) * t ** 2 + (6 - 2 * b)) / 6
        far = ((-b - 6 * c) * t ** 3 + (6 * b + 30 * c) * t ** 2 + (-12 * b - 48 * c) * t + (8 * b + 24 * c)) / 6
        v = np.where(t < 1, near, far)
    elif flt.type == "lanczos":
        v = np.sinc(x) * np.sinc(x / flt.tau)  # numpy's sinc is sin(pi x) / (pi x)
    else:
        raise ValueError(f"unknown pixel filter {flt.type!r}")
    return np.where(inside, v, 0.0)


def sign_changes(flt: PixelFilter, axis: int = 0) -> np.ndarray:
    """The offsets in (-r, r) where the filter changes sign (ascending)."""
    if flt.type in ("box", "tent", "gaussian"):
        return np.zeros(0)
    r = radius(flt, axis)
    x = np.linspace(-r, r, 20001)
    s = np.sign(profile(flt, x, axis))
    on_grid = (s[1:-1] == 0) & (s[:-2] * s[2:] < 0)  # a zero on the grid, with opposite signs around it
    roots = list(x[1:-1][on_grid])
    for i in np.flatnonzero(s[:-1] * s[1:] < 0):
        lo, hi = x[i], x[i + 1]
        flo = profile(flt, lo, axis)
        for _ in range(200):  # bisection to double precision
            mid = 0.5 * (lo + hi)
            fm = profile(flt, mid, axis)
            if fm == 0 or mid in (lo, hi):
                break
            if (fm < 0) == (flo < 0):
                lo, flo = mid, fm
            else:
                hi = mid
        roots.append(mid)
    return np.array(sorted(roots))


def _cell_integrals(flt: PixelFilter, x: np.ndarray, axis: int) -> np.ndarray:
    """The integral of f over each cell [x_i, x_i+1] (Gauss-Legendre), float64."""
    t, w = np.polynomial.legendre.leggauss(_GAUSS_ORDER)
    lo, hi = x[:-1, None], x[1:, None]
    mid, half = (lo + hi) / 2, (hi - lo) / 2
    return (profile(flt, mid + half * t, axis) * w).sum(axis=1) * half[:, 0]


def axis_integrals(flt: PixelFilter, axis: int = 0) -> tuple[float, float]:
    """(int f, int |f|) along ``axis``, float64 (exact for box, tent and Mitchell)."""
    r = radius(flt, axis)
    knots = np.unique(np.concatenate([np.linspace(-r, r, 257), sign_changes(flt, axis)]))
    cells = _cell_integrals(flt, knots, axis)
    return float(cells.sum()), float(np.abs(cells).sum())


def axis_table(flt: PixelFilter, axis: int = 0, cells: int = CELLS) -> tuple[np.ndarray, np.ndarray]:
    """(segments, knots) of FILTER_TABULATED along ``axis``: (S, FILTER_SEGMENT_FLOATS) records and
    (K, 2) knots (x, f), float64 (see the module docstring)."""
    r = radius(flt, axis)
    roots = sign_changes(flt, axis)
    bounds = np.concatenate([[-r], roots, [r]])
    fine = np.unique(np.concatenate([np.linspace(-r, r, 65537), roots]))
    mass = np.concatenate([[0.0], np.cumsum(np.abs(_cell_integrals(flt, fine, axis)))])
    total = mass[-1]
    segments, xs = [], [np.array([-r])]
    first = 0
    for a, b in zip(bounds[:-1], bounds[1:]):
        ma, mb = mass[np.searchsorted(fine, a)], mass[np.searchsorted(fine, b)]
        n = max(4, int(round(cells * (mb - ma) / total)))
        x = np.interp(np.linspace(ma, mb, n + 1), mass, fine)
        x[0], x[-1] = a, b
        xs.append(x[1:])
        negative = profile(flt, 0.5 * (x[n // 2] + x[n // 2 + 1]), axis) < 0
        segments.append((ma / total, n * total / (mb - ma), first, first + n - 1, 1.0 if negative else 0.0))
        first += n
    if len(segments) > abi.FILTER_MAX_SEGMENTS:
        raise UsageError(f"the {flt.type} pixel filter changes sign {len(roots)} times along {'xy'[axis]}: "
                         f"at most {abi.FILTER_MAX_SEGMENTS - 1}")
    x = np.concatenate(xs)
    f = profile(flt, x, axis)
    f[np.isin(x, roots)] = 0.0
    return np.array(segments), np.stack([x, f], axis=1)


def check(flt: PixelFilter) -> None:
    """UsageError (one line) for a filter whose integral is not positive along an axis."""
    for axis in (0, 1):
        total, absolute = axis_integrals(flt, axis)
        if not total > 1e-6 * absolute:
            raise UsageError(f"the {flt.type} pixel filter {flt.as_dict()} integrates to {total:.3g} along "
                             f"{'xy'[axis]}: its weights cannot be normalised")


def weight(flt: PixelFilter) -> float:
    """The magnitude of every sample's weight: the product over the axes of int |f| / int f."""
    w = 1.0
    for axis in (0, 1):
        if len(sign_changes(flt, axis)):  # else exactly 1: |f| = f
            total, absolute = axis_integrals(flt, axis)
            w *= absolute / total
    return w


def method(flt: PixelFilter) -> int:
    """How the camera draws the filter's offsets (the Camera record's FILTER_*)."""
    return {"box": abi.FILTER_BOX, "tent": abi.FILTER_TENT}.get(flt.type, abi.FILTER_TABULATED)


def apply(record: np.ndarray, flt: PixelFilter) -> np.ndarray:
    """Sets the filter fields of a CAMERA record; returns the ``filter_cdf`` buffer (float32; one
    0 where the filter has no table)."""
    record["filter"] = method(flt)
    record["filter_radius"] = flt.radius
    record["filter_segments"] = 0
    if record["filter"] != abi.FILTER_TABULATED:
        record["filter_knots"] = 0
        record["filter_weight"] = 1.0
        return np.zeros(1, np.float32)
    check(flt)
    tables = [axis_table(flt, axis) for axis in (0, 1)]
    knots = max(len(k) for _, k in tables)
    blocks = []
    for segments, k in tables:
        header = np.zeros((abi.FILTER_MAX_SEGMENTS, abi.FILTER_SEGMENT_FLOATS))
        header[:len(segments)] = segments
        padded = np.concatenate([k, np.repeat(k[-1:], knots - len(k), axis=0)])  # cells no segment reaches
        blocks += [header.ravel(), padded.ravel()]
    record["filter_segments"] = [len(segments) for segments, _ in tables]
    record["filter_knots"] = knots
    record["filter_weight"] = weight(flt)
    return np.concatenate(blocks).astype(np.float32)
