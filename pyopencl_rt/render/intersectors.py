"""Who traces the wavefront's rays: the extend (closest hit) and shadow (any hit) stages.

An :class:`Intersector` is to the wavefront what pbrt-v4's ``WavefrontAggregate`` is to its
integrator: the two ray-casting stages behind one interface, so that the rest of the wavefront
(generate, shade, accumulate) does not know who traces.

- :class:`OpenCLIntersector` (``"opencl"``, the default): our traversal kernels,
  ``cl/wavefront/extend.cl`` and ``shadow.cl``, on the wavefront's device.
- :class:`EmbreeIntersector` (``"embree"``): Intel Embree (embreex, robust mode, as the reference
  back end of :func:`pyopencl_rt.trace`) on the host.  It reads the active queue and the rays
  from the device, traces them, and writes the hits (or adds the unoccluded shadow contributions)
  back.  Comparing its samples/s with the default shows what our traversal costs inside a full
  render; the transfers are included on purpose (on PoCL they are memcpys, on a GPU they would
  dominate).  Embree returns original face ids, and the kernels expect BVH-reordered triangle
  indices, so hits are mapped through the inverse of ``bvh.prim_ids``.  Analytic shapes are not in the
  Embree scene: scenes with them are refused, and so are scenes with participating media (their
  shadow rays need transmittance, cl/render/volpath.h, not an any-hit test).

Each intersector keeps ``host_seconds`` per stage (time spent on the host, transfers included);
:meth:`Wavefront.run` adds it to the stage profile, where a device stage has its event times.
"""
from __future__ import annotations

import time

import numpy as np

from ..errors import UserError

INTERSECTORS = ("opencl", "embree")


class Intersector:
    """The extend and shadow stages of one :class:`~pyopencl_rt.render.wavefront.Wavefront`."""

    name = ""

    def __init__(self):
        self.host_seconds = {"extend": 0.0, "shadow": 0.0}

    def check(self, scene) -> None:
        """Refuse (UserError) a scene this intersector cannot trace, before anything is built."""

    def extend(self, wf, n_active: int, queue_in, queue_out):
        """Closest hit of the n_active paths of queue_in into hit_t/prim/u/v.  Returns the
        device event, or None when the work was done synchronously on the host."""
        raise NotImplementedError

    def shadow(self, wf, n_active: int, queue_in, queue_out):
        """Any-hit test of the shadow rays that shade queued (counters[COUNTER_SHADOW] of them,
        at most n_active); the unoccluded ones add their contribution to the path's radiance."""
        raise NotImplementedError


class OpenCLIntersector(Intersector):
    name = "opencl"

    def extend(self, wf, n_active, queue_in, queue_out):
        return wf.launch("extend", n_active, queue_in, queue_out, n_items=n_active)

    def shadow(self, wf, n_active, queue_in, queue_out):
        return wf.launch("shadow", n_active, queue_in, queue_out)


