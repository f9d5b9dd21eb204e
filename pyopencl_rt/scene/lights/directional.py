"""``directional``: a light infinitely far away, travelling along ``direction``, that gives a
surface facing it the irradiance ``irradiance`` (RGB) (cl/lights/directional.h samples it).

TOML: ``[[light]] type = "directional"``, ``direction`` (required: the way the light travels, not
zero), ``irradiance`` (default 1).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .frames import LUMINANCE, record_rgb

INFINITE = True  # picked as pbrt-v4's BVH light sampler picks infinitely distant lights
TOML_KEYS = frozenset({"direction", "irradiance"})


@dataclass
class DirectionalLight:
    """A light infinitely far away, travelling along ``direction``, that gives a surface facing
    it the irradiance ``irradiance`` (RGB)."""

    direction: tuple = (0.0, -1.0, 0.0)
    irradiance: tuple = (1.0, 1.0, 1.0)
    sampling_weight: float = 1.0


LIGHT = DirectionalLight


def read_toml(t) -> DirectionalLight:
    if "direction" not in t:
        raise t.error("missing 'direction' (the way the light travels)")
    d = t.vector("direction")
    if not np.linalg.norm(d) > 0:
        raise t.error("'direction' must not be zero")
    return DirectionalLight(direction=tuple(float(x) for x in d / np.linalg.norm(d)),
                            irradiance=t.color("irradiance", 1.0))


def pack(light: DirectionalLight, r, place) -> float:
    """Fill the LIGHT record r (the scene's bounding sphere ``place.centre``, ``place.radius`` for
    the shadow rays); its power: pi r^2 E."""
    d = np.asarray(light.direction, np.float64)
    norm = np.linalg.norm(d)
    if not norm > 0:
        raise ValueError("a directional light needs a non-zero direction")
    r["dir"] = d / norm
    r["p"], r["radius"] = place.centre, place.radius
    r["rgb"] = record_rgb(light.irradiance)
    return np.pi * place.radius**2 * float(r["rgb"] @ LUMINANCE)


def mirrored(light: DirectionalLight, mirror) -> DirectionalLight:
    direction = np.asarray(mirror, np.float64)[:3, :3] @ np.asarray(light.direction, np.float64)
    return replace(light, direction=tuple(np.asarray(direction, np.float64)))


def to_mitsuba(light: DirectionalLight) -> dict:
    return {"type": "directional", "direction": [float(x) for x in light.direction],
            "irradiance": [float(x) for x in light.irradiance]}
