"""The ray-casting API: ``trace`` (closest hit) and ``occluded`` (any hit).

Both take the same geometry (a trimesh mesh or scene, a ``(vertices, faces)`` pair, or a built
:class:`~pyopencl_rt.bvh.BVH`) and the same rays, and run either on an OpenCL device
(``backend="opencl"``) or through Intel Embree (``backend="embree"``, the reference).
"""
from __future__ import annotations

import numpy as np

from .accel.bvh import BVH, build_bvh
from .errors import UserError
from .accel.device_bvh import bvh_layout, device_bvh
from .accel.embree import embree_scene
from .scene.mesh import flatten


def as_bvh(geometry) -> BVH:
    """A BVH for ``geometry``; a BVH is returned as is, so repeated calls don't rebuild."""
    if isinstance(geometry, BVH):
        return geometry
    vertices, faces = flatten(geometry, name="geometry")
    return build_bvh(vertices, faces)


def _rays(origins, directions, tmin, tmax):
    o = np.ascontiguousarray(np.asarray(origins, dtype=np.float32).reshape(-1, 3))
    d = np.ascontiguousarray(np.asarray(directions, dtype=np.float32).reshape(-1, 3))
    if o.shape != d.shape:
        if len(o) == 1:
            o = np.ascontiguousarray(np.broadcast_to(o, d.shape))
        elif len(d) == 1:
            d = np.ascontiguousarray(np.broadcast_to(d, o.shape))
        else:
            raise UserError(f"origins {o.shape} and directions {d.shape} differ in length")
    n = len(o)
    tmin = np.ascontiguousarray(np.broadcast_to(np.asarray(tmin, dtype=np.float32), (n,)))
    tmax = np.ascontiguousarray(np.broadcast_to(np.asarray(tmax, dtype=np.float32), (n,)))
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

    def inbuf(a):
        return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)

    bo, bd, bmin, bmax = inbuf(o), inbuf(d), inbuf(tmin), inbuf(tmax)
    gsize, lsize = (n,), None
    if dev.layout == "wide":  # small work-groups: PoCL keeps a private stack per work-item of a group
        gsize, lsize = ((n + 63) // 64 * 64,), (64,)
    if any_hit:
        out = np.empty(n, np.uint8)
        bout = cl.Buffer(ctx, mf.WRITE_ONLY, out.nbytes)
        rt.kernel(("accel/trace.cl",), "trace_any", dev.defines)(queue, gsize, lsize, dev.nodes, dev.triangles, bo, bd, bmin, bmax, np.int32(n), bout)
        cl.enqueue_copy(queue, out, bout)
        return out.astype(bool)
    res = {
        "t": np.empty(n, np.float32),
        "prim_id": np.empty(n, np.int32),
        "u": np.empty(n, np.float32),
        "v": np.empty(n, np.float32),
        "normal": np.empty((n, 3), np.float32),
    }
    bufs = {k: cl.Buffer(ctx, mf.WRITE_ONLY, a.nbytes) for k, a in res.items()}
    rt.kernel(("accel/trace.cl",), "trace_closest", dev.defines)(
        queue, gsize, lsize, dev.nodes, dev.triangles, dev.prim_ids, bo, bd, bmin, bmax, np.int32(n),
        bufs["t"], bufs["prim_id"], bufs["u"], bufs["v"], bufs["normal"],
    )
    for k, a in res.items():
        cl.enqueue_copy(queue, a, bufs[k])
    queue.finish()
    return res


def _embree(bvh, o, d, tmin, tmax, any_hit):
    n = len(o)
    if len(bvh.faces) == 0 or n == 0:
        if any_hit:
            return np.zeros(n, bool)
        return {"t": np.full(n, np.inf, np.float32), "prim_id": np.full(n, -1, np.int32),
                "u": np.zeros(n, np.float32), "v": np.zeros(n, np.float32), "normal": np.zeros((n, 3), np.float32)}
    scene = embree_scene(bvh)
    # embreex has no tnear argument: start the ray at tmin instead, and add tmin back.
    start = np.ascontiguousarray(o + tmin[:, None] * d, dtype=np.float32)
    span = np.ascontiguousarray(tmax - tmin, dtype=np.float32)
    if any_hit:
        return scene.run(start, d, dists=span, query="OCCLUDED") != -1
    r = scene.run(start, d, dists=span, output=1)
    hit = r["primID"] >= 0
    t = np.where(hit, r["tfar"] + tmin, np.inf).astype(np.float32)
    ng = r["Ng"].astype(np.float32)
    with np.errstate(invalid="ignore", divide="ignore"):
        ng = np.where(hit[:, None], ng / np.linalg.norm(ng, axis=1, keepdims=True), 0.0).astype(np.float32)
    return {"t": t, "prim_id": r["primID"].astype(np.int32), "u": np.where(hit, r["u"], 0).astype(np.float32),
            "v": np.where(hit, r["v"], 0).astype(np.float32), "normal": ng}


def _cast(geometry, origins, directions, tmin, tmax, device, backend, layout, any_hit):
    """What trace() and occluded() share: the BVH, the rays, and the backend."""
    bvh = as_bvh(geometry)
    o, d, tmin, tmax = _rays(origins, directions, tmin, tmax)
    if backend == "embree":
        return _embree(bvh, o, d, tmin, tmax, any_hit=any_hit)
    if backend != "opencl":
        raise UserError(f"unknown backend {backend!r}: use 'opencl' or 'embree'")
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
    traverses, ``"binary"`` or ``"wide"`` (default: :func:`bvh_layout`, i.e. wide on CPUs).
    """
    return _cast(geometry, origins, directions, tmin, tmax, device, backend, layout, any_hit=False)


def occluded(geometry, origins, directions, tmin=0.0, tmax=np.inf, device=None, backend="opencl",
             layout=None) -> np.ndarray:
    """True for each ray that hits anything with t in (tmin, tmax) (``layout`` as for :func:`trace`)."""
    return _cast(geometry, origins, directions, tmin, tmax, device, backend, layout, any_hit=True)
