"""Mitsuba 3 media, phase functions and volumes as our media (pyopencl_rt/scene/media.py;
docs/SCENE_FORMAT.md, "Mitsuba 3 XML"):

| Mitsuba | ours |
|---|---|
| ``homogeneous`` (``sigma_t``, ``albedo``, ``scale``, ``sample_emitters``) | a homogeneous medium |
| ``heterogeneous`` (``sigma_t`` and ``albedo`` volumes, ``scale``) | a grid medium: ``sigma_t``'s volume is its density (its box the medium's extent), ``albedo``'s its albedo grid |
| ``gridvolume`` (``filename``: a .vol file, ``to_world``, ``filter_type``, ``use_grid_bbox``, ``max_value``) | a grid, clamped at its edges |
| ``constvolume`` (``value``, ``to_world``) | its value: a constant, or a 1 x 1 x 1 grid (``heterogeneous``'s sigma_t: the unit cube) |
| ``isotropic``, ``hg`` (``g``, default 0.8) | the phase functions of the same names |

Colours go through Mitsuba's RGB conversion (mitsuba_bsdf.color_value: a ``<spectrum>`` as a
reflectance, clamped to [0, 1] with a warning as Mitsuba clamps it).  Other phase functions
(``rayleigh``, ``sggx``, ``tabphase``, ``blendphase``) are isotropic with a warning.
"""
from __future__ import annotations

import numpy as np

from ..media import Grid, Medium, PhaseFunction
from .builder import error_at, scale, translate
from .mitsuba_bsdf import color_value
from .mitsuba_plugins import refusal
from .mitsuba_xml import MiObject



class MediaMapper:
    """The media of one Mitsuba import, each made once (by identity of its object)."""

    def __init__(self, importer):
        self.imp = importer
        self._media: dict[int, Medium] = {}

    def medium(self, obj: MiObject) -> Medium:
        if id(obj) not in self._media:
            self._media[id(obj)] = self._make(obj)
        return self._media[id(obj)]

    def _make(self, obj: MiObject) -> Medium:
        imp = self.imp
        name = obj.id or f"medium@{obj.node.pos}"
        med = Medium(name=name)
        if obj.type not in ("homogeneous", "heterogeneous"):
            raise error_at(obj.node.pos, refusal(obj))
        med.scale = obj.float("scale", 1.0, minimum=0.0)
        med.sample_emitters = bool(obj.boolean("sample_emitters", True))
        phases = obj.children_of("phase")
        med.phase = self.phase(phases[0]) if phases else PhaseFunction("isotropic")
        for extra in phases[1:]:
            imp.warn(extra.node.pos, f"{extra.label()} in {obj.label()}: a second phase function; ignored")
        for extra in obj.children:
            if extra.tag != "phase":
                raise error_at(extra.node.pos, f"{extra.label()} in {obj.label()}: not supported")
        sigma_t = self.volume_value(obj, "sigma_t", 1.0)
        albedo = self.volume_value(obj, "albedo", 0.75)
        if obj.type == "homogeneous":
            if isinstance(sigma_t, Grid):
                mean = tuple(float(x) for x in sigma_t.data.reshape(-1, sigma_t.channels).mean(0).repeat(
                    3 // sigma_t.channels))
                imp.warn(obj.props["sigma_t"].node.pos, f"{obj.label()}: a homogeneous medium needs a constant sigma_t; "
                                                        f"using the grid's mean {tuple(round(x, 4) for x in mean)}")
                sigma_t = mean
            med.sigma_t = sigma_t
        else:
            if not isinstance(sigma_t, Grid):  # a constant: Mitsuba's constvolume, on the unit cube
                sigma_t = Grid(np.asarray(sigma_t, np.float32).reshape(1, 1, 1, 3))
            med.sigma_t, med.density = (1.0, 1.0, 1.0), sigma_t
        if isinstance(albedo, Grid):
            med.albedo_grid = albedo
        else:
            med.albedo = albedo
        imp.unused(obj)
        return med

    def phase(self, obj: MiObject) -> PhaseFunction:
        if obj.type == "hg":
            g = obj.float("g", 0.8)
            if not -1 < g < 1:
                raise error_at(obj.props["g"].node.pos, f"{obj.label()}: g must lie in (-1, 1), got {g:g}")
            self.imp.unused(obj)
            return PhaseFunction("hg", g)
        self.imp.unused(obj)  # refuses other phase functions
        return PhaseFunction("isotropic")

    def volume_value(self, obj: MiObject, name: str, default: float):
        """The property ``name`` of a medium: an RGB tuple (a float, rgb, spectrum or constvolume) or a
        Grid (a gridvolume, or a constvolume with a transform: Mitsuba's unit cube)."""
        p = obj.props.get(name)
        if p is None or p.kind != "object" or p.value.tag != "volume":
            rgb, _ = color_value(self.imp, obj, name, (default,) * 3)
            return rgb
        obj.used.add(name)
        vol = p.value
        if vol.type == "gridvolume":
            return self.gridvolume(vol)
        if vol.type == "constvolume":
            rgb, _ = color_value(self.imp, vol, "value", (1.0,) * 3)
            m = vol.transform("to_world")
            self.imp.unused(vol)
            if m is None:
                return rgb
            return Grid(np.asarray(rgb, np.float32).reshape(1, 1, 1, 3), to_world=m)
        raise error_at(vol.node.pos, refusal(vol))

    def gridvolume(self, vol: MiObject) -> Grid:
        from .mitsuba_vol import read_vol

        imp = self.imp
        fname = vol.string("filename")
        if fname is None:
            raise error_at(vol.node.pos, f'{vol.label()} needs <string name="filename">')
        data, box = read_vol(imp.resolve(fname, vol), f"{vol.node.pos}: {vol.label()}")
        if data.shape[3] == 6:
            raise error_at(vol.node.pos, f"{vol.label()}: '{fname}' has 6 channels (an SGGX grid): not supported")
        filt = vol.choice("filter_type", ("trilinear", "nearest"))
        wrap = vol.choice("wrap_mode", ("clamp", "repeat", "mirror"))
        if wrap != "clamp":
            imp.warn(vol.props["wrap_mode"].node.pos, f'{vol.label()}: wrap_mode "{wrap}" is read as "clamp" (they '
                                                       "differ only in the outer half texel)")
        m = vol.transform("to_world")
        m = np.eye(4) if m is None else m
        if abs(np.linalg.det(m[:3, :3])) < 1e-300:
            raise error_at(vol.props["to_world"].node.pos, f"{vol.label()}: to_world is singular")
        if vol.boolean("use_grid_bbox", False):
            lo, hi = box
            if not (hi > lo).all():
                raise error_at(vol.node.pos, f"{vol.label()}: use_grid_bbox with the empty box {box.tolist()} of '{fname}'")
            m = m @ translate(lo) @ scale(hi - lo)
        max_value = vol.float("max_value", None)
        imp.unused(vol)
        return Grid(data, to_world=m, filter=filt, outside="clamp", max_value=max_value, source=str(fname))
