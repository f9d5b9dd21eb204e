"""The film (per-pixel sums of completed passes) and the statistics of a run, shared by every way
of rendering (one device, several devices, Dask, checkpoints)."""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from ..device import abi



@dataclass
class Film:
    """Radiance summed over completed passes (float64), its sum of squares (for the variance of
    each pixel's estimate), and how many passes that is.  Films of the same size add up.

    ``aov_sum`` (a film made with ``aovs=True``): the per-sample AOVs of the kernels summed the
    same way, ``abi.AOV_FLOATS`` per pixel at the ``abi.AOV_*`` offsets (render/aovs.py turns
    them into layers); None otherwise."""

    width: int
    height: int
    sum: np.ndarray = None
    sum_sq: np.ndarray = None
    passes: int = 0
    aov_sum: np.ndarray | None = None

    def __post_init__(self):
        if self.sum is None:
            self.sum = np.zeros((self.height * self.width, 3), np.float64)
        if self.sum_sq is None:
            self.sum_sq = np.zeros((self.height * self.width, 3), np.float64)

    @classmethod
    def new(cls, width: int, height: int, aovs: bool = False) -> "Film":
        """An empty film; with ``aovs`` it also sums the kernels' AOVs."""
        return cls(width, height, aov_sum=np.zeros((width * height, abi.AOV_FLOATS), np.float64) if aovs else None)

    def add_pass(self, radiance: np.ndarray, aov: np.ndarray | None = None) -> None:
        """One pass: radiance (P x 3) and, for a film with AOVs, the pass's AOV ring (P x AOV_FLOATS)."""
        r = radiance.astype(np.float64)
        self.sum += r
        self.sum_sq += r * r
        if self.aov_sum is not None:
            if aov is None:
                raise ValueError("this film sums AOVs: the pass must bring them")
            self.aov_sum += aov
        self.passes += 1

    def add(self, sum: np.ndarray, sum_sq: np.ndarray, passes: int, aov_sum: np.ndarray | None = None) -> None:
        """Another film's sums (passes that follow this film's, for the same pass order)."""
        self.sum += sum
        self.sum_sq += sum_sq
        if self.aov_sum is not None:
            if aov_sum is None:
                raise ValueError("this film sums AOVs: the film added must have them")
            self.aov_sum += aov_sum
        self.passes += passes

    def copy(self) -> "Film":
        return Film(self.width, self.height, sum=self.sum.copy(), sum_sq=self.sum_sq.copy(), passes=self.passes,
                    aov_sum=None if self.aov_sum is None else self.aov_sum.copy())

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
    stage_seconds: dict = field(default_factory=dict)  # kernel or host stage -> seconds (with --profile)

    def add_stage_seconds(self, stage_seconds: dict) -> None:
        """Add another run's stage times (a device of several, a Dask chunk)."""
        for name, seconds in stage_seconds.items():
            self.stage_seconds[name] = self.stage_seconds.get(name, 0.0) + seconds
