"""``spot``: a point light at ``position`` shining along its local +z (``to_world``: the 3x3
local-to-world matrix, its columns the local axes in world space; None: the identity) with radiant
intensity ``intensity`` [W/sr] (RGB) on its axis, falling to 0 at ``cutoff_angle`` degrees from the
axis.  ``falloff`` "mitsuba": full inside ``beam_width`` degrees (None: 3/4 of the cutoff), then
linear in the angle down to the cutoff (Mitsuba 3's spot); "smoothstep": pbrt-v4's smoothstep of
the cosine between cos(cutoff) and cos(beam_width).  ``texture`` (a Texture or None) multiplies the
intensity at (u, v) = (0.5 + x / (2 z tan cutoff), 0.5 + y / (2 z tan cutoff)) of the local
direction (x, y, z), as Mitsuba projects it over the cone (cl/lights/spot.h samples it).

TOML: ``[[light]] type = "spot"``, ``position`` and ``look_at`` (required), ``up`` (default +y),
``intensity`` (default 1), ``cutoff_angle`` (default 20, at most 180), ``beam_width`` (default 3/4
of the cutoff, at most the cutoff), ``falloff`` ("mitsuba" or "smoothstep"), ``texture`` (an sRGB
image).  Mitsuba 3: ``spot`` (its ``texture`` times ``intensity``).  pbrt-v4: ``spot`` (``from``,
``to``, ``coneangle``, ``conedeltaangle``: the smoothstep falloff, ``I`` times ``scale``).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .frames import (LUMINANCE, affine_point, checked_frame, floats, look_at_frame, record_rgb, to_world_4x4,
                     transformed_framed)
from ...device import abi

INFINITE = False
TOML_KEYS = frozenset({"intensity", "cutoff_angle", "beam_width", "falloff", "texture", "position", "look_at", "up"})
MITSUBA_PLUGINS = {"spot": ("intensity", "texture", "cutoff_angle", "beam_width", "to_world", "sampling_weight")}
PBRT_TYPES = ("spot",)


@dataclass
class SpotLight:
    """A spot light (this module's docstring)."""

    position: tuple = (0.0, 0.0, 0.0)
    intensity: tuple = (1.0, 1.0, 1.0)
    cutoff_angle: float = 20.0
    beam_width: float | None = None
    falloff: str = "mitsuba"
    texture: object = None
    to_world: np.ndarray | None = None
    sampling_weight: float = 1.0

    def frame(self) -> np.ndarray:
        return checked_frame(self.to_world)

    def beam(self) -> float:
        return 0.75 * float(self.cutoff_angle) if self.beam_width is None else float(self.beam_width)


LIGHT = SpotLight


def read_toml(t) -> SpotLight:
    position, frame, texture = t.aimed()
    cutoff = t.number("cutoff_angle", 20.0, positive=True, maximum=180.0)
    beam = t.number("beam_width", 0.75 * cutoff, minimum=0.0, maximum=cutoff)
    falloff = t.choice("falloff", "falloff", ("mitsuba", "smoothstep")) if "falloff" in t else "mitsuba"
    return SpotLight(position=position, intensity=t.color("intensity", 1.0), cutoff_angle=cutoff, beam_width=beam,
                     falloff=falloff, texture=texture, to_world=frame)


def _cone_integral(f, cos_min: float) -> float:
    """The integral of f(theta) over the solid angle of the cone of directions within
    arccos(cos_min) of its axis (midpoint rule in theta, 2048 steps)."""
    top = math.acos(min(1.0, max(-1.0, cos_min)))
    theta = (np.arange(2048) + 0.5) / 2048 * top
    return float(2 * np.pi * np.sum(f(theta) * np.sin(theta)) * top / 2048)


def pack(light: SpotLight, r, place) -> float:
    """Fill the LIGHT record r; its power (luminance) for the light sampler: the intensity
    integrated over the cone, times the texture's mean."""
    cutoff = math.radians(float(light.cutoff_angle))
    beam = math.radians(light.beam())
    if not 0 < cutoff <= math.pi or not 0 <= beam <= cutoff:
        raise ValueError(f"a spot light needs 0 < beam_width <= cutoff_angle <= 180 degrees, got "
                         f"{light.beam():g} and {float(light.cutoff_angle):g}")
    if light.falloff not in ("mitsuba", "smoothstep"):
        raise ValueError(f"unknown spot falloff {light.falloff!r}: use mitsuba or smoothstep")
    m = light.frame()
    r["p"] = light.position
    r["frame"] = np.linalg.inv(m).reshape(-1)
    r["rgb"] = record_rgb(light.intensity)
    cc, cb = math.cos(cutoff), math.cos(beam)
    with np.errstate(divide="ignore"):
        r["cone"] = (cc, cb, cutoff, np.float64(1.0) / (cutoff - beam) if cutoff > beam else np.inf)
    tan = math.tan(cutoff)
    r["uv_scale"] = (0.5 / tan, 0.5 / tan) if cutoff < math.pi / 2 else (0.0, 0.0)
    r["texture"] = place.texture_index(light.texture)
    if light.falloff == "smoothstep":
        r["flags"] = abi.LIGHT_SPOT_SMOOTHSTEP

        def f(theta):
            t = np.clip((np.cos(theta) - cc) / (cb - cc), 0, 1) if cb > cc else (np.cos(theta) >= cc) * 1.0
            return t * t * (3 - 2 * t)
    else:
        def f(theta):
            return np.where(theta <= beam, 1.0, np.clip((cutoff - theta) / max(cutoff - beam, 1e-30), 0, 1))
    mean = 1.0 if light.texture is None else float(light.texture.mean_rgb() @ LUMINANCE)
    return _cone_integral(f, cc) * float(r["rgb"] @ LUMINANCE) * mean


transformed = transformed_framed


def to_mitsuba(light: SpotLight) -> dict:
    if light.texture is not None or light.falloff != "mitsuba":
        raise ValueError("a textured SpotLight, or one with pbrt-v4's conventions, is not exported to Mitsuba")
    return {"type": "spot", "to_world": to_world_4x4(light), "intensity": floats(light.intensity),
            "cutoff_angle": float(light.cutoff_angle), "beam_width": light.beam()}


def from_mitsuba(obj, read) -> SpotLight:
    intensity, _ = read.color("intensity", (1.0, 1.0, 1.0))
    tint, texture = read.color("texture", (1.0, 1.0, 1.0), texture_ok=True)
    cutoff = obj.float("cutoff_angle", 20.0, positive=True)
    beam = obj.float("beam_width", 0.75 * cutoff, minimum=0.0)
    if beam > cutoff or cutoff > 180:
        raise read.error(f"needs beam_width <= cutoff_angle <= 180, got {beam:g} and {cutoff:g}")
    position, frame = read.placed()
    return SpotLight(position=position, intensity=tuple(a * b for a, b in zip(intensity, tint)), cutoff_angle=cutoff,
                     beam_width=beam, texture=texture, to_world=frame, sampling_weight=read.sampling_weight)


def from_pbrt(p, read) -> SpotLight:
    src = np.asarray(p.numbers("from", ("point3", "point"), 3, [0.0, 0.0, 0.0]), np.float64)
    dst = np.asarray(p.numbers("to", ("point3", "point"), 3, [0.0, 0.0, 1.0]), np.float64)
    axis = dst - src
    if not np.linalg.norm(axis) > 0:
        raise read.error('"from" and "to" are the same point')
    cone = p.float("coneangle", 30.0)
    delta = p.float("conedeltaangle", 5.0)
    if not 0 < cone <= 180 or not 0 <= delta <= cone:
        raise read.error(f"needs 0 < coneangle <= 180 and 0 <= conedeltaangle <= coneangle, got {cone:g} and {delta:g}")
    # a frame whose +z is the axis (its x and y do not matter: no texture), then the CTM
    up = np.array([0.0, 1.0, 0.0]) if abs(axis[1]) < 0.9 * np.linalg.norm(axis) else np.array([1.0, 0.0, 0.0])
    frame = read.ctm[:3, :3] @ look_at_frame(src, dst, up)
    if abs(np.linalg.det(frame)) < 1e-300:
        raise read.error("the transform is singular")
    intensity = read.spectrum("I", (1.0, 1.0, 1.0))
    return SpotLight(position=tuple(map(float, affine_point(read.ctm, src))), intensity=tuple(c * read.scale for c in intensity),
                     cutoff_angle=cone, beam_width=cone - delta, falloff="smoothstep", to_world=frame)
