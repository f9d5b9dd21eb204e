"""``projector``: a pinhole at ``position`` projecting an image along its local +z (``to_world`` as
for the spot; local +y is the image's up), ``fov`` degrees wide along the image's width, the image
``texture`` (None: constant) times ``irradiance`` (RGB) times ``scale``.  ``convention``
"mitsuba": the irradiance on the plane at z = 1 is pi scale irradiance texture, local +x on the
image's left (projector.cpp, its camera frame); "pbrt": the intensity toward a texel is scale
irradiance texture, local +x on the image's right (pbrt-v4's "projection" light)
(cl/lights/projector.h samples it).

TOML: ``[[light]] type = "projector"``, ``position`` and ``look_at`` (required), ``up`` (default
+y), ``irradiance`` (default 1), ``scale`` (default 1), ``fov`` (default 45), ``texture`` (an sRGB
image); Mitsuba's convention.  Mitsuba 3: ``projector`` (``fov``/``fov_axis`` or ``focal_length``
over its image).  pbrt-v4: ``projection`` (the image ``filename`` from the CTM's origin along its +z,
``fov`` (default 90) across the image's shorter side, intensity ``scale`` x the texel).
"""
from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .frames import LUMINANCE, checked_frame, floats, record_rgb, to_world_4x4, transformed_framed
from ...device import abi

INFINITE = False
TOML_KEYS = frozenset({"irradiance", "scale", "fov", "texture", "position", "look_at", "up"})
MITSUBA_PLUGINS = {"projector": ("irradiance", "scale", "fov", "fov_axis", "focal_length", "to_world", "sampling_weight")}
PBRT_TYPES = ("projection",)


@dataclass
class ProjectorLight:
    """A projector (this module's docstring)."""

    position: tuple = (0.0, 0.0, 0.0)
    irradiance: tuple = (1.0, 1.0, 1.0)
    texture: object = None
    scale: float = 1.0
    fov: float = 45.0
    convention: str = "mitsuba"
    to_world: np.ndarray | None = None
    sampling_weight: float = 1.0

    def frame(self) -> np.ndarray:
        return checked_frame(self.to_world)

    def aspect(self) -> float:
        """Width over height of the projected image (1 without a texture)."""
        return 1.0 if self.texture is None else self.texture.width / self.texture.height


LIGHT = ProjectorLight


def read_toml(t) -> ProjectorLight:
    position, frame, texture = t.aimed()
    fov = t.number("fov", 45.0, positive=True, maximum=179.999)
    return ProjectorLight(position=position, irradiance=t.color("irradiance", 1.0), texture=texture,
                          scale=t.number("scale", 1.0, minimum=0.0), fov=fov, to_world=frame)


def pack(light: ProjectorLight, r, place) -> float:
    """Fill the LIGHT record r; its power (luminance) for the light sampler."""
    fov = float(light.fov)
    if not 0 < fov < 180:
        raise ValueError(f"a projector's fov must be between 0 and 180 degrees, got {fov:g}")
    if light.convention not in ("mitsuba", "pbrt"):
        raise ValueError(f"unknown projector convention {light.convention!r}: use mitsuba or pbrt")
    m = light.frame()
    t, aspect = math.tan(math.radians(fov) / 2), light.aspect()
    r["p"] = light.position
    r["frame"] = np.linalg.inv(m).reshape(-1)
    r["dir"] = m[:, 2]
    rgb = np.asarray(record_rgb(light.irradiance), np.float64) * float(light.scale)
    # v grows toward local -y (the image upright); u toward -x in Mitsuba (its camera frame: +x on
    # the image's left), toward +x in pbrt-v4
    r["uv_scale"] = ((-0.5 if light.convention == "mitsuba" else 0.5) / t, -0.5 * aspect / t)
    r["texture"] = place.texture_index(light.texture)
    mean = 1.0 if light.texture is None else float(light.texture.mean_rgb() @ LUMINANCE)
    area = 4 * t * t / aspect  # of the image on the plane z = 1
    if light.convention == "mitsuba":
        r["flags"] = abi.LIGHT_PROJECTOR_COS3
        rgb = rgb * np.pi
        power = float(rgb @ LUMINANCE) * mean * area
    else:  # intensity I over the image's solid angle: integral of dA cos^3 over z = 1
        xs = (np.arange(256) + 0.5) / 256 * 2 - 1
        x, y = np.meshgrid(xs * t, xs * t / aspect)
        power = float(rgb @ LUMINANCE) * mean * float(np.mean((1 + x * x + y * y) ** -1.5)) * area
    r["rgb"] = rgb
    return power


transformed = transformed_framed


def to_mitsuba(light: ProjectorLight) -> dict:
    if light.texture is not None or light.convention != "mitsuba":
        raise ValueError("a textured ProjectorLight, or one with pbrt-v4's conventions, is not exported to Mitsuba")
    return {"type": "projector", "to_world": to_world_4x4(light), "irradiance": floats(light.irradiance),
            "scale": float(light.scale), "fov": float(light.fov)}


def from_mitsuba(obj, read) -> ProjectorLight:
    irradiance, texture = read.color("irradiance", (1.0, 1.0, 1.0), texture_ok=True)
    scale = obj.float("scale", 1.0)
    aspect = 1.0 if texture is None else texture.width / texture.height
    fov = read.fov_x(aspect)
    position, frame = read.placed()
    return ProjectorLight(position=position, irradiance=irradiance, texture=texture, scale=scale, fov=fov,
                          to_world=frame, sampling_weight=read.sampling_weight)


def from_pbrt(p, read) -> ProjectorLight:
    texture = read.image()
    fov = p.float("fov", 90.0)
    if not 0 < fov < 180:
        raise read.error(f"fov must be between 0 and 180 degrees, got {fov:g}")
    aspect = texture.width / texture.height
    fov_x = fov if aspect <= 1 else float(np.degrees(2 * np.arctan(np.tan(np.radians(fov) / 2) * aspect)))
    m = read.ctm
    if abs(np.linalg.det(m[:3, :3])) < 1e-300:
        raise read.error("the transform is singular")
    read.warn("the image is interpolated bilinearly (pbrt-v4 takes the nearest texel)")
    return ProjectorLight(position=tuple(map(float, m[:3, 3])), texture=texture, scale=read.scale, fov=fov_x,
                          convention="pbrt", to_world=m[:3, :3].copy())
