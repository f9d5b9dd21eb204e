"""Typed values of scene files, checked: every problem becomes one :class:`SceneError` line
``<file>: <where>: <what>`` (``where`` names the table, e.g. ``[[shape]] #2 (quad)``)."""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

from ...errors import UserError
from ..lights.frames import look_at_frame


class SceneError(UserError):
    """A scene file that cannot be loaded; the message is one line naming the file."""


def one_line(text: str) -> str:
    return " ".join(str(text).split())


class ErrorContext:
    """The scene file being read, for messages: every error is '<file>: <where>: <what>'."""

    def __init__(self, name: str):
        self.name = name

    def error(self, where: str, what: str) -> SceneError:
        prefix = f"{self.name}: {where}: " if where else f"{self.name}: "
        return SceneError(one_line(prefix + what))


def first_use_index(items: list, index: dict, value, key=None) -> int:
    """The index of ``value`` in ``items``, appended on its first use (``index`` maps ``key``, by
    default the value itself, to the index)."""
    key = value if key is None else key
    if key not in index:
        index[key] = len(items)
        items.append(value)
    return index[key]


def is_number(x) -> bool:
    return isinstance(x, (int, float)) and not isinstance(x, bool)


def describe(x) -> str:
    """What a wrong value is, for messages: 'boolean true', "string 'x'", 'a list of 2', ..."""
    if isinstance(x, bool):
        return f"boolean {str(x).lower()}"
    if isinstance(x, str):
        return f"string {x!r}"
    if isinstance(x, list):
        return f"a list of {len(x)}"
    if isinstance(x, dict):
        return "a table"
    return f"{type(x).__name__} {x!r}"


def check_keys(ctx: ErrorContext, where: str, table, allowed: set):
    if not isinstance(table, dict):
        raise ctx.error(where, f"must be a table, got {describe(table)}")
    for key in table:
        if key not in allowed:
            raise ctx.error(where, f"unknown key '{key}' (expected one of: {', '.join(sorted(allowed))})")


def check_choice(ctx: ErrorContext, where: str, what: str, value, options) -> str:
    """``value`` if it is one of the names ``options``; else 'unknown <what> ...'."""
    if not isinstance(value, str) or value not in options:
        shown = repr(value) if isinstance(value, str) else describe(value)
        raise ctx.error(where, f"unknown {what} {shown} (expected one of: {', '.join(options)})")
    return value


def _check_range(ctx, where, key, value, minimum, maximum, show):
    if minimum is not None and value < minimum:
        raise ctx.error(where, f"'{key}' must be >= {show(minimum)}, got {show(value)}")
    if maximum is not None and value > maximum:
        raise ctx.error(where, f"'{key}' must be <= {show(maximum)}, got {show(value)}")
    return value


def check_number(ctx, where, key, value, *, minimum=None, positive=False, maximum=None) -> float:
    if not is_number(value) or not math.isfinite(value):
        raise ctx.error(where, f"'{key}' must be a number, got {describe(value)}")
    value = float(value)
    if positive and not value > 0:
        raise ctx.error(where, f"'{key}' must be > 0, got {value:g}")
    return _check_range(ctx, where, key, value, minimum, maximum, lambda x: format(x, "g"))


def check_integer(ctx, where, key, value, *, minimum=None, maximum=None) -> int:
    if not isinstance(value, int) or isinstance(value, bool):
        raise ctx.error(where, f"'{key}' must be an integer, got {describe(value)}")
    return _check_range(ctx, where, key, value, minimum, maximum, str)


def check_boolean(ctx, where, key, value) -> bool:
    if not isinstance(value, bool):
        raise ctx.error(where, f"'{key}' must be true or false, got {describe(value)}")
    return value


def check_vector(ctx, where, key, value, n=3, *, allow_scalar=False) -> np.ndarray:
    if allow_scalar and is_number(value):
        value = [value] * n
    if not isinstance(value, list) or len(value) != n or not all(is_number(x) for x in value):
        shape = f"{n} numbers" + (" or one number" if allow_scalar else "")
        raise ctx.error(where, f"'{key}' must be a list of {shape}, got {describe(value)}")
    arr = np.asarray(value, np.float64)
    if not np.isfinite(arr).all():
        raise ctx.error(where, f"'{key}' must be finite, got {value}")
    return arr


def check_points(ctx, where, key, value, n) -> np.ndarray:
    if not isinstance(value, list) or len(value) != n:
        raise ctx.error(where, f"'{key}' must be a list of {n} points [x, y, z], got {describe(value)}")
    return np.stack([check_vector(ctx, where, f"{key}[{i}]", p) for i, p in enumerate(value)])


def check_color(ctx, where, key, value) -> tuple:
    """Linear RGB >= 0 (radiance, intensity, irradiance), from 3 numbers or one."""
    c = check_vector(ctx, where, key, value, allow_scalar=True)
    if (c < 0).any():
        raise ctx.error(where, f"'{key}' must be >= 0, got {c.tolist()}")
    return tuple(float(x) for x in c)


def check_rgb01(ctx, where, key, value) -> tuple:
    """Linear RGB in [0, 1] (a reflectance), from 3 numbers or one."""
    v = check_vector(ctx, where, key, value, allow_scalar=True)
    if v.min() < 0 or v.max() > 1:
        raise ctx.error(where, f"'{key}' components must lie in [0, 1], got {v.tolist()}")
    return tuple(float(x) for x in v)


