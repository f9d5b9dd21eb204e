"""Participating media in TOML scene files (docs/SCENE_FORMAT.md, "Participating media"): the
``[media.NAME]`` tables, a shape's ``interior`` / ``exterior`` / ``index_matched`` keys and
``[camera] medium``, read into pyopencl_rt/scene/media.py's model."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import UserError
from ..media import Grid, Medium, MediumInterface, PhaseFunction
from .values import (check_boolean, check_choice, check_keys, check_number, check_vector, describe, first_use_index,
                     one_line)

MEDIUM_KEYS = {"type", "sigma_t", "albedo", "scale", "phase", "g", "sample_emitters", "file", "density", "bounds",
               "matrix", "filter", "outside", "albedo_file"}
GRID_KEYS = {"file", "density", "bounds", "matrix", "filter", "outside", "albedo_file"}
SHAPE_KEYS = {"interior", "exterior", "index_matched"}


def read_media(ctx, scene_path: Path, table) -> tuple[list, dict]:
    """([Medium], {name: index}) of the ``[media]`` table."""
    if not isinstance(table, dict):
        raise ctx.error("media", f"must be tables written [media.NAME], got {describe(table)}")
    media, index = [], {}
    for name, spec in table.items():
        index[name] = len(media)
        media.append(_medium(ctx, scene_path, f"[media.{name}]", name, spec))
    return media, index


def _rgb(ctx, where, key, value, upper=None):
    v = check_vector(ctx, where, key, value, allow_scalar=True)
    if (v < 0).any() or (upper is not None and (v > upper).any()):
        bound = f"in [0, {upper:g}]" if upper is not None else ">= 0"
        raise ctx.error(where, f"'{key}' must be {bound}, got {v.tolist()}")
    return tuple(float(x) for x in v)


def _medium(ctx, scene_path, where, name, spec) -> Medium:
    if not isinstance(spec, dict):
        raise ctx.error(where, f"must be a table, got {describe(spec)}")
    check_keys(ctx, where, spec, MEDIUM_KEYS)
    mtype = check_choice(ctx, where, "type", spec.get("type", "homogeneous"), ("homogeneous", "grid"))
    if mtype == "homogeneous":
        extra = sorted(set(spec) & GRID_KEYS)
        if extra:
            raise ctx.error(where, f"'{extra[0]}' is for type = \"grid\" media")
    med = Medium(name=name, sigma_t=_rgb(ctx, where, "sigma_t", spec.get("sigma_t", 1.0)),
                 albedo=_rgb(ctx, where, "albedo", spec.get("albedo", 0.75), upper=1.0),
                 scale=check_number(ctx, where, "scale", spec.get("scale", 1.0), minimum=0.0),
                 sample_emitters=check_boolean(ctx, where, "sample_emitters", spec.get("sample_emitters", True)))
    phase = check_choice(ctx, where, "phase", spec.get("phase", "isotropic"), ("isotropic", "hg"))
    if "g" in spec and phase != "hg":
        raise ctx.error(where, "'g' is the asymmetry of phase = \"hg\"")
    g = check_number(ctx, where, "g", spec.get("g", 0.0))
    if not -1 < g < 1:
        raise ctx.error(where, f"'g' must lie in (-1, 1), got {g:g}")
    med.phase = PhaseFunction(phase, float(g) if phase == "hg" else 0.0)
    if mtype == "grid":
        to_world = _grid_box(ctx, where, spec)
        filt = check_choice(ctx, where, "filter", spec.get("filter", "trilinear"), ("trilinear", "nearest"))
        outside = check_choice(ctx, where, "outside", spec.get("outside", "clamp"), ("clamp", "zero"))
        if ("file" in spec) == ("density" in spec):
            raise ctx.error(where, "a grid medium needs 'file' (a Mitsuba .vol grid) or 'density' (nested lists "
                                   "[z][y][x]), one of them")
        data = _vol(ctx, scene_path, where, "file", spec["file"]) if "file" in spec else _density(ctx, where, spec)
        med.density = Grid(data, to_world=to_world, filter=filt, outside=outside, source=spec.get("file"))
        if "albedo_file" in spec:
            albedo = _vol(ctx, scene_path, where, "albedo_file", spec["albedo_file"])
            if albedo.max(initial=0.0) > 1:
                raise ctx.error(where, f"'albedo_file' values must lie in [0, 1], got up to {albedo.max():g}")
            med.albedo_grid = Grid(albedo, to_world=to_world, filter=filt, outside=outside, source=spec["albedo_file"])
    return med


def _grid_box(ctx, where, spec) -> np.ndarray:
    """The 4 x 4 map of the grid's unit cube to the scene: 'bounds' [[x0, y0, z0], [x1, y1, z1]] or
    'matrix' (rows, applied to column vectors); default the unit cube itself."""
    if "bounds" in spec and "matrix" in spec:
        raise ctx.error(where, "give 'bounds' or 'matrix', not both")
    m = np.eye(4)
    if "bounds" in spec:
        b = spec["bounds"]
        if not isinstance(b, list) or len(b) != 2:
            raise ctx.error(where, f"'bounds' must be two corners [[x0, y0, z0], [x1, y1, z1]], got {describe(b)}")
        lo, hi = (check_vector(ctx, where, "bounds", c) for c in b)
        if not (hi > lo).all():
            raise ctx.error(where, f"'bounds' must have its second corner above the first, got {lo.tolist()}, "
                                   f"{hi.tolist()}")
        m[:3, :3], m[:3, 3] = np.diag(hi - lo), lo
    elif "matrix" in spec:
        rows = spec["matrix"]
        if not isinstance(rows, list) or len(rows) != 4:
            raise ctx.error(where, f"'matrix' must be 4 rows of 4 numbers, got {describe(rows)}")
        m = np.stack([check_vector(ctx, where, f"matrix[{i}]", r, 4) for i, r in enumerate(rows)])
        if not np.allclose(m[3], [0, 0, 0, 1]) or abs(np.linalg.det(m[:3, :3])) < 1e-12:
            raise ctx.error(where, "'matrix' must be affine (last row [0, 0, 0, 1]) and invertible")
    return m


def _vol(ctx, scene_path: Path, where, key, fname) -> np.ndarray:
    from .mitsuba_vol import read_vol

    if not isinstance(fname, str) or not fname:
        raise ctx.error(where, f"'{key}' must be a file name, got {describe(fname)}")
    path = scene_path.parent / fname
    if not path.is_file():
        raise ctx.error(where, f"grid file '{fname}' not found (looked for {path})")
    try:
        data, _box = read_vol(path, fname)
    except UserError as exc:
        raise ctx.error(where, one_line(str(exc))) from None
    if data.shape[3] not in (1, 3):
        raise ctx.error(where, f"'{fname}' has {data.shape[3]} channels (1 or 3 are supported)")
    if not np.isfinite(data).all() or (data < 0).any():
        raise ctx.error(where, f"'{fname}' has negative or non-finite values")
    return data


def _density(ctx, where, spec) -> np.ndarray:
    try:
        data = np.asarray(spec["density"], np.float64)
    except (TypeError, ValueError):
        data = None
    if data is None or data.ndim != 3 or 0 in data.shape:
        raise ctx.error(where, "'density' must be nested lists of numbers [z][y][x], all rows the same length")
    if not np.isfinite(data).all() or (data < 0).any():
        raise ctx.error(where, "'density' values must be finite and >= 0")
    return data.astype(np.float32)


def shape_interface(ctx, where, table, media_index: dict) -> MediumInterface | None:
    """The medium interface of a [[shape]]: 'interior' and 'exterior' media (a transition when either
    is given; the exterior is on the side the faces' normals point to) and 'index_matched'."""
    sides = {}
    for side in ("interior", "exterior"):
        if side in table:
            name = table[side]
            if not isinstance(name, str) or name not in media_index:
                known = ", ".join(sorted(media_index)) or "none defined"
                raise ctx.error(where, f"'{side}' must name a medium (media: {known}), got {describe(name)}")
            sides[side] = media_index[name]
    null = check_boolean(ctx, where, "index_matched", table.get("index_matched", False))
    if null and "material" in table:
        raise ctx.error(where, "an index_matched shape has no material (it only bounds media)")
    if not sides and not null:
        return None
    return MediumInterface(sides.get("interior", -1), sides.get("exterior", -1), transition=bool(sides), null=null)


class Interfaces:
    """The distinct medium interfaces of the shapes, in order of first use (``list``)."""

    def __init__(self, ctx, media_index: dict):
        self.ctx, self.media_index = ctx, media_index
        self.list: list = []
        self._index: dict = {}

    def index(self, where, table) -> int:
        """The index of the shape's medium interface (-1: none)."""
        interface = shape_interface(self.ctx, where, table, self.media_index)
        return -1 if interface is None else first_use_index(self.list, self._index, interface)


def camera_medium(ctx, table, media_index: dict) -> int:
    """[camera] medium: the medium the camera is in (-1: none)."""
    if "medium" not in table:
        return -1
    name = table["medium"]
    if not isinstance(name, str) or name not in media_index:
        known = ", ".join(sorted(media_index)) or "none defined"
        raise ctx.error("[camera]", f"'medium' must name a medium (media: {known}), got {describe(name)}")
    return media_index[name]
