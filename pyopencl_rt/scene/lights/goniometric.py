"""``goniometric``: pbrt-v4's goniometric light, a point light at ``position`` whose radiant
intensity varies with the direction: I(w) = ``intensity`` (RGB) times Y(w), Y a profile over the
sphere stored as an equal-area square image (pbrt-v4's octahedral mapping; a colour image's Y is the
mean of its linear R, G and B, as pbrt-v4 makes it), read at its nearest texel.  The directions are
those of the light's frame ``to_world`` (3x3 local-to-world, its columns the local axes; None: the
identity) with pbrt-v4's swap of y and z: the profile's pole (the centre of its square) lies along
local +y.  Without a profile it is a point light (cl/lights/goniometric.h samples it).

TOML: ``[[light]] type = "goniometric"``, ``position`` and ``look_at`` (required: local +z toward
it), ``up`` (default +y: local +y, the profile's pole, nearest it), ``intensity`` (default 1),
``texture`` (the profile: a square image, sRGB unless HDR).  pbrt-v4: ``goniometric`` (its CTM the
frame, ``I`` times ``scale``, the square image ``filename``).  Mitsuba 3 has none.
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..textures import texture_from_array
from .frames import LUMINANCE, checked_frame, record_rgb, transformed_framed

INFINITE = False
TOML_KEYS = frozenset({"intensity", "texture", "position", "look_at", "up"})
MITSUBA_PLUGINS: dict = {}  # Mitsuba 3 has no goniometric emitter
PBRT_TYPES = ("goniometric",)
# pbrt-v4's swapYZ: its light space is the frame with y and z exchanged
SWAP_YZ = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, 1.0, 0.0]])


@dataclass
class GoniometricLight:
    """A goniometric light (this module's docstring); ``texture``: its profile, a Texture of Y in
    every channel (profile_texture; None: 1)."""

    position: tuple = (0.0, 0.0, 0.0)
    intensity: tuple = (1.0, 1.0, 1.0)
    texture: object = None
    to_world: np.ndarray | None = None
    sampling_weight: float = 1.0

    def frame(self) -> np.ndarray:
        return checked_frame(self.to_world)


LIGHT = GoniometricLight


def profile_texture(texture, where: str = "goniometric"):
    """The profile of an image texture: square (pbrt-v4 refuses others: not an equal-area map), its
    Y the mean of the linear R, G, B in every channel, looked up at the nearest texel, clamped."""
    if texture is None:
        return None
    h, w = texture.texels.shape[:2]
    if h != w:
        raise ValueError(f"{where}: the profile image is {w} x {h}, not square (an equal-area map is)")
    y = texture.texels[..., :3].astype(np.float64).mean(axis=2)
    return texture_from_array(np.repeat(y[:, :, None], 3, axis=2).astype(np.float32),
                              name=texture.name).with_lookup(wrap="clamp", filter="nearest")


def read_toml(t) -> GoniometricLight:
    position, frame, texture = t.aimed()
    try:
        profile = profile_texture(texture, t.where)
    except ValueError as exc:
        raise t.error(str(exc).split(": ", 1)[1]) from None
    return GoniometricLight(position=position, intensity=t.color("intensity", 1.0), texture=profile, to_world=frame)


def pack(light: GoniometricLight, r, place) -> float:
    """Fill the LIGHT record r (its frame: pbrt's light space, y and z swapped); its power: 4 pi I
    times the profile's mean (pbrt-v4's Phi)."""
    r["p"] = light.position
    r["frame"] = np.linalg.inv(light.frame() @ SWAP_YZ).reshape(-1)
    r["rgb"] = record_rgb(light.intensity)
    r["texture"] = place.texture_index(light.texture)
    mean = 1.0 if light.texture is None else float(light.texture.texels[..., 0].astype(np.float64).mean())
    return 4 * np.pi * float(r["rgb"] @ LUMINANCE) * mean


transformed = transformed_framed


def to_mitsuba(light: GoniometricLight) -> dict:
    raise ValueError("a GoniometricLight is not exported to Mitsuba (Mitsuba 3 has no such emitter)")


def from_pbrt(p, read) -> GoniometricLight:
    m = read.ctm
    if abs(np.linalg.det(m[:3, :3])) < 1e-300:
        raise read.error("the transform is singular")
    intensity = tuple(c * read.scale for c in read.spectrum("I", (1.0, 1.0, 1.0)))
    if p.string("filename") is None:  # pbrt-v4 warns and its empty image emits nothing
        read.warn('no "filename": the light emits nothing, as in pbrt-v4')
        return GoniometricLight(position=tuple(map(float, m[:3, 3])), intensity=(0.0, 0.0, 0.0), to_world=m[:3, :3].copy())
    texture = read.image(finite=True)  # pbrt-v4 refuses infinite or NaN texels
    try:
        profile = profile_texture(texture)
    except ValueError as exc:
        raise read.error(str(exc).split(": ", 1)[1]) from None
    return GoniometricLight(position=tuple(map(float, m[:3, 3])), intensity=intensity, texture=profile,
                            to_world=m[:3, :3].copy())
