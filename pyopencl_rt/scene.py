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


# Complex indices of refraction eta + i k of named conductors at the RGB wavelengths 650, 550
# and 450 nm (sampled from the refractiveindex.info data sets, as tabulated in Chaos Group's
# "Understanding metalness", 2014).
CONDUCTORS = {
    "gold": ((0.18299, 0.42108, 1.3734), (3.4242, 2.3459, 1.7704)),
    "silver": ((0.16262, 0.14512, 0.13550), (4.0728, 3.1900, 2.1997)),
    "copper": ((0.27105, 0.67693, 1.3164), (3.6092, 2.6248, 2.2921)),
    "aluminium": ((1.3456, 0.96521, 0.61722), (7.4746, 6.3995, 5.3031)),
}


@dataclass
class Material:
    """A material; ``type`` is one of :data:`MATERIAL_TYPES` (documented in docs/SCENE_FORMAT.md
    and at the top of each ``cl/materials/<type>.h``).  Every type may emit.

    * ``diffuse``: ``albedo``.
    * ``conductor``: ``alpha`` (GGX; 0 = mirror) and either ``eta``/``k`` (complex IOR per RGB
      channel) or, when ``eta`` is None, ``f0`` (Schlick; default 1 = a perfect mirror).
    * ``dielectric``: ``ior`` (inside relative to outside), ``alpha``, ``tint``.
    * ``gltf``: ``albedo`` (baseColor), ``metallic``, ``alpha`` (= roughness^2), ``ior``.
    """

    name: str = "default"
    albedo: tuple = (0.8, 0.8, 0.8)
    emission: tuple = (0.0, 0.0, 0.0)
    two_sided: bool = False
    type: str = "diffuse"
    alpha: float = 0.0  # GGX alpha (the scene format's roughness squared)
    metallic: float = 0.0
    ior: float = 1.5
    f0: tuple = (1.0, 1.0, 1.0)
    eta: tuple | None = None
    k: tuple | None = None
    tint: tuple = (1.0, 1.0, 1.0)

    @property
    def is_emissive(self) -> bool:
        return max(self.emission) > 0.0

    @property
    def roughness(self) -> float:
        """Perceptual roughness sqrt(alpha)."""
        return float(np.sqrt(self.alpha))

    def record(self) -> np.ndarray:
        """The MATERIAL struct."""
        if self.type not in layout.MATERIAL_TYPES:
            raise ValueError(f"material {self.name!r}: unknown type {self.type!r}")
        rec = np.zeros((), layout.MATERIAL)
        rec["type"] = layout.MATERIAL_TYPES[self.type]
        rec["albedo"] = self.albedo
        rec["emission"] = self.emission
        flags = layout.MATERIAL_FLAG_TWO_SIDED if self.two_sided else 0
        rec["alpha"] = self.alpha
        rec["metallic"] = self.metallic
        rec["ior"] = self.ior
        rec["specular"] = self.tint
        if self.type == "conductor":
            if self.eta is None:
                flags |= layout.MATERIAL_FLAG_CONDUCTOR_F0
                rec["specular"] = self.f0
            else:
                rec["eta"] = self.eta
                rec["k"] = self.k if self.k is not None else (0.0, 0.0, 0.0)
        rec["flags"] = flags
        return rec


MATERIAL_TYPES = tuple(layout.MATERIAL_TYPES)


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
            recs[i] = m.record()
        return recs

    def material_defines(self) -> dict:
        """Preprocessor defines that compile only the material types this scene uses
        (MATERIALS_SELECTED + HAS_MATERIAL_<TYPE>; see cl/bsdf.h)."""
        defines = {"MATERIALS_SELECTED": True}
        for m in self.materials:
            if m.type != "diffuse":
                defines[f"HAS_MATERIAL_{m.type.upper()}"] = True
        return defines

    def sphere_records(self) -> np.ndarray:
        recs = np.zeros(len(self.spheres), layout.SPHERE)
        if len(self.spheres):
            recs["center"] = self.spheres[:, :3]
            recs["radius"] = self.spheres[:, 3]
        return recs
