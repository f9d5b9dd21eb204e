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
    them into layers); None otherwise.

    Adaptive sampling (render/adaptive.py) adds passes that cover some pixels only
    (``add_pass(..., pixels=)``): ``counts`` then holds each pixel's samples (None while every
    pixel has ``passes``), and ``passes`` stays the number of passes, the next pass's index."""

    width: int
    height: int
    sum: np.ndarray = None
    sum_sq: np.ndarray = None
    passes: int = 0
    aov_sum: np.ndarray | None = None
    counts: np.ndarray | None = None  # int64 per pixel; None: every pixel has ``passes`` samples

    def __post_init__(self):
        if self.sum is None:
            self.sum = np.zeros((self.height * self.width, 3), np.float64)
        if self.sum_sq is None:
            self.sum_sq = np.zeros((self.height * self.width, 3), np.float64)

    @classmethod
    def new(cls, width: int, height: int, aovs: bool = False) -> "Film":
        """An empty film; with ``aovs`` it also sums the kernels' AOVs."""
        return cls(width, height, aov_sum=np.zeros((width * height, abi.AOV_FLOATS), np.float64) if aovs else None)

    def pixel_counts(self) -> np.ndarray:
        """Samples of each pixel (P, int64)."""
        return self.counts if self.counts is not None else np.full(self.width * self.height, self.passes, np.int64)

    def add_pass(self, radiance: np.ndarray, aov: np.ndarray | None = None, pixels: np.ndarray | None = None) -> None:
        """One pass: radiance (P x 3) and, for a film with AOVs, the pass's AOV ring (P x AOV_FLOATS).
        With ``pixels`` (indices) the pass covers those pixels only and ``radiance`` holds their
        values, in that order (len(pixels) x 3)."""
        if pixels is None:
            # in place, through one reused float64 scratch: the same sums as r = float64(radiance),
            # sum += r, sum_sq += r * r, without allocating (and page-faulting) two temporaries per
            # pass, which cost the megakernel's host loop 2 ms a pass at 256 x 256
            np.add(self.sum, radiance, out=self.sum)
            square = self._scratch(radiance.shape)
            np.multiply(radiance, radiance, out=square, dtype=np.float64)
            self.sum_sq += square
            if self.counts is not None:
                self.counts += 1
        else:
            r = radiance.astype(np.float64)
            if self.counts is None:
                self.counts = self.pixel_counts().copy()
            self.sum[pixels] += r
            self.sum_sq[pixels] += r * r
            self.counts[pixels] += 1
        if self.aov_sum is not None:
            if aov is None:
                raise ValueError("this film sums AOVs: the pass must bring them")
            self.aov_sum[slice(None) if pixels is None else pixels] += aov
        self.passes += 1

    def _scratch(self, shape) -> np.ndarray:
        """A float64 array of ``shape`` kept between passes (not part of the film's state)."""
        scratch = self.__dict__.get("_square")
        if scratch is None or scratch.shape != tuple(shape):
            scratch = np.empty(shape, np.float64)
            self.__dict__["_square"] = scratch
        return scratch

    def __getstate__(self):  # pickled (Dask, checkpoints) without the scratch
        state = self.__dict__.copy()
        state.pop("_square", None)
        return state

    def add_passes(self, radiance: np.ndarray, pixels: np.ndarray) -> None:
        """Passes over the same ``pixels`` (k x len(pixels) x 3), without AOVs: the sums of
        ``add_pass`` one pass after the other, bit for bit, gathered and scattered once."""
        if self.aov_sum is not None:
            raise ValueError("this film sums AOVs: add the passes one by one with them")
        if self.counts is None:
            self.counts = self.pixel_counts().copy()
        s, q = self.sum[pixels], self.sum_sq[pixels]
        for r in radiance:
            r = r.astype(np.float64)
            s += r
            q += r * r
        self.sum[pixels], self.sum_sq[pixels] = s, q
        self.counts[pixels] += len(radiance)
        self.passes += len(radiance)

    def add(self, sum: np.ndarray, sum_sq: np.ndarray, passes: int, aov_sum: np.ndarray | None = None) -> None:
        """Another film's sums (passes that follow this film's, for the same pass order)."""
        self.sum += sum
        self.sum_sq += sum_sq
        if self.aov_sum is not None:
            if aov_sum is None:
                raise ValueError("this film sums AOVs: the film added must have them")
            self.aov_sum += aov_sum
        if self.counts is not None:
            self.counts += passes
        self.passes += passes

    def copy(self) -> "Film":
        def dup(a):
            return None if a is None else a.copy()

        return Film(self.width, self.height, sum=self.sum.copy(), sum_sq=self.sum_sq.copy(), passes=self.passes,
                    aov_sum=dup(self.aov_sum), counts=dup(self.counts))

    def image(self) -> np.ndarray:
        if self.counts is None:
            scale = 1.0 / max(self.passes, 1)
            return (self.sum * scale).astype(np.float32).reshape(self.height, self.width, 3)
        scale = 1.0 / np.maximum(self.counts, 1)
        return (self.sum * scale[:, None]).astype(np.float32).reshape(self.height, self.width, 3)

    def variance_of_mean(self) -> np.ndarray:
        """Unbiased estimate of the variance of each pixel's mean (H x W x 3 float64); +inf for a
        pixel of fewer than 2 samples."""
        if self.counts is None:
            n = self.passes
            if n < 2:
                return np.full((self.height, self.width, 3), np.inf)
            mean = self.sum / n
            var = np.maximum(self.sum_sq / n - mean * mean, 0.0) * (n / (n - 1))
            return (var / n).reshape(self.height, self.width, 3)
        n = self.counts.astype(np.float64)[:, None]
        with np.errstate(divide="ignore", invalid="ignore"):
            mean = self.sum / n
            var = np.maximum(self.sum_sq / n - mean * mean, 0.0) * (n / (n - 1)) / n
        return np.where(n >= 2, var, np.inf).reshape(self.height, self.width, 3)


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
