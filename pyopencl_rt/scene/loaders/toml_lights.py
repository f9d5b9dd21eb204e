"""Lights in TOML scene files (docs/SCENE_FORMAT.md, ``[[light]]``): point, directional, spot and
projector lights, read into pyopencl_rt/scene/model.py's light classes."""
from __future__ import annotations

import numpy as np

from ..model import DirectionalLight, PointLight, ProjectorLight, SpotLight, look_at_frame
from .values import TableReader, check_choice, check_color, check_keys, check_vector, describe

LIGHT_TYPES = ("point", "directional", "spot", "projector")
_AIM_KEYS = {"position", "look_at", "up"}
_LIGHT_KEYS = {"point": {"type", "position", "intensity"}, "directional": {"type", "direction", "irradiance"},
               "spot": {"type", "intensity", "cutoff_angle", "beam_width", "falloff", "texture"} | _AIM_KEYS,
               "projector": {"type", "irradiance", "scale", "fov", "texture"} | _AIM_KEYS}


def read_lights(ctx, lights) -> list:
    """The Light objects of the [[light]] tables."""
    if not isinstance(lights, list):
        raise ctx.error("light", "must be an array of tables written [[light]]")
    out = []
    for number, table in enumerate(lights, 1):
        where = f"[[light]] #{number}"
        if not isinstance(table, dict):
            raise ctx.error(where, f"must be a table, got {describe(table)}")
        ltype = table.get("type")
        if not isinstance(ltype, str) or ltype not in LIGHT_TYPES:
            shown = "missing 'type'" if ltype is None else f"unknown type {ltype!r}"
            raise ctx.error(where, f"{shown} (expected one of: {', '.join(LIGHT_TYPES)})")
        where = f"[[light]] #{number} ({ltype})"
        check_keys(ctx, where, table, _LIGHT_KEYS[ltype])
        if ltype in ("spot", "projector"):
            out.append(_read_aimed_light(ctx, where, ltype, TableReader(ctx, where, table)))
        elif ltype == "point":
            if "position" not in table:
                raise ctx.error(where, "missing 'position'")
            out.append(PointLight(position=tuple(float(x) for x in check_vector(ctx, where, "position", table["position"])),
                                  intensity=check_color(ctx, where, "intensity", table.get("intensity", 1.0))))
        else:
            if "direction" not in table:
                raise ctx.error(where, "missing 'direction' (the way the light travels)")
            d = check_vector(ctx, where, "direction", table["direction"])
            if not np.linalg.norm(d) > 0:
                raise ctx.error(where, "'direction' must not be zero")
            out.append(DirectionalLight(direction=tuple(float(x) for x in d / np.linalg.norm(d)),
                                        irradiance=check_color(ctx, where, "irradiance", table.get("irradiance", 1.0))))
    return out


def _read_aimed_light(ctx, where, ltype, t: TableReader):
    """A spot or projector light: at `position`, aimed at `look_at` (its local +z), `up` its local +y."""
    for key in ("position", "look_at"):
        if key not in t:
            raise t.error(f"missing '{key}'")
    position, target = t.vector("position"), t.vector("look_at")
    up = t.vector("up") if "up" in t else np.array([0.0, 1.0, 0.0])
    try:
        frame = look_at_frame(position, target, up)
    except ValueError as exc:
        raise t.error(str(exc)) from None
    texture = t.texture("texture", srgb=True)
    position = tuple(float(x) for x in position)
    if ltype == "spot":
        cutoff = t.number("cutoff_angle", 20.0, positive=True, maximum=180.0)
        beam = t.number("beam_width", 0.75 * cutoff, minimum=0.0, maximum=cutoff)
        falloff = check_choice(ctx, where, "falloff", t.table.get("falloff", "mitsuba"), ("mitsuba", "smoothstep"))
        return SpotLight(position=position, intensity=check_color(ctx, where, "intensity", t.table.get("intensity", 1.0)),
                         cutoff_angle=cutoff, beam_width=beam, falloff=falloff, texture=texture, to_world=frame)
    fov = t.number("fov", 45.0, positive=True, maximum=179.999)
    return ProjectorLight(position=position, irradiance=check_color(ctx, where, "irradiance", t.table.get("irradiance", 1.0)),
                          texture=texture, scale=t.number("scale", 1.0, minimum=0.0), fov=fov, to_world=frame)
