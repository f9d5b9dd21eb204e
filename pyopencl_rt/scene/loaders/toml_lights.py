"""Lights in TOML scene files (docs/SCENE_FORMAT.md, ``[[light]]``): each table read by its registered
type's ``read_toml`` (pyopencl_rt/scene/lights/)."""
from __future__ import annotations

from ..lights import REGISTRY
from .values import TableReader, check_keys, describe

LIGHT_TYPES = tuple(REGISTRY)


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
        if not isinstance(ltype, str) or ltype not in REGISTRY:
            shown = "missing 'type'" if ltype is None else f"unknown type {ltype!r}"
            raise ctx.error(where, f"{shown} (expected one of: {', '.join(LIGHT_TYPES)})")
        where = f"[[light]] #{number} ({ltype})"
        check_keys(ctx, where, table, REGISTRY[ltype].toml_keys | {"type"})
        out.append(REGISTRY[ltype].read_toml(TableReader(ctx, where, table)))
    return out
