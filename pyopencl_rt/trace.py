"""The ray-casting API: ``trace`` (closest hit) and ``occluded`` (any hit).

Both take the same geometry (a trimesh mesh or scene, a ``(vertices, faces)`` pair, or a built
:class:`~pyopencl_rt.bvh.BVH`) and the same rays, and run either on an OpenCL device
(``backend="opencl"``) or through Intel Embree (``backend="embree"``, the reference).
"""
from __future__ import annotations

import numpy as np

from .accel.bvh import BVH, build_bvh
from . import validate
from .errors import UsageError
from .accel.device_bvh import PACKET_ORIGIN_SPREAD, bvh_layout, device_bvh, packet_width
from .accel.embree import embree_scene
from .scene.mesh import flatten


def as_bvh(geometry) -> BVH:
    """A BVH for ``geometry``; a BVH is returned as is, so repeated calls don't rebuild."""
    if isinstance(geometry, BVH):
        return geometry
    vertices, faces = flatten(geometry, name="geometry")
    if len(faces):
        from .scene.validate import GEOMETRY_LIMIT

        reach = float(np.abs(vertices[np.unique(faces)]).max())
        if reach > GEOMETRY_LIMIT:
            raise UsageError(f"geometry: vertices reach {reach:.3g} from the origin, beyond {GEOMETRY_LIMIT:.3g}: the "
                             "float32 kernels cannot intersect them (scale the geometry down)")
    return build_bvh(vertices, faces)


def _rays(origins, directions, tmin, tmax):
    """The rays as contiguous float32, checked (pyopencl_rt.validate): (N, 3) or (3,) origins and
    directions of real numbers that float32 holds (one of them may be a single row, used for
    every ray); never reshaped, so a (3, N) array is refused; directions not zero; tmin a finite
    number or (N,) of them, tmax likewise or +inf."""
    o = validate.float32_rows(origins, "origins")
    d = validate.float32_rows(directions, "directions")
    if o.shape != d.shape:
        if len(o) == 1:
            o = np.ascontiguousarray(np.broadcast_to(o, d.shape))
        elif len(d) == 1:
            d = np.ascontiguousarray(np.broadcast_to(d, o.shape))
        else:
            raise UsageError(f"origins {o.shape} and directions {d.shape} differ in length")
    zero = ~d.any(axis=1)
    if zero.any():
        raise UsageError(f"directions has {int(zero.sum())} zero vectors (first at row {int(np.argmax(zero))})")
    n = len(o)
    tmin = validate.float32_per_row(tmin, "tmin", n)
    tmax = validate.float32_per_row(tmax, "tmax", n, allow_inf=True)
    return o, d, tmin, tmax


