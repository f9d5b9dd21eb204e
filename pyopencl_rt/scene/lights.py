"""The scene's lights other than emissive surfaces: point, directional, spot and projector lights
and the environment (:mod:`.model` re-exports them; cl/render/lights.h renders them)."""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np


@dataclass
class PointLight:
    """An isotropic point light of radiant intensity ``intensity`` [W/sr] (RGB)."""

    position: tuple = (0.0, 0.0, 0.0)
    intensity: tuple = (1.0, 1.0, 1.0)
    sampling_weight: float = 1.0  # its share of the picks with RenderSettings.light_sampler "uniform"


@dataclass
class DirectionalLight:
    """A light infinitely far away, travelling along ``direction``, that gives a surface facing
    it the irradiance ``irradiance`` (RGB)."""

    direction: tuple = (0.0, -1.0, 0.0)
    irradiance: tuple = (1.0, 1.0, 1.0)
    sampling_weight: float = 1.0


def look_at_frame(origin, target, up) -> np.ndarray:
    """The 3x3 local-to-world matrix of Mitsuba's ``lookat``: local +z toward ``target``, +y
    nearest ``up``, +x = y x z (its columns are the local axes in world space)."""
    d = np.asarray(target, np.float64) - np.asarray(origin, np.float64)
    if not np.linalg.norm(d) > 0:
        raise ValueError("look_at: the target is the origin")
    d /= np.linalg.norm(d)
    left = np.cross(np.asarray(up, np.float64), d)
    if not np.linalg.norm(left) > 0:
        raise ValueError("look_at: up is parallel to the viewing direction")
    left /= np.linalg.norm(left)
    return np.stack([left, np.cross(d, left), d], axis=1)


def _frame(to_world) -> np.ndarray:
    m = np.eye(3) if to_world is None else np.asarray(to_world, np.float64).reshape(3, 3)
    if not np.all(np.isfinite(m)) or abs(np.linalg.det(m)) < 1e-300:
        raise ValueError("a light's to_world must be a finite, invertible 3x3 matrix")
    return m


@dataclass
class SpotLight:
    """A point light at ``position`` shining along its local +z (``to_world``: the 3x3
    local-to-world matrix, its columns the local axes in world space; None: the identity) with
    radiant intensity ``intensity`` [W/sr] (RGB) on its axis, falling to 0 at ``cutoff_angle``
    degrees from the axis.  ``falloff`` "mitsuba": full inside ``beam_width`` degrees (None: 3/4 of
    the cutoff), then linear in the angle down to the cutoff (Mitsuba 3's spot); "smoothstep":
    pbrt-v4's smoothstep of the cosine between cos(cutoff) and cos(beam_width).  ``texture`` (a
    Texture or None) multiplies the intensity at (u, v) = (0.5 + x / (2 z tan cutoff), 0.5 + y /
    (2 z tan cutoff)) of the local direction (x, y, z), as Mitsuba projects it over the cone."""

    position: tuple = (0.0, 0.0, 0.0)
    intensity: tuple = (1.0, 1.0, 1.0)
    cutoff_angle: float = 20.0
    beam_width: float | None = None
    falloff: str = "mitsuba"
    texture: object = None
    to_world: np.ndarray | None = None
    sampling_weight: float = 1.0

    def frame(self) -> np.ndarray:
        return _frame(self.to_world)

    def beam(self) -> float:
        return 0.75 * float(self.cutoff_angle) if self.beam_width is None else float(self.beam_width)


@dataclass
class ProjectorLight:
    """A pinhole at ``position`` projecting an image along its local +z (``to_world`` as for
    SpotLight; local +y is the image's up), ``fov`` degrees wide along the image's width, the image
    ``texture`` (None: constant) times ``irradiance`` (RGB) times ``scale``.  ``convention``
    "mitsuba": the irradiance on the plane at z = 1 is pi scale irradiance texture, local +x on
    the image's left (projector.cpp, its camera frame); "pbrt": the intensity toward a texel is
    scale irradiance texture, local +x on the image's right (pbrt-v4's "projection" light)."""

    position: tuple = (0.0, 0.0, 0.0)
    irradiance: tuple = (1.0, 1.0, 1.0)
    texture: object = None
    scale: float = 1.0
    fov: float = 45.0
    convention: str = "mitsuba"
    to_world: np.ndarray | None = None
    sampling_weight: float = 1.0

    def frame(self) -> np.ndarray:
        return _frame(self.to_world)

    def aspect(self) -> float:
        """Width over height of the projected image (1 without a texture)."""
        return 1.0 if self.texture is None else self.texture.width / self.texture.height


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
