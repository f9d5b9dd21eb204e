"""pyopencl_rt: a physically based wavefront path tracer with an OpenCL back end.

Python API::

    import pyopencl_rt as rt
    hits = rt.trace(mesh, origins, directions)          # closest hit
    blocked = rt.occluded(mesh, origins, directions)     # any hit
    bvh = rt.build_bvh(vertices, faces)                  # reuse across calls

    scene = rt.load_scene("scenes/cornell-box.toml")     # TOML scene, OBJ+MTL, glTF, PLY...
    image = rt.render(scene, spp=64, device="cpu")       # H x W x 3 float32, linear
    image = rt.render("scenes/cornell-box.toml", spp=64) # or the scene file itself

The names below are imported on first use (PEP 562), so that ``pyopencl-rt`` starts without
numpy and pyopencl and can answer Ctrl-C at once (cli.main handles it from its first line).
"""
import importlib
import sys
import types

from .errors import DeviceSelectionError, UsageError, UserError

_LAZY = {
    "BVH": ".accel.bvh", "build_bvh": ".accel.bvh",
    "list_devices": ".device.devices", "select_device": ".device.devices",
    "render": ".render.api", "render_full": ".render.api",
    "Camera": ".scene.model", "Material": ".scene.model", "RenderSettings": ".scene.model", "Scene": ".scene.model",
    "load_scene": ".scene.loaders",
    "occluded": ".trace", "trace": ".trace",
}

__all__ = [
    "BVH", "build_bvh", "trace", "occluded", "list_devices", "select_device",
    "load_scene", "render", "render_full", "Scene", "Material", "Camera", "RenderSettings",
    "UserError", "UsageError", "DeviceSelectionError",
]


class _Package(types.ModuleType):
    def __getattr__(self, name):
        if name not in _LAZY:
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
        value = getattr(importlib.import_module(_LAZY[name], __name__), name)
        types.ModuleType.__setattr__(self, name, value)
        return value

    def __setattr__(self, name, value):
        # importing the submodule pyopencl_rt.trace sets the package's attribute "trace" to it:
        # the public name stays the function
        if name in _LAZY and isinstance(value, types.ModuleType):
            return
        types.ModuleType.__setattr__(self, name, value)

    def __dir__(self):
        return sorted(set(super().__dir__()) | set(_LAZY))


sys.modules[__name__].__class__ = _Package