TEXTURE_TABLE_KEYS = ("file", "wrap", "filter", "scale", "offset", "rotation")


def read_texture(ctx, where, key, fname, *, srgb):
    """The image file ``fname`` (relative to the scene file) of the key ``key``, as a Texture; or
    a table {file, wrap, filter, scale, offset, rotation}: the file and how it is looked up (wrap
    "repeat", "mirror" or "clamp"; filter "bilinear" or "nearest"; the lookup's coordinates
    offset + R(rotation) (scale * uv), rotation in degrees, counter-clockwise in uv)."""
    if isinstance(fname, dict):
        from ..textures import FILTERS, WRAPS

        unknown = sorted(set(fname) - set(TEXTURE_TABLE_KEYS))
        if unknown:
            raise ctx.error(where, f"'{key}': unknown keys {', '.join(unknown)} (a texture table has "
                                   f"{', '.join(TEXTURE_TABLE_KEYS)})")
        if "file" not in fname:
            raise ctx.error(where, f"'{key}' needs 'file', the image path")
        tex = read_texture(ctx, where, f"{key}.file", fname["file"], srgb=srgb)
        wrap = check_choice(ctx, where, f"{key}.wrap", fname.get("wrap", "repeat"), WRAPS)
        filt = check_choice(ctx, where, f"{key}.filter", fname.get("filter", "bilinear"), FILTERS)
        su, sv = check_vector(ctx, where, f"{key}.scale", fname.get("scale", [1.0, 1.0]), 2, allow_scalar=True)
        ou, ov = check_vector(ctx, where, f"{key}.offset", fname.get("offset", [0.0, 0.0]), 2)
        r = np.radians(check_number(ctx, where, f"{key}.rotation", fname.get("rotation", 0.0)))
        c, s_ = float(np.cos(r)), float(np.sin(r))
        return tex.with_lookup(wrap=wrap, filter=filt, to_uv=(c * su, -s_ * sv, ou, s_ * su, c * sv, ov))
    if not isinstance(fname, str) or not fname:
        raise ctx.error(where, f"'{key}' must be an image file path or a texture table, got {describe(fname)}")
    path = Path(ctx.name).parent / Path(fname).expanduser()
    if not path.is_file():
        raise ctx.error(where, f"{key} '{fname}' not found (looked for {path})")
    from ..textures import texture_from_image

    try:
        return texture_from_image(path, srgb=srgb)
    except Exception as exc:
        raise ctx.error(where, f"cannot read {key} '{fname}' ({type(exc).__name__}: {exc})") from None


class TableReader:
    """One table of a scene file, read key by key with the checks above; what a material type's
    ``read_toml`` gets (pyopencl_rt.scene.materials).  ``default`` is used when the key is absent."""

    def __init__(self, ctx: ErrorContext, where: str, table: dict):
        self.ctx, self.where, self.table = ctx, where, table

    def __contains__(self, key) -> bool:
        return key in self.table

    def error(self, what: str) -> SceneError:
        return self.ctx.error(self.where, what)

    def number(self, key, default, **limits) -> float:
        """See :func:`check_number` for ``minimum``, ``maximum`` and ``positive``."""
        return check_number(self.ctx, self.where, key, self.table.get(key, default), **limits)

    def vector(self, key, n=3, *, allow_scalar=False) -> np.ndarray:
        return check_vector(self.ctx, self.where, key, self.table[key], n, allow_scalar=allow_scalar)

    def boolean(self, key, default) -> bool:
        return check_boolean(self.ctx, self.where, key, self.table.get(key, default))

    def rgb01(self, key, default) -> tuple:
        return check_rgb01(self.ctx, self.where, key, self.table.get(key, default))

    def choice(self, key, what, options) -> str:
        return check_choice(self.ctx, self.where, what, self.table[key], options)

    def texture(self, key, *, srgb):
        """The Texture the key names, or None without the key."""
        if key not in self.table:
            return None
        return read_texture(self.ctx, self.where, key, self.table[key], srgb=srgb)

    def color(self, key, default) -> tuple:
        """An RGB colour (a number or three), finite and non-negative."""
        return check_color(self.ctx, self.where, key, self.table.get(key, default))

    def aimed(self) -> tuple:
        """(position, 3x3 local-to-world frame, texture) of a light at ``position`` aimed at ``look_at``
        (its local +z), its local +y nearest ``up`` (default +y); ``texture``: an sRGB image or None."""
        for key in ("position", "look_at"):
            if key not in self:
                raise self.error(f"missing '{key}'")
        position, target = self.vector("position"), self.vector("look_at")
        up = self.vector("up") if "up" in self else np.array([0.0, 1.0, 0.0])
        try:
            frame = look_at_frame(position, target, up)
        except ValueError as exc:
            raise self.error(str(exc)) from None
        return tuple(float(x) for x in position), frame, self.texture("texture", srgb=True)


class SceneFormatError(SceneError):
    """Malformed Mitsuba XML or pbrt input: one line, ``<file>:<line>: <what>``."""


def error_at(position: str, what: str) -> SceneFormatError:
    return SceneFormatError(one_line(f"{position}: {what}"))
