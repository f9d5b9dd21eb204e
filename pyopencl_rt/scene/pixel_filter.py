"""A pixel reconstruction filter, as scene files and settings give it (pyopencl_rt/render/filters.py
samples it; docs/SCENE_FORMAT.md, "Pixel filters", lists the types)."""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass

import numpy as np

# The types, each separable: f(x, y) = f(x) f(y), with half widths radius (x, y) in pixels
FILTERS = ("box", "tent", "gaussian", "mitchell", "lanczos")
MAX_FILTER_RADIUS = 16.0  # pixels


@dataclass(frozen=True)
class PixelFilter:
    """A reconstruction filter: its type (one of FILTERS), its half widths along x and y (pixels)
    and its parameters: gaussian ``sigma`` (exp(-x^2 / 2 sigma^2) minus its value at the radius,
    as Mitsuba 3 and pbrt-v4 have it), mitchell ``b``, ``c`` (Mitchell-Netravali over [-radius,
    radius]), lanczos ``tau`` (sinc(x) sinc(x / tau), cut at the radius).  Those of other types
    are ignored (and left at their defaults)."""

    type: str = "box"
    radius: tuple = (0.5, 0.5)
    sigma: float = 0.5
    b: float = 1.0 / 3.0
    c: float = 1.0 / 3.0
    tau: float = 3.0

    @classmethod
    def from_value(cls, value) -> "PixelFilter":
        """A PixelFilter from itself or from its dict (as_dict, JSON); TypeError/ValueError if it is none."""
        if isinstance(value, cls):
            return value.checked()
        if not isinstance(value, dict):
            raise TypeError(f"a pixel filter must be a table, got {type(value).__name__}")
        unknown = set(value) - {f.name for f in dataclasses.fields(cls)}
        if unknown:
            raise ValueError(f"unknown pixel filter keys {sorted(unknown)}")
        radius = value.get("radius", (0.5, 0.5))
        if not isinstance(radius, (list, tuple)) or len(radius) != 2:
            raise ValueError(f"a pixel filter's radius must be two numbers, got {radius!r}")
        return cls(**{**value, "radius": tuple(radius)}).checked()

    def checked(self) -> "PixelFilter":
        """Itself, with its numbers as floats, after checking them (ValueError, one line)."""
        if self.type not in FILTERS:
            raise ValueError(f"unknown pixel filter {self.type!r}: use one of {', '.join(FILTERS)}")
        numbers = {"radius x": self.radius[0], "radius y": self.radius[1], "sigma": self.sigma, "b": self.b,
                   "c": self.c, "tau": self.tau}
        for name, v in numbers.items():
            if isinstance(v, bool) or not isinstance(v, (int, float, np.floating, np.integer)) or not np.isfinite(v):
                raise ValueError(f"pixel filter {name} must be a finite number, got {v!r}")
        for name in ("radius x", "radius y"):
            if not 0 < numbers[name] <= MAX_FILTER_RADIUS:
                raise ValueError(f"pixel filter {name} must be in (0, {MAX_FILTER_RADIUS:g}] pixels, "
                                 f"got {numbers[name]!r}")
        if not self.sigma > 0 or not self.tau > 0:
            raise ValueError(f"pixel filter sigma and tau must be > 0, got {self.sigma!r}, {self.tau!r}")
        return dataclasses.replace(self, radius=(float(self.radius[0]), float(self.radius[1])),
                                   sigma=float(self.sigma), b=float(self.b), c=float(self.c), tau=float(self.tau))

    def as_dict(self) -> dict:
        """JSON values (the radius as a list)."""
        return {"type": self.type, "radius": list(self.radius), "sigma": self.sigma, "b": self.b, "c": self.c,
                "tau": self.tau}
