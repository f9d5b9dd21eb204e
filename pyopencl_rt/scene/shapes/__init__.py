"""The analytic shape types, one module per type: ``REGISTRY`` maps each name to its
:class:`ShapeType`; ``Scene.shapes`` holds their abi.SHAPE records (a type and a block of 28
parameters that each type names for itself).

A type is a module of this package named as its entry of the kernel's shape enum
(:data:`pyopencl_rt.device.abi.SHAPE_TYPES`), paired by that name with ``cl/shapes/<name>.h``
(which the generated header "shapes/units.h" includes and dispatches to).  Its docstring documents
the type for scene files, and it defines, over (n, 28) float64 parameter rows:

* ``params(...)``: one shape's row (its own arguments);
* ``bounds(p) -> (lo, hi)``, ``area(p)``, ``reach(p)`` (the largest coordinate it reaches) and
  ``emission_cone(p) -> (axis, cos_o)`` (its normals' cone, for the light BVH);
* ``transformed(p, m)``: the rows under the 4 x 4 affine map m (a scene's mirror, an instance, the
  camera-relative shift), or None where m makes it another shape; then ``mesh(p, m) -> (v, f, uv,
  normals, matrix)``: one shape as triangles (its exact normals) to be moved by ``matrix``;
* ``check(p) -> [(row, what)]``: what the kernels cannot take (scene/validate.py says it);
* ``to_mitsuba(p) -> dict``: one shape as Mitsuba 3's ``mi.load_dict`` takes it;
* ``TOML_KEYS`` and ``read_toml(t)``: a ``[[shape]]`` table of this type (its ``type`` and
  ``material`` aside), through a :class:`~pyopencl_rt.scene.loaders.values.TableReader`;
* ``MITSUBA_PLUGINS`` and ``from_mitsuba(obj, read)`` (``read``: :class:`.frames.ShapeMitsubaReading`;
  None where the file's shape is not one of ours, an elliptic tube: the loader makes its triangles),
  and ``FLIPS``: whether flip_normals turns it over (else the loader flips its medium interface).

Adding a type: ``<name>.py`` here, its entry of ``abi.SHAPE_TYPES`` and ``cl/shapes/<name>.h``
(``shape_intersect_<name>``, ``_point_``, ``_normal_``, ``_sample_`` and its ``SHAPE_CASE_<NAME>``);
docs/ARCHITECTURE.md has the recipe and tests/render/test_shape_units.py checks that they agree.
"""
from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass
from typing import Callable

import numpy as np

from ...device import abi
from .frames import rows

__all__ = ["REGISTRY", "MITSUBA_TYPES", "ShapeType", "shape_type", "records", "unit_rows"]


@dataclass(frozen=True)
class ShapeType:
    """One analytic shape type: its module's definitions and its kernel enum value ``code``."""

    name: str
    code: int
    documentation: str
    params: Callable
    bounds: Callable
    area: Callable
    reach: Callable
    emission_cone: Callable
    transformed: Callable
    mesh: Callable | None  # None: transformed never gives None
    check: Callable
    to_mitsuba: Callable
    toml_keys: frozenset
    read_toml: Callable
    mitsuba_plugins: tuple
    from_mitsuba: Callable
    flips: bool

    @classmethod
    def from_module(cls, name: str, code: int, module) -> "ShapeType":
        return cls(name=name, code=code, documentation=inspect.cleandoc(module.__doc__), params=module.params,
                   bounds=module.bounds, area=module.area, reach=module.reach, emission_cone=module.emission_cone,
                   transformed=module.transformed, mesh=getattr(module, "mesh", None), check=module.check,
                   to_mitsuba=module.to_mitsuba, toml_keys=frozenset(module.TOML_KEYS), read_toml=module.read_toml,
                   mitsuba_plugins=tuple(module.MITSUBA_PLUGINS), from_mitsuba=module.from_mitsuba, flips=module.FLIPS)


REGISTRY: dict[str, ShapeType] = {
    name: ShapeType.from_module(name, code, importlib.import_module(f".{name}", __name__))
    for name, code in abi.SHAPE_TYPES.items()
}
BY_CODE = {t.code: t for t in REGISTRY.values()}
MITSUBA_TYPES = {plugin: t for t in REGISTRY.values() for plugin in t.mitsuba_plugins}


def shape_type(code) -> ShapeType:
    return BY_CODE[int(code)]


def records(shape: ShapeType | str, p) -> np.ndarray:
    """abi.SHAPE records of one type from its (n, 28) parameter rows."""
    t = REGISTRY[shape] if isinstance(shape, str) else shape
    p = rows(p)
    out = np.zeros(len(p), abi.SHAPE)
    out["params"], out["type"] = p, t.code
    return out


def unit_rows(shapes) -> list:
    """[(ShapeType, indices, (n, 28) float64 rows)] of each type present in the records ``shapes``."""
    shapes = np.asarray(shapes, abi.SHAPE)
    out = []
    for code in np.unique(shapes["type"]):
        idx = np.flatnonzero(shapes["type"] == code)
        out.append((shape_type(code), idx, shapes["params"][idx].astype(np.float64)))
    return out


def per_shape(shapes, fn: str) -> np.ndarray:
    """Each type's scalar ``fn`` ("area", "reach") over the records, in their order."""
    shapes = np.asarray(shapes, abi.SHAPE)
    out = np.zeros(len(shapes))
    for t, idx, p in unit_rows(shapes):
        out[idx] = getattr(t, fn)(p)
    return out


def bounds(shapes) -> tuple:
    """(lo, hi): (S, 3) float64 boxes of the records."""
    shapes = np.asarray(shapes, abi.SHAPE)
    lo, hi = np.zeros((len(shapes), 3)), np.zeros((len(shapes), 3))
    for t, idx, p in unit_rows(shapes):
        lo[idx], hi[idx] = t.bounds(p)
    return lo, hi


def transformed(shapes, m) -> np.ndarray:
    """The records under the 4 x 4 affine map m (each type must keep its shape: a similarity for
    spheres, as the mirror and the camera-relative shift are)."""
    out = np.array(shapes, abi.SHAPE, copy=True)
    for t, idx, p in unit_rows(shapes):
        moved = t.transformed(p, m)
        if moved is None:
            raise ValueError(f"{t.name}: the map makes it another shape")
        out["params"][idx] = moved
    return out
