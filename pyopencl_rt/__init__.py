"""pyopencl_rt: a physically based wavefront path tracer with an OpenCL back end.

Python API::

    import pyopencl_rt as rt
    hits = rt.trace(mesh, origins, directions)          # closest hit
    blocked = rt.occluded(mesh, origins, directions)     # any hit
    bvh = rt.build_bvh(vertices, faces)                  # reuse across calls
"""
from .bvh import BVH, build_bvh
from .devices import list_devices, select_device
from .errors import DeviceSelectionError, UserError
from .trace import occluded, trace

__all__ = [
    "BVH", "build_bvh", "trace", "occluded", "list_devices", "select_device",
    "UserError", "DeviceSelectionError",
]
