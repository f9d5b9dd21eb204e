"""Participating media in the scene model, and their kernel records (cl/render/media.h).

A :class:`Medium` fills space with an extinction coefficient ``sigma_t`` [1 / scene unit] (RGB,
times ``scale``) and a single-scattering albedo, and scatters by a :class:`PhaseFunction`:

* **homogeneous** (no ``density``): the same everywhere (Mitsuba's ``homogeneous``, pbrt-v4's
  ``homogeneous``);
* **grid**: ``sigma_t * scale`` times the value of its ``density`` :class:`Grid` (one channel, or
  RGB), inside the grid's box only (vacuum outside it): Mitsuba's ``heterogeneous`` (``scale`` times
  its ``sigma_t`` volume), pbrt-v4's ``uniformgrid`` (``(sigma_a + sigma_s) * scale`` times its
  ``density``).  Its majorant is ``sigma_t * scale`` times the grid's largest value, per channel.

An ``albedo_grid`` replaces ``albedo`` by a grid's value (Mitsuba's albedo volume).  Shapes bound
media through :class:`MediumInterface` s (``Scene.interfaces``, indexed per face and per sphere):
crossing a surface that is a medium *transition* enters its ``exterior`` along the side its normal
faces (a triangle's ``(p1 - p0) x (p2 - p0)``, a sphere's outside) and its ``interior`` against it,
as Mitsuba does; a surface that is no transition keeps the ray's medium, as pbrt does for shapes
whose inside and outside media are the same.  A *null* (index-matched) surface does not scatter
(Mitsuba's ``null`` BSDF, pbrt's ``interface`` material).  ``Scene.camera_medium`` is the medium
the camera is in.  -1 (:data:`VACUUM`) is no medium.

:func:`pack_media` makes the kernel buffers (abi.MEDIA_PARAMS names them).
"""
from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np

from ..device import abi

VACUUM = abi.MEDIUM_VACUUM
PHASES = ("isotropic", "hg")
FILTERS = {"trilinear": abi.GRID_TRILINEAR, "nearest": abi.GRID_NEAREST}
OUTSIDE = {"clamp": abi.GRID_CLAMP, "zero": abi.GRID_ZERO}


@dataclass
class PhaseFunction:
    """``isotropic``, or ``hg``: Henyey-Greenstein with asymmetry ``g`` in (-1, 1) (g > 0 forward)."""

    type: str = "isotropic"
    g: float = 0.0


