"""The light types other than emissive surfaces, one module per type: ``REGISTRY`` maps each name to
its :class:`LightType`.

A type is a module of this package named as its entry of the kernel's light enum
(:data:`pyopencl_rt.device.abi.LIGHT_TYPES`), paired by that name with its sampling in
``cl/lights/<name>.h`` (which the generated header "lights/units.h" includes and dispatches to).
Its docstring documents the type for scene files, and it defines:

* ``LIGHT``: the light's dataclass (what loaders make and ``Scene.lights`` holds);
* ``INFINITE``: whether it is infinitely far (picked as pbrt-v4's BVH light sampler picks those,
  render/lights.py ``selection_weights``; HAS_INFINITE_LIGHTS), else the light BVH bounds it;
* ``TOML_KEYS`` and ``read_toml(t)``: a ``[[light]]`` table of this type (its ``type`` aside) read
  through a :class:`~pyopencl_rt.scene.loaders.values.TableReader` (``t.aimed()``: the position,
  frame and texture of a light aimed by ``position``, ``look_at`` and ``up``);
* ``pack(light, record, place) -> power``: write its ``abi.LIGHT`` record (whose kind and
  material the caller sets) and return its power's luminance for the light sampler; ``place``
  gives the scene's bounding sphere (``centre``, ``radius``) and ``texture_index(texture)``;
* ``transformed(light, m)``: the light under the 4x4 affine map ``m`` (a scene's mirror, the
  camera-relative shift);
* ``to_mitsuba(light) -> dict``: its Mitsuba 3 emitter, as ``mi.load_dict`` takes it (ValueError
  where it has none);
* ``MITSUBA_PLUGINS`` ({plugin: the parameters it renders as Mitsuba does}; empty where Mitsuba has
  no such emitter) and ``from_mitsuba(obj, read)`` (only with plugins): a Mitsuba XML emitter (``obj``; ``read``: the XML loader's
  ``EmitterReading``: ``color``, ``placed``, ``fov_x``, ``to_world``, ``sampling_weight``, ``error``);
* ``PBRT_TYPES`` and ``from_pbrt(params, read)``: a pbrt-v4 ``LightSource`` (``read``: pbrt_lights.py's
  ``LightReading``: ``ctm``, ``scale``, ``spectrum``, ``image``, ``warn``, ``error``).

Adding a type: ``<name>.py`` here, its entry of ``abi.LIGHT_TYPES`` and its kernel
``cl/lights/<name>.h`` (``light_sample_<name>`` and its ``LIGHT_CASE_<NAME>``); docs/ARCHITECTURE.md
has the recipe and tests/render/test_light_units.py checks that the three agree.  The environment
(:mod:`.environment`) is one per scene with tables of its own, and the emissive surfaces are
materials' emission: neither is a registered type here, though both sample through kernel units.
"""
from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass
from typing import Callable

from ...device import abi
from .directional import DirectionalLight
from .environment import Environment
from .frames import LUMINANCE, look_at_frame
from .point import PointLight
from .projector import ProjectorLight
from .spot import SpotLight

__all__ = ["REGISTRY", "MITSUBA_TYPES", "PBRT_TYPES", "LightType", "light_type", "DirectionalLight", "Environment",
           "PointLight", "ProjectorLight", "SpotLight", "LUMINANCE", "look_at_frame"]


@dataclass(frozen=True)
class LightType:
    """One light type: its module's definitions and its kernel enum value ``kind``."""

    name: str
    kind: int
    documentation: str
    light: type
    infinite: bool
    toml_keys: frozenset
    read_toml: Callable
    pack: Callable
    transformed: Callable
    to_mitsuba: Callable
    mitsuba_plugins: dict
    from_mitsuba: Callable | None  # None: no Mitsuba plugin (MITSUBA_PLUGINS empty)
    pbrt_types: tuple
    from_pbrt: Callable

    @classmethod
    def from_module(cls, name: str, kind: int, module) -> "LightType":
        return cls(name=name, kind=kind, documentation=inspect.cleandoc(module.__doc__), light=module.LIGHT,
                   infinite=module.INFINITE, toml_keys=frozenset(module.TOML_KEYS), read_toml=module.read_toml,
                   pack=module.pack, transformed=module.transformed, to_mitsuba=module.to_mitsuba,
                   mitsuba_plugins=dict(module.MITSUBA_PLUGINS), from_mitsuba=getattr(module, "from_mitsuba", None),
                   pbrt_types=tuple(module.PBRT_TYPES), from_pbrt=module.from_pbrt)


# kernel units without a host module here (this package's docstring says why)
UNREGISTERED = ("triangle", "shape", "environment", "directional_area")


def _registry() -> dict[str, LightType]:
    return {name: LightType.from_module(name, kind, importlib.import_module(f"{__name__}.{name}"))
            for name, kind in abi.LIGHT_TYPES.items() if name not in UNREGISTERED}


REGISTRY: dict[str, LightType] = _registry()
_BY_CLASS = {t.light: t for t in REGISTRY.values()}
# the Mitsuba 3 emitter plugins and the pbrt-v4 LightSource types that the registered types read
MITSUBA_TYPES: dict[str, LightType] = {plugin: t for t in REGISTRY.values() for plugin in t.mitsuba_plugins}
PBRT_TYPES: dict[str, LightType] = {name: t for t in REGISTRY.values() for name in t.pbrt_types}


def light_type(light) -> LightType:
    """The registered type of a light object (TypeError for an object of no registered type)."""
    t = _BY_CLASS.get(type(light))
    if t is None:
        raise TypeError(f"unknown light {light!r}")
    return t