class EmbreeIntersector(Intersector):
    name = "embree"

    def __init__(self):
        super().__init__()
        self.wavefront = None

    def check(self, scene) -> None:
        if len(scene.shapes):
            raise UserError("--intersector embree: scenes with analytic shapes (spheres, disks, tubes) are not supported "
                            "(Embree gets triangles only)")
        if scene.has_media():
            raise UserError("--intersector embree: scenes with participating media or index-matched shapes are not "
                            "supported (their shadow rays need the transmittance through media and null boundaries, "
                            "which the OpenCL shadow stage computes)")

    def _attach(self, wf) -> None:
        """Host copies of the wave's rays and hits, and Embree's scene (once per wavefront)."""
        from ..accel.embree import embree_scene

        bvh = wf.bvh
        self.wavefront = wf
        self.embree = embree_scene(bvh) if len(bvh.faces) else None
        self.to_bvh_index = np.empty(len(bvh.prim_ids), np.int32)
        self.to_bvh_index[np.asarray(bvh.prim_ids, np.int64)] = np.arange(len(bvh.prim_ids), dtype=np.int32)
        size = wf.wave_size
        self.origins = np.empty((size, 3), np.float32)
        self.directions = np.empty((size, 3), np.float32)
        self.queue = np.empty(size, np.int32)
        self.hit = {name: np.empty(size, dtype) for name, dtype in
                    (("hit_t", np.float32), ("hit_prim", np.int32), ("hit_u", np.float32), ("hit_v", np.float32))}
        self.radiance = np.empty((size, 3), np.float32)
        self.contribution = np.empty((size, 3), np.float32)
        self.counters = np.zeros(wf.counter_slot("shadow") + 1, np.int32)

    def _rays(self, wf, queue_buffer, count, origin_name, direction_name):
        import pyopencl as cl

        queue = wf.rt.queue
        active = self.queue[:count]
        cl.enqueue_copy(queue, active, queue_buffer)  # blocking: after the stages before it (in-order queue)
        cl.enqueue_copy(queue, self.origins, wf.buffer(origin_name))
        cl.enqueue_copy(queue, self.directions, wf.buffer(direction_name))
        return active, np.ascontiguousarray(self.origins[active]), np.ascontiguousarray(self.directions[active])

    def extend(self, wf, n_active, queue_in, queue_out):
        import pyopencl as cl

        if self.wavefront is not wf:
            self._attach(wf)
        start = time.perf_counter()
        active, o, d = self._rays(wf, queue_in, n_active, "ray_o", "ray_d")
        h = self.hit
        if self.embree is not None and n_active:
            r = self.embree.run(o, d, output=1)
            prim = r["primID"]
            hit = prim >= 0
            h["hit_t"][active] = np.where(hit, r["tfar"], np.inf)
            h["hit_prim"][active] = np.where(hit, self.to_bvh_index[np.where(hit, prim, 0)], -1)
            h["hit_u"][active] = np.where(hit, r["u"], 0.0)
            h["hit_v"][active] = np.where(hit, r["v"], 0.0)
        else:
            h["hit_t"][active], h["hit_prim"][active], h["hit_u"][active], h["hit_v"][active] = np.inf, -1, 0.0, 0.0
        for name, values in h.items():
            cl.enqueue_copy(wf.rt.queue, wf.buffer(name), values)
        self.host_seconds["extend"] += time.perf_counter() - start
        return None

    def shadow(self, wf, n_active, queue_in, queue_out):
        import pyopencl as cl

        if self.wavefront is not wf:
            self._attach(wf)
        start = time.perf_counter()
        queue = wf.rt.queue
        cl.enqueue_copy(queue, self.counters, wf.buffer("counters"))  # after shade (in-order queue)
        count = int(self.counters[wf.counter_slot("shadow")])
        if count:
            active, o, d = self._rays(wf, wf.buffer("shadow_q"), count, "sh_o", "sh_d")
            if self.embree is not None:
                blocked = self.embree.run(o, d, dists=np.ones(count, np.float32), query="OCCLUDED") != -1
            else:
                blocked = np.zeros(count, bool)
            free = active[~blocked]
            if len(free):
                cl.enqueue_copy(queue, self.radiance, wf.buffer("radiance"))
                cl.enqueue_copy(queue, self.contribution, wf.buffer("sh_contrib"))
                self.radiance[free] += self.contribution[free]
                cl.enqueue_copy(queue, wf.buffer("radiance"), self.radiance)
        self.host_seconds["shadow"] += time.perf_counter() - start
        return None


def make_intersector(spec) -> Intersector:
    """An intersector from its name, or ``spec`` itself when it already is one."""
    if isinstance(spec, Intersector):
        return spec
    if spec == "opencl" or spec is None:
        return OpenCLIntersector()
    if spec == "embree":
        return EmbreeIntersector()
    raise UserError(f"unknown intersector {spec!r}: use one of {', '.join(INTERSECTORS)}")