@dataclass(eq=False)
class Grid:
    """Values on a 3-D grid filling the unit cube of its local space, which ``to_world`` (4 x 4)
    places in the scene: ``data[z, y, x, c]`` (C = 1 or 3 channels) is the texel whose centre is
    ``((x + 0.5) / nx, (y + 0.5) / ny, (z + 0.5) / nz)`` (the order of Mitsuba's .vol files).
    ``filter``: "trilinear" or "nearest"; ``outside``: beyond the outer texel centres, "clamp" (the
    edge texels continue, Mitsuba) or "zero" (texels beyond the grid are 0, pbrt-v4).
    ``max_value``: the majorant's grid maximum when given (Mitsuba's ``max_value``), else the data's."""

    data: np.ndarray
    to_world: np.ndarray = field(default_factory=lambda: np.eye(4))
    filter: str = "trilinear"
    outside: str = "clamp"
    max_value: float | None = None
    source: str | None = None

    def __post_init__(self):
        d = np.asarray(self.data, np.float32)
        if d.ndim == 3:
            d = d[..., None]
        if d.ndim != 4 or d.shape[3] not in (1, 3) or 0 in d.shape:
            raise ValueError(f"a grid is (nz, ny, nx, 1 or 3) values, got shape {np.shape(self.data)}")
        self.data = np.ascontiguousarray(d)
        self.to_world = np.asarray(self.to_world, np.float64)

    @property
    def resolution(self) -> tuple:
        """(nx, ny, nz)"""
        nz, ny, nx, _ = self.data.shape
        return nx, ny, nz

    @property
    def channels(self) -> int:
        return self.data.shape[3]

    def maxima(self) -> np.ndarray:
        """The largest value per channel (3 numbers; a one-channel grid's in each), or max_value."""
        if self.max_value is not None:
            return np.full(3, float(self.max_value))
        m = self.data.reshape(-1, self.channels).max(axis=0).astype(np.float64)
        return np.broadcast_to(m, 3).copy() if len(m) == 1 else m

    def to_local(self) -> np.ndarray:
        """The 3 x 4 world -> local map."""
        return np.linalg.inv(self.to_world)[:3]

    def transformed(self, m) -> "Grid":
        """The grid moved by the 4 x 4 ``m`` (after its own transform)."""
        return dataclasses.replace(self, to_world=np.asarray(m, np.float64) @ self.to_world)

    def eval(self, points) -> np.ndarray:
        """The value (N x 3, float64) at world points, as cl/render/media.h's grid_eval computes it."""
        p = np.asarray(points, np.float64).reshape(-1, 3)
        q = p @ self.to_local()[:, :3].T + self.to_local()[:, 3]
        res = np.array(self.resolution, np.float64)
        data = self.data.astype(np.float64)
        if self.channels == 1:
            data = np.repeat(data, 3, axis=3)
        n = np.array(self.resolution)

        def fetch(i):  # i: (N, 3) integer positions
            inside = np.all((i >= 0) & (i < n), axis=1)
            c = np.clip(i, 0, n - 1)
            v = data[c[:, 2], c[:, 1], c[:, 0]]
            return v if self.outside == "clamp" else np.where(inside[:, None], v, 0.0)

        if self.filter == "nearest":
            return fetch(np.floor(q * res).astype(np.int64))
        pos = q * res - 0.5
        i0 = np.floor(pos).astype(np.int64)
        w1 = pos - i0
        w0 = 1.0 - w1
        out = 0.0
        for dz in (0, 1):
            for dy in (0, 1):
                for dx in (0, 1):
                    w = (w1[:, 0] if dx else w0[:, 0]) * (w1[:, 1] if dy else w0[:, 1]) * (w1[:, 2] if dz else w0[:, 2])
                    out = out + w[:, None] * fetch(i0 + np.array([dx, dy, dz]))
        return out

    def record(self, offset: int) -> np.ndarray:
        rec = np.zeros((), abi.MEDIUM_GRID)
        rec["offset"] = offset
        rec["nx"], rec["ny"], rec["nz"] = self.resolution
        rec["channels"] = self.channels
        rec["filter"] = FILTERS[self.filter]
        rec["outside"] = OUTSIDE[self.outside]
        rec["max_value"] = float(self.maxima().max())
        rec["to_local"] = self.to_local().reshape(-1)
        return rec


@dataclass(eq=False)
class Medium:
    """A participating medium (the module docstring): extinction ``sigma_t * scale``, ``albedo``,
    ``phase``; a grid medium when ``density`` is set.  ``sample_emitters``: next-event estimation
    at its scattering events (Mitsuba's flag).  ``majorant``: per channel, when given; else
    :meth:`majorant_rgb` computes it."""

    name: str = "medium"
    sigma_t: tuple = (1.0, 1.0, 1.0)
    albedo: tuple = (0.75, 0.75, 0.75)
    scale: float = 1.0
    phase: PhaseFunction = field(default_factory=PhaseFunction)
    density: Grid | None = None
    albedo_grid: Grid | None = None
    sample_emitters: bool = True
    majorant: tuple | None = None

    @property
    def type(self) -> str:
        return "homogeneous" if self.density is None else "grid"

    def extinction(self) -> np.ndarray:
        """sigma_t * scale (3 numbers)"""
        return np.asarray(self.sigma_t, np.float64) * float(self.scale)

    def majorant_rgb(self) -> np.ndarray:
        """At least sigma_t(x) everywhere, per channel: the extinction itself (homogeneous), or
        times the density grid's largest value per channel."""
        if self.majorant is not None:
            return np.asarray(self.majorant, np.float64)
        e = self.extinction()
        return e if self.density is None else e * self.density.maxima()

    def chromatic(self) -> bool:
        """Whether sigma_t (or its majorant) differs between the channels: the distances a path samples
        with one channel's coefficients then need the spectral-MIS weights (cl/render/media.h)."""
        e, m = self.extinction(), self.majorant_rgb()
        rgb_grid = self.density is not None and self.density.channels == 3
        return bool(rgb_grid or np.ptp(e) > 0 or np.ptp(m) > 0)

    def grids(self) -> list:
        return [g for g in (self.density, self.albedo_grid) if g is not None]

    def transformed(self, m) -> "Medium":
        """The medium with its grids moved by the 4 x 4 ``m`` (a homogeneous one is itself)."""
        if not self.grids():
            return self
        return dataclasses.replace(self, density=None if self.density is None else self.density.transformed(m),
                                   albedo_grid=None if self.albedo_grid is None else self.albedo_grid.transformed(m))

    def record(self, grid_index: dict) -> np.ndarray:
        """The MEDIUM struct; ``grid_index`` maps id(grid) to its index in the grid table."""
        rec = np.zeros((), abi.MEDIUM)
        rec["type"] = abi.MEDIUM_TYPE_HOMOGENEOUS if self.density is None else abi.MEDIUM_TYPE_GRID
        rec["sigma_t"] = self.extinction()
        rec["albedo"] = self.albedo
        rec["majorant"] = self.majorant_rgb()
        rec["phase"] = abi.PHASE_HG if self.phase.type == "hg" else abi.PHASE_ISOTROPIC
        rec["g"] = self.phase.g if self.phase.type == "hg" else 0.0
        rec["density_grid"] = -1 if self.density is None else grid_index[id(self.density)]
        rec["albedo_grid"] = -1 if self.albedo_grid is None else grid_index[id(self.albedo_grid)]
        rec["flags"] = abi.MEDIUM_FLAG_SAMPLE_EMITTERS if self.sample_emitters else 0
        return rec


