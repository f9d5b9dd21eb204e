"""Comparing two linear images, as pbrt's ``imgtool diff`` does: ``pyopencl-rt compare A.exr B.exr``.

B is the reference.  Over all pixels and the three channels:

* ``mse``: mean of (a - b)^2, and ``rmse`` its square root;
* ``relmse``: mean of (a - b)^2 / (b^2 + 1e-2) (Rousselle et al. 2011's relative MSE, with the
  epsilon the convergence benchmark uses);
* ``mean_ratio``: mean(a) / mean(b) per channel (1 when the two agree on average: a bias check);
* ``flip``: the mean HDR-FLIP error (Andersson et al. 2021; NVIDIA's ``flip-evaluator`` package,
  the optional extra ``pip install 'pyopencl-rt[flip]'``), None without it.

The heat map is FLIP's error map when FLIP ran, else the per-pixel relative squared error
(averaged over the channels) on a log scale from 1e-4 to 1, through a black-red-yellow-white ramp.
"""
from __future__ import annotations

import numpy as np

from .errors import UserError

REL_EPS = 1e-2


def _rgb(image, name) -> np.ndarray:
    a = np.asarray(image, np.float64)
    if a.ndim != 3 or a.shape[2] < 3:
        raise UserError(f"{name}: expected an RGB image, got shape {a.shape}")
    return a[..., :3]


def metrics(image, reference) -> dict:
    """MSE, RMSE, relMSE and the per-channel mean ratio of ``image`` against ``reference``."""
    a, b = _rgb(image, "image"), _rgb(reference, "reference")
    if a.shape != b.shape:
        raise UserError(f"the images differ in size: {a.shape[1]}x{a.shape[0]} and {b.shape[1]}x{b.shape[0]}")
    d2 = (a - b) ** 2
    mean_b = b.reshape(-1, 3).mean(0)
    with np.errstate(divide="ignore", invalid="ignore"):
        ratio = a.reshape(-1, 3).mean(0) / mean_b
    return {"mse": float(d2.mean()), "rmse": float(np.sqrt(d2.mean())),
            "relmse": float((d2 / (b * b + REL_EPS)).mean()),
            "mean_ratio": [float(r) if np.isfinite(r) else None for r in ratio]}


def flip(image, reference):
    """(mean HDR-FLIP error, H x W error map), or None when flip-evaluator is not installed."""
    try:
        import flip_evaluator
    except ImportError:
        return None
    a = np.ascontiguousarray(np.maximum(_rgb(image, "image"), 0.0), np.float32)
    b = np.ascontiguousarray(np.maximum(_rgb(reference, "reference"), 0.0), np.float32)
    error_map, mean, _ = flip_evaluator.evaluate(b, a, "HDR", applyMagma=False)
    return float(mean), np.asarray(error_map, np.float64).reshape(a.shape[:2])


def heat(values: np.ndarray) -> np.ndarray:
    """Values in [0, 1] (H x W) through a black-red-yellow-white ramp: H x W x 3 uint8."""
    t = np.clip(np.nan_to_num(np.asarray(values, np.float64), nan=1.0), 0.0, 1.0)
    rgb = np.stack([np.clip(3 * t, 0, 1), np.clip(3 * t - 1, 0, 1), np.clip(3 * t - 2, 0, 1)], -1)
    return (rgb * 255 + 0.5).astype(np.uint8)


def error_map(image, reference, flip_map=None) -> np.ndarray:
    """The heat map's H x W values in [0, 1]: FLIP's map, else log10 relative squared error in [-4, 0]."""
    if flip_map is not None:
        return flip_map
    a, b = _rgb(image, "image"), _rgb(reference, "reference")
    rel = ((a - b) ** 2 / (b * b + REL_EPS)).mean(-1)
    return (np.log10(np.maximum(rel, 1e-4)) + 4.0) / 4.0


def compare(image, reference, heatmap=None) -> dict:
    """Every metric; writes the heat map PNG to ``heatmap`` when given."""
    result = metrics(image, reference)
    f = flip(image, reference)
    result["flip"] = None if f is None else f[0]
    if heatmap is not None:
        from pathlib import Path

        from PIL import Image

        from .imageio import _atomic_write

        data = heat(error_map(image, reference, None if f is None else f[1]))
        path = Path(heatmap)
        path.parent.mkdir(parents=True, exist_ok=True)
        _atomic_write(path, lambda tmp: Image.fromarray(data, "RGB").save(tmp, format="PNG"))
        result["heatmap"] = str(path)
    return result
