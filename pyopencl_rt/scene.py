"""The in-memory scene: what every loader produces and what the renderer consumes.

Units are whatever the scene file uses; radiance and albedo are linear RGB.  Emission is
one-sided (the side the triangle's geometric normal (v1 - v0) x (v2 - v0) faces, or the outside
of a sphere) unless the material is two-sided, as for Mitsuba's and pbrt's area lights.
"""
from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from . import layout

INTEGRATORS = ("path", "bsdf", "nee")


@dataclass
class Material:
    name: str = "default"
    albedo: tuple = (0.8, 0.8, 0.8)
    emission: tuple = (0.0, 0.0, 0.0)
    two_sided: bool = False
    type: str = "diffuse"

    @property
    def is_emissive(self) -> bool:
        return max(self.emission) > 0.0


@dataclass
class Camera:
    eye: tuple = (0.0, 0.0, 5.0)
    look_at: tuple = (0.0, 0.0, 0.0)
    up: tuple = (0.0, 1.0, 0.0)
    fov: float = 40.0  # degrees, along the vertical axis

    def record(self, width: int, height: int) -> np.ndarray:
        """The CAMERA struct for an image of width x height."""
        eye = np.asarray(self.eye, np.float64)
        forward = np.asarray(self.look_at, np.float64) - eye
        forward /= np.linalg.norm(forward)
        right = np.cross(forward, np.asarray(self.up, np.float64))
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        tan_half = np.tan(np.radians(self.fov) / 2)
        rec = np.zeros((), layout.CAMERA)
        rec["origin"] = eye
        rec["forward"] = forward
        rec["right"] = right * tan_half * width / height
        rec["up"] = up * tan_half
        rec["width"] = width
        rec["height"] = height
        return rec


@dataclass
class RenderSettings:
    width: int = 512
    height: int = 512
    spp: int = 64
    max_depth: int = 8
    integrator: str = "path"
    seed: int = 0
    rr_depth: int = 3  # Russian roulette starts after this many bounces


@dataclass
class Scene:
    vertices: np.ndarray  # (V, 3) float32, world space
    faces: np.ndarray  # (F, 3) int32
    face_materials: np.ndarray  # (F,) int32 index into materials
    materials: list  # list[Material]
    camera: Camera = field(default_factory=Camera)
    spheres: np.ndarray = field(default_factory=lambda: np.zeros((0, 4), np.float32))  # (S, 4) centre xyz, radius
    sphere_materials: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int32))
    settings: RenderSettings = field(default_factory=RenderSettings)
    source: str = "<memory>"

    def material_records(self) -> np.ndarray:
        recs = np.zeros(max(1, len(self.materials)), layout.MATERIAL)
        for i, m in enumerate(self.materials):
            recs[i]["albedo"] = m.albedo
            recs[i]["emission"] = m.emission
            recs[i]["type"] = layout.MATERIAL_DIFFUSE
            recs[i]["flags"] = layout.MATERIAL_FLAG_TWO_SIDED if m.two_sided else 0
        return recs

    def sphere_records(self) -> np.ndarray:
        recs = np.zeros(len(self.spheres), layout.SPHERE)
        if len(self.spheres):
            recs["center"] = self.spheres[:, :3]
            recs["radius"] = self.spheres[:, 3]
        return recs
