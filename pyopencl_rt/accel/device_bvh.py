"""A BVH as the kernels read it on one device: which node format a device traverses (binary
for GPUs, 8-wide or 4-wide for CPUs), the node buffer of that format with conservatively padded boxes, and
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


# layout name -> node width (binary: 2); "wide" is the 4-wide layout
LAYOUT_WIDTHS = {"binary": 2, "wide": 4, "wide8": 8}
LAYOUTS = tuple(LAYOUT_WIDTHS)
LAYOUT_ENV = "PYOPENCL_RT_BVH_LAYOUT"
CPU_LAYOUT = "wide8"


def bvh_layout(device, layout: str | None = None) -> str:
    """The BVH layout the kernels traverse on ``device``: ``layout`` if given, else the
    ``PYOPENCL_RT_BVH_LAYOUT`` environment variable, else :data:`CPU_LAYOUT` on CPU devices (8-wide
    nodes, Tri8 leaves: cl/accel/bvh_wide8.h; ``"wide"`` is the 4-wide one, cl/accel/bvh_wide.h) and
    ``"binary"`` (cl/accel/bvh.h) on the others."""
    import os

    layout = layout or os.environ.get(LAYOUT_ENV) or None
    if layout is None:
        import pyopencl as cl

        layout = CPU_LAYOUT if device.type & cl.device_type.CPU else "binary"
    if layout not in LAYOUTS:
        raise UserError(f"unknown BVH layout {layout!r}: use one of {', '.join(LAYOUTS)} (argument or ${LAYOUT_ENV})")
    return layout


# Rays (paths) per work-item of the packet kernels on PoCL's x86 CPU device: 16 (one AVX-512 register of
# floats), 8 (one AVX2 register) or 0 (one per work-item), from what PoCL compiles for
# (pyopencl_rt/device/isa.py); $PYOPENCL_RT_LANES = 0 turns packets off, 8 or 16 asks for that width.
LANES_ENV = "PYOPENCL_RT_LANES"
# trace()/occluded(): a packet whose ray origins lie further apart than this share of the scene's
# largest extent goes ray by ray (cl/accel/trace.cl); the bench's diffuse bounces of 16
# neighbouring pixels span 2-4% of the torus, a batch in random order about 80%
PACKET_ORIGIN_SPREAD = 0.125
_REFUSALS_SAID: set = set()


def lanes_setting(requested=None) -> str:
    """``requested`` or ``$PYOPENCL_RT_LANES`` as given ("" for the default), checked."""
    import os

    text = requested if requested is not None else os.environ.get(LANES_ENV)
    text = "" if text is None else str(text).strip()
    if text not in ("", "0", "8", "16"):
        raise UserError(f"${LANES_ENV}={text!r}: use 0 (one path per work-item), 8 or 16")
    return text


def packet_choice(device, requested=None) -> tuple[int, str]:
    """Rays (paths) per work-item of the lane kernels on ``device`` and why: on an x86 CPU device the
    width :func:`pyopencl_rt.device.isa.lane_rule` gives for its OpenCL implementation (PoCL: from
    what it compiles for; Intel's CPU runtime: as measured), elsewhere 0 (one ray per work-item).
    ``requested`` or ``$PYOPENCL_RT_LANES`` overrides: 0 (off), 8 or 16, the latter two only where
    the implementation builds that width alike (else one warning line and the rule's width)."""
    import warnings

    import pyopencl as cl

    from ..device import isa as isa_module

    text = lanes_setting(requested)
    if not isa_module.x86_cpu(device):
        return 0, "one path per work-item: the lane kernels are for CPU devices on x86"
    if text == "0":
        return 0, f"one path per work-item: ${LANES_ENV}=0"
    try:
        rule = isa_module.lane_rule(device)
    except cl.Error as exc:  # a device that cannot build the probe cannot be trusted with lanes
        return 0, f"one path per work-item: the instruction-set probe failed ({str(exc).splitlines()[0]})"
    if not text:
        return rule.default, rule.reason
    width, refusal = rule.checked(int(text))
    if refusal:
        if refusal not in _REFUSALS_SAID:
            _REFUSALS_SAID.add(refusal)
            warnings.warn(f"${LANES_ENV}={text}: {refusal}", stacklevel=3)
        return width, refusal
    return width, f"{width} lanes: ${LANES_ENV}={text} ({rule.describe})"


def packet_width(device, requested=None) -> int:
    """The width of :func:`packet_choice`."""
    return packet_choice(device, requested)[0]


def layout_defines(layout: str) -> dict:
    """Preprocessor defines that make cl/accel/traverse.h (trace.cl, scene.h) traverse ``layout``."""
    return {"wide": {"BVH_WIDE": True}, "wide8": {"BVH_WIDE8": True}}.get(layout, {})


def node_buffer(bvh: BVH, layout: str, consume: bool = False) -> np.ndarray:
    """What the kernels' first (nodes) buffer holds for ``layout``, boxes padded either way.
    ``consume`` (a renderer's own BVH): a wide layout is built for this buffer alone, not cached,
    and takes the binary records from ``bvh`` (bvh_wide.build_wide)."""
    width = LAYOUT_WIDTHS[layout]
    if width > 2:
        from .bvh_wide import build_wide, device_blob, wide_bvh

        return device_blob(build_wide(bvh, width, consume=True) if consume else wide_bvh(bvh, width))
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
