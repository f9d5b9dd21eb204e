"""``point``: an isotropic point light of radiant intensity ``intensity`` [W/sr] (RGB) at
``position`` (cl/lights/point.h samples it).

TOML: ``[[light]] type = "point"``, ``position`` (required), ``intensity`` (default 1).  Mitsuba 3:
``point`` (``position``, else to_world's origin).  pbrt-v4: ``point`` (``from``, ``I`` times ``scale``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .frames import LUMINANCE, affine_point, floats, record_rgb

INFINITE = False  # at a place in the scene (the light BVH bounds it)
TOML_KEYS = frozenset({"position", "intensity"})
MITSUBA_PLUGINS = {"point": ("intensity", "position", "to_world", "sampling_weight")}
PBRT_TYPES = ("point",)


@dataclass
class PointLight:
    """An isotropic point light of radiant intensity ``intensity`` [W/sr] (RGB)."""

    position: tuple = (0.0, 0.0, 0.0)
    intensity: tuple = (1.0, 1.0, 1.0)
    sampling_weight: float = 1.0  # its share of the picks with RenderSettings.light_sampler "uniform"


LIGHT = PointLight


def read_toml(t) -> PointLight:
    if "position" not in t:
        raise t.error("missing 'position'")
    return PointLight(position=tuple(float(x) for x in t.vector("position")), intensity=t.color("intensity", 1.0))


def pack(light: PointLight, r, place) -> float:
    """Fill the LIGHT record r; its power (luminance) for the light sampler: 4 pi I."""
    r["p"] = light.position
    r["rgb"] = record_rgb(light.intensity)
    return 4 * np.pi * float(r["rgb"] @ LUMINANCE)


def transformed(light: PointLight, m) -> PointLight:
    return replace(light, position=affine_point(m, light.position))


def to_mitsuba(light: PointLight) -> dict:
    return {"type": "point", "position": floats(light.position), "intensity": floats(light.intensity)}


def from_mitsuba(obj, read) -> PointLight:
    pos = obj.point("position", None)
    if pos is None:
        pos = read.to_world[:3, 3] if read.to_world is not None else np.zeros(3)
    intensity, _ = read.color("intensity", (1.0, 1.0, 1.0))
    return PointLight(position=tuple(map(float, pos)), intensity=intensity, sampling_weight=read.sampling_weight)


def from_pbrt(p, read) -> PointLight:
    pos = affine_point(read.ctm, p.numbers("from", ("point3", "point"), 3, [0.0, 0.0, 0.0]))
    intensity = read.spectrum("I", (1.0, 1.0, 1.0))
    return PointLight(position=tuple(map(float, pos)), intensity=tuple(c * read.scale for c in intensity))
