"""Host side of light selection: the alias table that ``sample_alias`` in ``cl/render/sampling.h`` reads.

Vose's method (Vose 1991, "A linear algorithm for generating random numbers with a given
distribution"): every column i of the table holds probability 1/n, split between light i
(kept with probability ``alias_prob[i]``) and one other light ``alias[i]``.  The device picks the
column with floor(u n) and decides with the fractional part of u n, in O(1).
"""
from __future__ import annotations

import numpy as np

from ..device import abi


def build_alias_table(weights) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Return ``(pmf float32, alias_prob float32, alias int32)`` for non-negative ``weights``.

    ``pmf[i] = weights[i] / sum(weights)``.  Lights of weight zero get pmf 0 and
    ``alias_prob`` 0 and are the alias of no column, so they are never drawn.  Columns that keep
    their own light always have ``alias[i] = i``.  Raises ValueError for empty, all-zero,
    negative or non-finite weights.  O(n).
    """
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    n = w.size
    if n == 0:
        raise ValueError("alias table: no weights")
    if not np.all(np.isfinite(w)):
        raise ValueError("alias table: weights must be finite")
    if np.any(w < 0):
        raise ValueError("alias table: weights must be non-negative")
    total = w.sum()
    if not total > 0:
        raise ValueError("alias table: all weights are zero")

    pmf = w / total
    scaled = pmf * n  # mean 1
    prob = np.ones(n, np.float64)
    alias = np.arange(n, dtype=np.int64)
    small = np.flatnonzero(scaled < 1.0).tolist()
    large = np.flatnonzero(scaled >= 1.0).tolist()
    s_list = scaled.tolist()  # Python floats: faster element access in the loop below
    while small and large:
        s = small.pop()
        g = large.pop()
        prob[s] = s_list[s]
        alias[s] = g
        # g gives away 1 - scaled[s]; written as a sum of the two for less cancellation
        s_list[g] = (s_list[g] + s_list[s]) - 1.0
        (small if s_list[g] < 1.0 else large).append(g)
    # Leftovers are 1 up to rounding: they keep their column.  A zero-weight light can only be
    # left over through rounding; send its column to the heaviest light instead.
    heaviest = int(np.argmax(w))
    for i in small + large:
        if w[i] > 0:
            prob[i], alias[i] = 1.0, i
        else:
            prob[i], alias[i] = 0.0, heaviest
    prob[w == 0] = 0.0
    return pmf.astype(np.float32), np.clip(prob, 0.0, 1.0).astype(np.float32), alias.astype(np.int32)


def fill_light_table(lights: np.ndarray, weights) -> np.ndarray:
    """Write ``pmf``, ``alias_prob`` and ``alias`` of a :data:`abi.LIGHT` array in place
    (``weights`` per light, e.g. emitted power); returns ``lights``."""
    if lights.dtype != abi.LIGHT:
        raise TypeError(f"expected a abi.LIGHT array, got {lights.dtype}")
    w = np.asarray(weights, dtype=np.float64).reshape(-1)
    if w.size != lights.shape[0]:
        raise ValueError(f"{w.size} weights for {lights.shape[0]} lights")
    pmf, prob, alias = build_alias_table(w)
    lights["pmf"] = pmf
    lights["alias_prob"] = prob
    lights["alias"] = alias
    return lights
