"""The environment light: radiance from every direction, constant or an equirectangular map
(sampled by cl/lights/environment.h; its tables and record: pyopencl_rt/render/lights.py).  One
per scene (Scene.environment), not a registered type: its loaders and tables are its own."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class Environment:
    """Radiance arriving from infinitely far in every direction: ``radiance`` (RGB) times, when
    given, the equirectangular map ``image`` (H x W x 3 linear RGB, row 0 = up (+y); cl/render/lights.h
    gives the direction of each texel)."""

    radiance: tuple = (1.0, 1.0, 1.0)
    image: np.ndarray | None = None
    source: str | None = None  # the map's file, for messages
    # the map's frame: world directions are turned by this 3x3 rotation (None: the identity) before
    # (u, v) is taken; rows "centred" in [0, 1] (row i at v = (i + 0.5) / H) or on the "poles" (row i
    # at v = i / (H - 1), Mitsuba's envmap); texels are interpolated bilinearly
    rotation: np.ndarray | None = None
    rows: str = "centred"
    sampling_weight: float = 1.0
