"""The material types, one module per type: ``REGISTRY`` maps each name to its :class:`MaterialType`.

A type is a module of this package named as its entry of the kernel's type enum
(:data:`pyopencl_rt.device.abi.MATERIAL_TYPES`), paired by that name with its BSDF in
``cl/materials/<name>.h``.  Its docstring documents the type for scene files
(docs/SCENE_FORMAT.md includes it verbatim), and it defines:

* ``TOML_KEYS``: the keys of a ``[materials.NAME]`` table of this type besides the ones every
  type takes (``type``, ``emission``, ``two_sided``, ``emission_texture``, read by the TOML loader);
* ``read_toml(material, table)``: set the material's parameters from ``table``, a
  :class:`~pyopencl_rt.scene.loaders.values.TableReader` (its checks raise the scene file's
  errors), with the defaults the docstring gives;
* ``pack(material, record)``: write those parameters into an ``abi.MATERIAL`` record whose
  type, emission, two-sided flag and texture indices :meth:`Material.record` has set;
* ``KERNEL_DEFINE``: the ``HAS_MATERIAL_<NAME>`` that compiles the type into a scene's kernels
  (cl/materials/dispatch.h), or None for one that is always compiled;
* ``MTL_PRECEDENCE`` and ``from_mtl(material, mtl) -> bool`` (optional): claim a material of an
  MTL file from its statements (:class:`~pyopencl_rt.scene.loaders.obj.MtlStatements`) and set
  its parameters; the OBJ loader asks the types in increasing precedence, the first claim wins;
* ``to_mitsuba(material) -> dict`` (optional): the Mitsuba 3 BSDF, as ``mi.load_dict`` takes it;
* ``MITSUBA_PLUGINS`` and ``from_mitsuba(obj, material, color)`` (optional): the Mitsuba XML BSDF
  plugins the type reads itself ({plugin: the parameters it renders as Mitsuba does}) and its reader
  (``obj`` the XML object, ``color(name, default)`` a colour or texture of it), for plugins the
  XML loader (scene/loaders/mitsuba_bsdf.py) does not read on its own.

Other modules here are helpers shared by types (``microfacet.py``, as ``cl/materials/microfacet.h``).

Adding a type: ``<name>.py`` here, its enum entry in ``device/abi.py`` and its kernel
``cl/materials/<name>.h``, which defines its case of ``cl/materials/dispatch.h`` (the dispatch
includes it and routes to it from the enum), and its docstring in docs/SCENE_FORMAT.md
(tests/scene/test_material_registry.py checks that these agree; docs/ARCHITECTURE.md has the
recipe).  A type whose parameters are not yet fields of :class:`~pyopencl_rt.scene.model.Material`
(or entries of its ``params``) and of the ``abi.MATERIAL`` record also adds them there.
"""
from __future__ import annotations

import importlib
import inspect
from dataclasses import dataclass
from typing import Callable

from ...device import abi


@dataclass(frozen=True)
class MaterialType:
    """One material type: its module's definitions, and its kernel enum value ``type_id``."""

    name: str
    type_id: int
    documentation: str
    toml_keys: frozenset
    read_toml: Callable
    pack: Callable
    kernel_define: str | None
    mtl_precedence: int | None = None
    from_mtl: Callable | None = None
    to_mitsuba: Callable | None = None
    mitsuba_plugins: dict | None = None
    from_mitsuba: Callable | None = None

    @classmethod
    def from_module(cls, name: str, type_id: int, module) -> "MaterialType":
        return cls(
            name=name, type_id=type_id, documentation=inspect.cleandoc(module.__doc__),
            toml_keys=frozenset(module.TOML_KEYS), read_toml=module.read_toml, pack=module.pack,
            kernel_define=module.KERNEL_DEFINE, mtl_precedence=getattr(module, "MTL_PRECEDENCE", None),
            from_mtl=getattr(module, "from_mtl", None), to_mitsuba=getattr(module, "to_mitsuba", None),
            mitsuba_plugins=getattr(module, "MITSUBA_PLUGINS", None), from_mitsuba=getattr(module, "from_mitsuba", None),
        )


def _registry() -> dict[str, MaterialType]:
    types = {}
    for name, type_id in sorted(abi.MATERIAL_TYPES.items(), key=lambda item: item[1]):
        types[name] = MaterialType.from_module(name, type_id, importlib.import_module(f"{__name__}.{name}"))
    return types


REGISTRY: dict[str, MaterialType] = _registry()

# The types that MTL materials can become, in the order the OBJ loader asks them.
MTL_TYPES: tuple[MaterialType, ...] = tuple(
    sorted((t for t in REGISTRY.values() if t.from_mtl is not None), key=lambda t: t.mtl_precedence))


# The Mitsuba XML BSDF plugins that registered types read themselves: plugin -> type.
MITSUBA_TYPES: dict[str, MaterialType] = {
    plugin: t for t in REGISTRY.values() for plugin in (t.mitsuba_plugins or {})}


def documentation() -> str:
    """The scene-file documentation of every type, as docs/SCENE_FORMAT.md has it."""
    from . import microfacet

    return "\n\n".join([inspect.cleandoc(microfacet.__doc__)] + [t.documentation for t in REGISTRY.values()])
