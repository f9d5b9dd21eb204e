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
* gaussian, mitchell, lanczos (FILTER_TABULATED): the CDF of |f| at :data:`KNOTS` knots per axis
  (uniform over [-r, r], plus the filter's sign changes, so that the sign is constant over each
  cell), each cell's mass integrated exactly (Gauss-Legendre of order 16 in float64: exact for
  Mitchell's cubics, to double precision for the others); the cell is found by binary search and
  the offset within it by inverting |f| interpolated linearly across the cell.  The density drawn
  is |f| to within 1e-5 relatively (a cell's mass is exact, only its shape is linear; measured
  against the exact inverse CDF: 3e-8 pixels median, 7e-6 at the 99.9th percentile, at float32
  precision), so the gaussian is drawn as exactly as a Newton refinement of the erf CDF in
  float32 would draw it (measured: the refinement gains nothing).

The table buffer (kernel parameter ``filter_cdf``) holds, per axis at ``axis * 3 * knots``: the
knots x (pixels from the pixel's centre), f there (signed), and the normalised CDF of |f|.
"""
from __future__ import annotations

import math

import numpy as np

from ..device import abi
from ..errors import UsageError
from ..scene.model import PixelFilter

KNOTS = 513  # knots per axis of a tabulated filter: 512 cells, more where the filter changes sign
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


def axis_table(flt: PixelFilter, axis: int = 0, knots: int = KNOTS) -> np.ndarray:
    """(3, knots) float64: the knots, f there and the normalised CDF of |f| (FILTER_TABULATED)."""
    r = radius(flt, axis)
    roots = sign_changes(flt, axis)
    x = np.unique(np.concatenate([np.linspace(-r, r, knots - len(roots)), roots]))
    mass = np.abs(_cell_integrals(flt, x, axis))
    cdf = np.concatenate([[0.0], np.cumsum(mass)])
    cdf /= cdf[-1]
    f = profile(flt, x, axis)
    f[np.isin(x, roots)] = 0.0
    table = np.empty((3, knots))
    n = len(x)
    table[0, :n], table[1, :n], table[2, :n] = x, f, cdf
    table[:, n:] = table[:, n - 1:n]  # padding: cells of no mass after the last knot
    table[2, n - 1:] = 1.0
    return table


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
    if record["filter"] != abi.FILTER_TABULATED:
        record["filter_knots"] = 0
        record["filter_weight"] = 1.0
        return np.zeros(1, np.float32)
    check(flt)
    record["filter_knots"] = KNOTS
    record["filter_weight"] = weight(flt)
    return np.concatenate([axis_table(flt, axis).ravel() for axis in (0, 1)]).astype(np.float32)
