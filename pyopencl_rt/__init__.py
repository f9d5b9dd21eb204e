"""pyopencl_rt: a physically based wavefront path tracer with an OpenCL back end.

Python API::

    import pyopencl_rt as rt
    hits = rt.trace(mesh, origins, directions)          # closest hit
    blocked = rt.occluded(mesh, origins, directions)     # any hit
    bvh = rt.build_bvh(vertices, faces)                  # reuse across calls

    scene = rt.load_scene("scenes/cornell-box.toml")     # TOML scene, OBJ+MTL, glTF, PLY...
    image = rt.render(scene, spp=64, device="cpu")       # H x W x 3 float32, linear
"""
from .accel.bvh import BVH, build_bvh
from .device.devices import list_devices, select_device
from .errors import DeviceSelectionError, UserError
from .render.api import render, render_full
from .scene.model import Camera, Material, RenderSettings, Scene
from .scene.loaders import load_scene
from .trace import occluded, trace

__all__ = [
    "BVH", "build_bvh", "trace", "occluded", "list_devices", "select_device",
    "load_scene", "render", "render_full", "Scene", "Material", "Camera", "RenderSettings",
    "UserError", "DeviceSelectionError",
]