@dataclass(frozen=True)
class MediumInterface:
    """How a surface bounds media: ``interior`` and ``exterior`` are indices into ``Scene.media``
    (:data:`VACUUM`: none); ``transition``: crossing it changes the medium (else the ray keeps its
    own); ``null``: index-matched, no surface scattering."""

    interior: int = VACUUM
    exterior: int = VACUUM
    transition: bool = True
    null: bool = False

    def flipped(self) -> "MediumInterface":
        """The same boundary seen from a surface whose normal points the other way."""
        return dataclasses.replace(self, interior=self.exterior, exterior=self.interior)

    def record(self) -> np.ndarray:
        rec = np.zeros((), abi.MEDIUM_INTERFACE)
        rec["interior"], rec["exterior"] = self.interior, self.exterior
        rec["flags"] = (abi.MEDIUM_IF_TRANSITION if self.transition else 0) | (abi.MEDIUM_IF_NULL if self.null else 0)
        return rec


def pack_grids(media) -> tuple[np.ndarray, np.ndarray, dict]:
    """(MEDIUM_GRID table, float32 grid_data, {id(grid): index}) of the media's grids."""
    grids, index = [], {}
    for m in media:
        for g in m.grids():
            if id(g) not in index:
                index[id(g)] = len(grids)
                grids.append(g)
    table = np.zeros(max(1, len(grids)), abi.MEDIUM_GRID)
    chunks, offset = [], 0
    for i, g in enumerate(grids):
        table[i] = g.record(offset)
        chunks.append(g.data.reshape(-1))
        offset += g.data.size
    if offset >= 2**31:
        raise ValueError("medium grids too large (more than 2^31 values in all)")
    data = np.concatenate(chunks).astype(np.float32) if chunks else np.zeros(1, np.float32)
    return table, data, index


def uses_spectral_mis(scene) -> bool:
    """Whether the media's channels are combined by spectral MIS: a chromatic medium, and
    RenderSettings.spectral_mis (the kernels' SPECTRAL_MIS, or spectral_mis at run time)."""
    return bool(getattr(scene.settings, "spectral_mis", True) and any(m.chromatic() for m in scene.media))


def pack_media(scene) -> dict:
    """The kernel buffers of the scene's media, by their abi.MEDIA_PARAMS names (not the per-path
    state): media, medium_grids, grid_data, medium_interfaces (one record at least each),
    tri_interface (per face, in the scene's face order: the renderer reorders it as tri_material),
    shape_interface, camera_medium and spectral_mis."""
    table, data, index = pack_grids(scene.media)
    media = np.zeros(max(1, len(scene.media)), abi.MEDIUM)
    for i, m in enumerate(scene.media):
        media[i] = m.record(index)
    interfaces = np.zeros(max(1, len(scene.interfaces)), abi.MEDIUM_INTERFACE)
    for i, mi in enumerate(scene.interfaces):
        interfaces[i] = mi.record()
    return {"media": media, "medium_grids": table, "grid_data": data, "medium_interfaces": interfaces,
            "tri_interface": scene.face_interface_array(), "shape_interface": scene.shape_interface_array(),
            "camera_medium": int(scene.camera_medium), "spectral_mis": int(uses_spectral_mis(scene))}
