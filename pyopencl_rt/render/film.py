"""The film (per-pixel sums of completed passes) and the statistics of a run, shared by every way
of rendering (one device, several devices, Dask, checkpoints)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

STAGES = ("generate", "extend", "shade", "shadow", "accumulate")


@dataclass
class Film:
    """Radiance summed over completed passes (float64), its sum of squares (for the variance of
    each pixel's estimate), and how many passes that is.  Films of the same size add up."""

    width: int
    height: int
    sum: np.ndarray = None
    sum_sq: np.ndarray = None
    passes: int = 0

    def __post_init__(self):
        if self.sum is None:
            self.sum = np.zeros((self.height * self.width, 3), np.float64)
        if self.sum_sq is None:
            self.sum_sq = np.zeros((self.height * self.width, 3), np.float64)

    def add_pass(self, radiance: np.ndarray) -> None:
        r = radiance.astype(np.float64)
        self.sum += r
        self.sum_sq += r * r
        self.passes += 1

    def image(self) -> np.ndarray:
        scale = 1.0 / max(self.passes, 1)
        return (self.sum * scale).astype(np.float32).reshape(self.height, self.width, 3)

    def variance_of_mean(self) -> np.ndarray:
        """Unbiased estimate of the variance of each pixel's mean (H x W x 3 float64)."""
        n = self.passes
        if n < 2:
            return np.full((self.height, self.width, 3), np.inf)
        mean = self.sum / n
        var = np.maximum(self.sum_sq / n - mean * mean, 0.0) * (n / (n - 1))
        return (var / n).reshape(self.height, self.width, 3)


@dataclass
class RunStats:
    passes: int = 0
    samples: int = 0
    seconds: float = 0.0
    iterations: int = 0
    rays_extend: int = 0
    rays_shadow: int = 0
    nonfinite: int = 0
    interrupted: bool = False
    stage_seconds: dict = field(default_factory=lambda: {s: 0.0 for s in STAGES})
