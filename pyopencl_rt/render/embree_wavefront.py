"""The wavefront renderer with its two ray-casting stages on the host, through Embree (embreex).

``EmbreeWavefront`` overrides :meth:`Wavefront.extend` and :meth:`Wavefront.shadow`: it reads
the active queue and the rays from the device, traces them with Embree (robust mode, as the
reference back end of :func:`pyopencl_rt.trace`), and writes the hits (or the unoccluded shadow
contributions) back; generation, shading and accumulation stay in OpenCL.  Comparing its
samples/s with the all-OpenCL renderer (``--intersector embree`` in ``render`` and in ``bench
convergence``) shows what our traversal costs inside a full render.  The transfers are included
on purpose: on the PoCL CPU device they are memcpys; on a GPU they would dominate.

Embree returns original face ids; the kernels expect BVH-reordered triangle indices, so hits
are mapped through the inverse of ``bvh.prim_ids``.  Spheres are not in the Embree scene:
scenes with spheres are refused.
"""
from __future__ import annotations

import numpy as np

from ..errors import UserError
from ..accel.embree import embree_scene
from .wavefront import Wavefront

# indices into Wavefront.buffers (the WAVE_PARAMS order of cl/scene.h)
RAY_O, RAY_D, RADIANCE = 10, 11, 13
HIT_T, HIT_PRIM, HIT_U, HIT_V = 18, 19, 20, 21
SH_O, SH_D, SH_CONTRIB = 22, 23, 24
COUNTER_SHADOW = 1


class EmbreeWavefront(Wavefront):
    """:class:`Wavefront` with closest-hit and shadow rays traced by Embree on the host."""

    def __init__(self, scene, device, **kwargs):
        if len(scene.spheres):
            raise UserError("--intersector embree: scenes with spheres are not supported (Embree gets triangles only)")
        super().__init__(scene, device, **kwargs)
        self.embree = embree_scene(self.bvh) if len(self.bvh.faces) else None
        self.to_bvh_index = np.empty(len(self.bvh.prim_ids), np.int32)
        self.to_bvh_index[np.asarray(self.bvh.prim_ids, np.int64)] = np.arange(len(self.bvh.prim_ids), dtype=np.int32)
        W = self.wave_size
        self._o = np.empty((W, 3), np.float32)
        self._d = np.empty((W, 3), np.float32)
        self._q = np.empty(W, np.int32)
        self._hit = {k: np.empty(W, t) for k, t in (("t", np.float32), ("prim", np.int32), ("u", np.float32), ("v", np.float32))}
        self._rad = np.empty((W, 3), np.float32)
        self._contrib = np.empty((W, 3), np.float32)
        self._count = np.zeros(2, np.int32)
        self.host_seconds = {"extend": 0.0, "shadow": 0.0}

    def extend(self, n_active, qin, qout):
        import time

        import pyopencl as cl

        t0 = time.perf_counter()
        queue = self.rt.queue
        q = self._q[:n_active]
        cl.enqueue_copy(queue, q, qin)  # blocking: waits for generate / the previous iteration
        cl.enqueue_copy(queue, self._o, self.buffers[RAY_O])
        cl.enqueue_copy(queue, self._d, self.buffers[RAY_D])
        o = np.ascontiguousarray(self._o[q])
        d = np.ascontiguousarray(self._d[q])
        h = self._hit
        if self.embree is not None and n_active:
            r = self.embree.run(o, d, output=1)
            prim = r["primID"]
            hit = prim >= 0
            h["t"][q] = np.where(hit, r["tfar"], np.inf)
            h["prim"][q] = np.where(hit, self.to_bvh_index[np.where(hit, prim, 0)], -1)
            h["u"][q] = np.where(hit, r["u"], 0.0)
            h["v"][q] = np.where(hit, r["v"], 0.0)
        else:
            h["t"][q], h["prim"][q], h["u"][q], h["v"][q] = np.inf, -1, 0.0, 0.0
        for k, idx in (("t", HIT_T), ("prim", HIT_PRIM), ("u", HIT_U), ("v", HIT_V)):
            cl.enqueue_copy(queue, self.buffers[idx], h[k])
        self.host_seconds["extend"] += time.perf_counter() - t0
        return None

    def shadow(self, n_active, qin, qout):
        import time

        import pyopencl as cl

        t0 = time.perf_counter()
        queue = self.rt.queue
        cl.enqueue_copy(queue, self._count, self.counters)  # after shade (in-order queue)
        n = int(self._count[COUNTER_SHADOW])
        if n == 0:
            self.host_seconds["shadow"] += time.perf_counter() - t0
            return None
        q = self._q[:n]
        cl.enqueue_copy(queue, q, self.shadow_q)
        cl.enqueue_copy(queue, self._o, self.buffers[SH_O])
        cl.enqueue_copy(queue, self._d, self.buffers[SH_D])
        if self.embree is not None:
            o = np.ascontiguousarray(self._o[q])
            d = np.ascontiguousarray(self._d[q])
            blocked = self.embree.run(o, d, dists=np.ones(n, np.float32), query="OCCLUDED") != -1
        else:
            blocked = np.zeros(n, bool)
        free = q[~blocked]
        if len(free):
            cl.enqueue_copy(queue, self._rad, self.buffers[RADIANCE])
            cl.enqueue_copy(queue, self._contrib, self.buffers[SH_CONTRIB])
            self._rad[free] += self._contrib[free]
            cl.enqueue_copy(queue, self.buffers[RADIANCE], self._rad)
        self.host_seconds["shadow"] += time.perf_counter() - t0
        return None
