"""``directional``: a light infinitely far away, travelling along ``direction``, that gives a
surface facing it the irradiance ``irradiance`` (RGB) (cl/lights/directional.h samples it).

TOML: ``[[light]] type = "directional"``, ``direction`` (required: the way the light travels, not
zero), ``irradiance`` (default 1).  Mitsuba 3: ``directional`` (``direction``, else to_world's +z).
pbrt-v4: ``distant`` (from ``from`` to ``to``, ``L`` times ``scale``).
"""
from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .frames import LUMINANCE, floats, record_rgb, transform_vector

INFINITE = True  # picked as pbrt-v4's BVH light sampler picks infinitely distant lights
TOML_KEYS = frozenset({"direction", "irradiance"})
MITSUBA_PLUGINS = {"directional": ("irradiance", "direction", "to_world", "sampling_weight")}
PBRT_TYPES = ("distant",)


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


def transformed(light: DirectionalLight, m) -> DirectionalLight:
    return replace(light, direction=tuple(transform_vector(m, light.direction)))


def to_mitsuba(light: DirectionalLight) -> dict:
    return {"type": "directional", "direction": floats(light.direction), "irradiance": floats(light.irradiance)}


def from_mitsuba(obj, read) -> DirectionalLight:
    d = obj.point("direction", None)
    if d is None:
        d = transform_vector(read.to_world, [0.0, 0.0, 1.0]) if read.to_world is not None else np.array([0.0, 0.0, 1.0])
    if not np.linalg.norm(d) > 0:
        raise read.error("the direction is zero")
    irradiance, _ = read.color("irradiance", (1.0, 1.0, 1.0))
    return DirectionalLight(direction=tuple(map(float, d / np.linalg.norm(d))), irradiance=irradiance,
                            sampling_weight=read.sampling_weight)


def from_pbrt(p, read) -> DirectionalLight:
    src = np.asarray(p.numbers("from", ("point3", "point"), 3, [0.0, 0.0, 0.0]), np.float64)
    dst = np.asarray(p.numbers("to", ("point3", "point"), 3, [0.0, 0.0, 1.0]), np.float64)
    direction = transform_vector(read.ctm, dst - src)
    if not np.linalg.norm(direction) > 0:
        raise read.error('"from" and "to" are the same point' if not np.linalg.norm(dst - src) > 0 else
                         "the transform is singular (it takes the direction to zero)")
    radiance = read.spectrum("L", (1.0, 1.0, 1.0))
    return DirectionalLight(direction=tuple(map(float, direction / np.linalg.norm(direction))),
                            irradiance=tuple(c * read.scale for c in radiance))