def _opencl(bvh, o, d, tmin, tmax, device, any_hit, layout=None):
    import pyopencl as cl

    from .device.devices import select_device
    from .device.kernels import runtime

    rt = runtime(select_device(device))
    dev = device_bvh(bvh, rt, bvh_layout(rt.device, layout))
    n = len(o)
    mf = cl.mem_flags
    ctx, queue = rt.context, rt.queue
    if n == 0:
        return None if not any_hit else np.zeros(0, bool)

    # The rays and results stay in host memory (USE_HOST_PTR): a CPU device (PoCL) reads and
    # writes them in place, without the copies in and out (10-30% of a trace() of 1M rays); the
    # results are read through a map, which is what makes them valid on any device.
    def inbuf(a):
        return cl.Buffer(ctx, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=a)

    def outbuf(a):
        return cl.Buffer(ctx, mf.WRITE_ONLY | mf.USE_HOST_PTR, hostbuf=a)

    def read(buf, a):
        mapped, _event = cl.enqueue_map_buffer(queue, buf, cl.map_flags.READ, 0, a.shape, a.dtype)
        if mapped.ctypes.data != a.ctypes.data:   # a device that keeps its own copy
            a[...] = mapped
        mapped.base.release(queue)

    bo, bd, bmin, bmax = inbuf(o), inbuf(d), inbuf(tmin), inbuf(tmax)
    # Groups of 64 rays (the kernels skip items past n): PoCL keeps a private stack per work-item of
    # a group, and it compiles a kernel once per group size, so a size of the driver's choice (the
    # whole grid) meant a new compile for every new ray count.
    gsize, lsize = ((n + 63) // 64 * 64,), (64,)
    defines, suffix, spread = dev.defines, "", ()
    width = packet_width(rt.device) if dev.layout == "wide8" else 0
    if width and not _packets_build(rt, {**dev.defines, "PACKET_WIDTH": width}):
        width = 0
    if width:  # packets of `width` consecutive rays per work-item (cl/accel/trace.cl), groups of 8
        items = -(-n // width)
        gsize, lsize = (-(-items // 8) * 8,), (8,)
        defines, suffix = {**dev.defines, "PACKET_WIDTH": width}, "_packets"
        extent = float(np.max(bvh.bounds[1] - bvh.bounds[0])) if len(bvh.triangles) else 0.0
        spread = (np.float32(PACKET_ORIGIN_SPREAD * extent),)
    if any_hit:
        out = _page_aligned(n, np.uint8)
        bout = outbuf(out)
        rt.kernel(("accel/trace.cl",), "trace_any" + suffix, defines)(
            queue, gsize, lsize, dev.nodes, dev.triangles, bo, bd, bmin, bmax, np.int32(n), *spread, bout)
        read(bout, out)
        queue.finish()
        return out.view(bool)  # the kernel writes 0 or 1
    res = {
        "t": _page_aligned(n, np.float32),
        "prim_id": _page_aligned(n, np.int32),
        "u": _page_aligned(n, np.float32),
        "v": _page_aligned(n, np.float32),
        "normal": _page_aligned((n, 3), np.float32),
    }
    bufs = {k: outbuf(a) for k, a in res.items()}
    rt.kernel(("accel/trace.cl",), "trace_closest" + suffix, defines)(
        queue, gsize, lsize, dev.nodes, dev.triangles, dev.prim_ids, bo, bd, bmin, bmax, np.int32(n), *spread,
        bufs["t"], bufs["prim_id"], bufs["u"], bufs["v"], bufs["normal"],
    )
    for k, a in res.items():
        read(bufs[k], a)
    queue.finish()
    return res


_PACKETS_FAILED: set = set()  # (runtime, defines) whose packet kernels did not build


def _packets_build(rt, defines) -> bool:
    """Whether the packet kernels build and create on ``rt``'s device (the runtime keeps them once
    built); where they do not, one warning line and trace()/occluded() go one ray per work-item (a
    kernel of ours never ends the process)."""
    import warnings

    import pyopencl as cl

    key = (id(rt), tuple(sorted(defines.items())))
    if key in _PACKETS_FAILED:
        return False
    try:
        rt.kernel(("accel/trace.cl",), "trace_closest_packets", defines)
        rt.kernel(("accel/trace.cl",), "trace_any_packets", defines)
        return True
    except cl.Error as exc:
        warnings.warn(f"the {defines['PACKET_WIDTH']}-ray packet kernels failed ({str(exc).splitlines()[0]}): "
                      "tracing one ray per work-item", stacklevel=3)
        _PACKETS_FAILED.add(key)
        return False


def _page_aligned(shape, dtype):
    """An uninitialised array starting on a page boundary: PoCL uses a USE_HOST_PTR buffer in place
    only when its memory is aligned (otherwise it allocates its own and copies)."""
    nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
    raw = np.empty(nbytes + 4096, np.uint8)
    start = (-raw.ctypes.data) % 4096
    return raw[start:start + nbytes].view(dtype).reshape(shape)


def _embree(bvh, o, d, tmin, tmax, any_hit):
    n = len(o)
    if len(bvh.faces) == 0 or n == 0:
        if any_hit:
            return np.zeros(n, bool)
        return {"t": np.full(n, np.inf, np.float32), "prim_id": np.full(n, -1, np.int32),
                "u": np.zeros(n, np.float32), "v": np.zeros(n, np.float32), "normal": np.zeros((n, 3), np.float32)}
    scene = embree_scene(bvh)
    # embreex has no tnear argument: start the ray at tmin instead, and add tmin back.  A start
    # beyond float32 (a huge tmin) has nothing to hit there: a miss, as in the OpenCL kernels.
    with np.errstate(over="ignore", invalid="ignore"):
        start = np.ascontiguousarray(o + tmin[:, None] * d, dtype=np.float32)
        span = np.ascontiguousarray(tmax - tmin, dtype=np.float32)
    lost = ~np.isfinite(start).all(axis=1)
    start[lost] = 0.0
    if any_hit:
        return (scene.run(start, d, dists=span, query="OCCLUDED") != -1) & ~lost
    r = scene.run(start, d, dists=span, output=1)
    hit = (r["primID"] >= 0) & ~lost
    r["primID"] = np.where(hit, r["primID"], -1)
    t = np.where(hit, r["tfar"] + tmin, np.inf).astype(np.float32)
    ng = r["Ng"].astype(np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        ng = np.where(hit[:, None], ng / np.linalg.norm(ng, axis=1, keepdims=True), 0.0).astype(np.float32)
    return {"t": t, "prim_id": r["primID"].astype(np.int32), "u": np.where(hit, r["u"], 0).astype(np.float32),
            "v": np.where(hit, r["v"], 0).astype(np.float32), "normal": ng}


def _cast(geometry, origins, directions, tmin, tmax, device, backend, layout, any_hit):
    """What trace() and occluded() share: the BVH, the rays, and the backend."""
    o, d, tmin, tmax = _rays(origins, directions, tmin, tmax)
    bvh = as_bvh(geometry)
    if backend == "embree":
        return _embree(bvh, o, d, tmin, tmax, any_hit=any_hit)
    if backend != "opencl":
        raise UsageError(f"unknown backend {backend!r}: use 'opencl' or 'embree'")
    res = _opencl(bvh, o, d, tmin, tmax, device, any_hit=any_hit, layout=layout)
    if res is None:  # zero rays: the empty result
        return _embree(bvh, o, d, tmin, tmax, any_hit=any_hit)
    return res


def trace(geometry, origins, directions, tmin=0.0, tmax=np.inf, device=None, backend="opencl",
          layout=None) -> dict:
    """Closest hit of each ray o + t d, t in (tmin, tmax).

    Returns a dict of arrays: ``t`` (inf on a miss), ``prim_id`` (face index, -1 on a miss),
    ``u``, ``v`` (barycentrics of the face's 2nd and 3rd vertex) and ``normal`` (unit geometric
    normal (v1 - v0) x (v2 - v0), zero on a miss).  ``layout``: the BVH layout the OpenCL kernel
    traverses, ``"binary"``, ``"wide"`` or ``"wide8"`` (default: :func:`bvh_layout`, i.e. wide8 on CPUs).
    """
    return _cast(geometry, origins, directions, tmin, tmax, device, backend, layout, any_hit=False)


def occluded(geometry, origins, directions, tmin=0.0, tmax=np.inf, device=None, backend="opencl",
             layout=None) -> np.ndarray:
    """True for each ray that hits anything with t in (tmin, tmax) (``layout`` as for :func:`trace`)."""
    return _cast(geometry, origins, directions, tmin, tmax, device, backend, layout, any_hit=True)
