"""A BVH as the kernels read it on one device: which node format a device traverses (binary
for GPUs, 4-wide for CPUs), the node buffer of that format with conservatively padded boxes, and
the per-device upload cache."""
from __future__ import annotations

import numpy as np

from ..device import abi
from ..errors import UserError
from .bvh import BVH


def padded_nodes(bvh: BVH) -> np.ndarray:
    """Node boxes grown by 2^-20 of the scene's largest coordinate, so that the box test is
    conservative with respect to the triangle test's rounding (cl/accel/intersect.h)."""
    nodes = bvh.nodes.copy()
    if len(bvh.triangles) == 0:
        return nodes
    scale = float(np.abs(bvh.bounds).max())
    pad = np.float32(scale * abi.BOX_PAD_RELATIVE)
    for side in ("left", "right"):
        present = nodes[f"count_{side}"] >= 0
        lo, hi = nodes[f"bmin_{side}"], nodes[f"bmax_{side}"]
        lo[present] = np.nextafter(lo[present] - pad, np.float32(-np.inf))
        hi[present] = np.nextafter(hi[present] + pad, np.float32(np.inf))
    return nodes


LAYOUTS = ("binary", "wide")
LAYOUT_ENV = "PYOPENCL_RT_BVH_LAYOUT"


def bvh_layout(device, layout: str | None = None) -> str:
    """The BVH layout the kernels traverse on ``device``: ``layout`` if given, else the
    ``PYOPENCL_RT_BVH_LAYOUT`` environment variable, else ``"wide"`` (4-wide nodes, Tri4 leaves:
    cl/accel/bvh_wide.h) on CPU devices and ``"binary"`` (cl/accel/bvh.h) on the others."""
    import os

    layout = layout or os.environ.get(LAYOUT_ENV) or None
    if layout is None:
        import pyopencl as cl

        layout = "wide" if device.type & cl.device_type.CPU else "binary"
    if layout not in LAYOUTS:
        raise UserError(f"unknown BVH layout {layout!r}: use 'binary' or 'wide' (argument or ${LAYOUT_ENV})")
    return layout


def layout_defines(layout: str) -> dict:
    """Preprocessor defines that make cl/accel/trace.cl and cl/scene/scene.h traverse ``layout``."""
    return {"BVH_WIDE": True} if layout == "wide" else {}


def node_buffer(bvh: BVH, layout: str) -> np.ndarray:
    """What the kernels' first (nodes) buffer holds for ``layout``, boxes padded either way."""
    if layout == "wide":
        from .bvh_wide import device_blob, wide_bvh

        return device_blob(wide_bvh(bvh))
    return padded_nodes(bvh)


class DeviceBVH:
    """A BVH uploaded to one device in one layout (kept on the BVH object, one per device and layout)."""

    def __init__(self, bvh: BVH, rt, layout: str = "binary"):
        import pyopencl as cl

        mf = cl.mem_flags
        ctx = rt.context

        def upload(a):
            a = np.ascontiguousarray(a)
            if a.nbytes == 0:  # OpenCL forbids empty buffers
                a = np.zeros(16, np.uint8)
            return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)

        self.layout = layout
        self.defines = layout_defines(layout)
        self.nodes = upload(node_buffer(bvh, layout))
        self.triangles = upload(bvh.triangles)
        self.prim_ids = upload(bvh.prim_ids.astype(np.int32))


def device_bvh(bvh: BVH, rt, layout: str = "binary") -> DeviceBVH:
    cache = bvh.__dict__.setdefault("_device_cache", {})
    key = (id(rt), layout)
    if key not in cache:
        cache[key] = DeviceBVH(bvh, rt, layout)
    return cache[key]
