"""The host side of the wavefront path tracer: buffers, the stage loop, the film.

One :class:`Wavefront` drives one device.  Each iteration of :meth:`Wavefront.run` enqueues
the five stages of ``cl/wavefront/`` and does one small blocking read (the queue counters); a
sample pass whose paths have all finished is read back and added to the film (float64, in pass
order, so the image is the same whatever order the atomics gave the queues).
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass, field

import numpy as np

from ..device import abi
from ..accel.bvh import build_bvh
from .film import STAGES, Film, RunStats
from .lights import build_lights, environment_buffers, light_features
from ..scene.model import INTEGRATORS, Scene

SOURCES = tuple(f"wavefront/{s}.cl" for s in STAGES)
LOCAL_SIZE = 64
N_COUNTERS = 8  # counters[] slots before the pass-completion counts (see cl/scene.h)

# Wave sizes: large on a GPU to fill it; on a CPU large enough to amortise the launches and
# small enough that the path state stays in cache (measured with `pyopencl-rt bench wave`).
DEFAULT_WAVE_GPU = 1 << 20
DEFAULT_WAVE_CPU = 1 << 16


def default_wave_size(device) -> int:
    import pyopencl as cl

    return DEFAULT_WAVE_GPU if device.type & cl.device_type.GPU else DEFAULT_WAVE_CPU


def scene_features(scene: Scene, n_lights: int, integrator: str) -> dict:
    """Preprocessor defines: only what the scene uses is compiled."""
    if integrator not in INTEGRATORS:
        raise ValueError(f"integrator must be one of {INTEGRATORS}")
    defines = {"INTEGRATOR": INTEGRATORS.index(integrator), "WAVE_LOCAL_SIZE": LOCAL_SIZE}
    if len(scene.faces):
        defines["HAS_TRIANGLES"] = True
    if len(scene.spheres):
        defines["HAS_SPHERES"] = True
    if n_lights:
        defines["HAS_LIGHTS"] = True
    defines.update(scene.material_defines())  # only the material types the scene uses
    return defines


class Wavefront:
    """A scene loaded on one device, ready to render passes."""

    def __init__(self, scene: Scene, device, *, width=None, height=None, integrator=None, max_depth=None,
                 rr_depth=None, seed=None, wave_size=None, bvh=None):
        import pyopencl as cl

        from ..device.kernels import runtime
        from ..accel.device_bvh import bvh_layout, layout_defines

        st = scene.settings
        self.scene = scene
        self.device = device
        self.width = int(width or st.width)
        self.height = int(height or st.height)
        self.integrator = integrator or st.integrator
        self.max_depth = int(st.max_depth if max_depth is None else max_depth)
        self.rr_depth = int(st.rr_depth if rr_depth is None else rr_depth)
        self.seed = int(st.seed if seed is None else seed) & 0xFFFFFFFF
        self.n_pixels = self.width * self.height
        self.wave_size = int(wave_size or default_wave_size(device))
        self.timings = {}

        t0 = time.perf_counter()
        if bvh is None:  # a BVH passed in was built by the caller from scene.camera_relative()
            scene = scene.camera_relative()
            self.scene = scene
        self.bvh = bvh if bvh is not None else build_bvh(scene.vertices, scene.faces)
        self.timings["bvh_seconds"] = time.perf_counter() - t0
        lights, tri_light, sphere_light = build_lights(scene, self.bvh)
        self.n_lights = len(lights)
        self.features = scene_features(scene, self.n_lights, self.integrator)
        self.features.update(light_features(lights))  # point/directional/environment code, if used
        if self.n_lights == 0:
            import warnings

            warnings.warn("scene has no lights: the image will be black", stacklevel=2)
        self.bvh_layout = bvh_layout(device)  # wide (cl/bvh_wide.h) on CPUs; $PYOPENCL_RT_BVH_LAYOUT overrides
        self.features.update(layout_defines(self.bvh_layout))

        self.rt = runtime(device)
        t0 = time.perf_counter()
        prog = self.rt.program(SOURCES, self.features)
        self.kernels = {s: cl.Kernel(prog, f"wf_{s}") for s in STAGES}
        self.timings["build_seconds"] = time.perf_counter() - t0

        ctx = self.rt.context
        mf = cl.mem_flags

        def const(a):
            a = np.ascontiguousarray(a)
            if a.nbytes == 0:
                a = np.zeros(16, np.uint8)
            return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)

        def scratch(nbytes):
            return cl.Buffer(ctx, mf.READ_WRITE, max(int(nbytes), 16))

        from ..accel.device_bvh import node_buffer

        prim = self.bvh.prim_ids
        tri_material = scene.face_materials[prim].astype(np.int32) if len(prim) else np.zeros(0, np.int32)
        cam = scene.camera.record(self.width, self.height)
        W, P = self.wave_size, self.n_pixels
        # enough ring slots for every pass a full wave can span, plus the one draining
        self.ring_size = int(min(max(2, math.ceil(W / P) + 2), 1 << 12))
        f4, i4 = 4, 4
        self.buffers = [
            const(node_buffer(self.bvh, self.bvh_layout)), const(self.bvh.triangles), const(tri_material), const(tri_light),
            const(scene.sphere_records()), const(scene.sphere_materials.astype(np.int32)),
            const(sphere_light), const(scene.material_records()), const(lights), const(cam),
            scratch(3 * f4 * W), scratch(3 * f4 * W), scratch(3 * f4 * W), scratch(3 * f4 * W),  # ray o/d, beta, L
            scratch(i4 * W), scratch(i4 * W), scratch(i4 * W), scratch(f4 * W),  # pixel, pass, depth, pdf
            scratch(f4 * W), scratch(i4 * W), scratch(f4 * W), scratch(f4 * W),  # hit t/prim/u/v
            scratch(3 * f4 * W), scratch(3 * f4 * W), scratch(3 * f4 * W),  # shadow o/d/contrib
            *self._texture_buffers(const, scratch, W),  # tri_uv, textures, tex_data, mat_scratch
        ]
        self.queue_a, self.queue_b = scratch(i4 * W), scratch(i4 * W)
        self.shadow_q, self.term_q = scratch(i4 * W), scratch(i4 * W)
        self.free_q = cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=np.arange(W, dtype=np.int32))
        self.counters_host = np.zeros(N_COUNTERS + self.ring_size, np.int32)
        self.counters = cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=self.counters_host)
        self.pass_ring = scratch(3 * f4 * P * self.ring_size)
        self.env_buffers = [const(a) for a in environment_buffers(scene)]  # env_map, env_cdf (kept alive here)
        fixed = self.buffers + [None, None, self.shadow_q, self.term_q, self.free_q, self.counters, self.pass_ring,
                                *self.env_buffers,
                                np.int32(len(scene.spheres)), np.int32(self.n_lights), np.int32(P),
                                np.int32(self.ring_size), np.int32(self.max_depth), np.int32(self.rr_depth),
                                np.uint32(self.seed)]
        self._queue_arg = len(self.buffers)  # index of queue_in; queue_out follows
        self._scalar_arg = len(fixed)
        for k in self.kernels.values():
            for idx, a in enumerate(fixed):
                if a is not None:
                    k.set_arg(idx, a)
        # host-side state of the wave, carried across run() calls
        self.n_active = 0
        self.n_free = W
        self.next_sample = 0  # linear index pass * P + pixel of the next sample to start
        self.oldest_pass = 0  # the first pass not yet added to the film

    def _texture_buffers(self, const, scratch, W):
        """tri_uv (3 UVs per reordered triangle), the TEXTURE table, the float4 texels and the
        per-slot scratch Material (cl/textures.h); 16-byte dummies when the scene has no textures."""
        if not self.scene.has_textures():
            return [const(np.zeros(0, np.uint8)) for _ in range(3)] + [scratch(0)]
        from ..scene.textures import pack_textures

        uv = self.scene.face_uvs()[self.bvh.prim_ids].reshape(-1, 2)
        table, texels = pack_textures(self.scene.textures())
        return [const(uv), const(table), const(texels), scratch(abi.MATERIAL.itemsize * W)]

    # -- one stage launch ------------------------------------------------------------------
    def _launch(self, stage, count, qin, qout, a0=0, a1=0, a2=0, a3=0, a4=0):
        import pyopencl as cl

        k = self.kernels[stage]
        k.set_arg(self._queue_arg, qin)
        k.set_arg(self._queue_arg + 1, qout)
        for j, v in enumerate((a0, a1, a2, a3, a4)):
            k.set_arg(self._scalar_arg + j, np.int32(v))
        # A fixed work-group size: PoCL compiles a work-group function per local size, so letting
        # it choose one per launch (global sizes vary every iteration) recompiled constantly.
        size = max(LOCAL_SIZE, (count + LOCAL_SIZE - 1) // LOCAL_SIZE * LOCAL_SIZE)
        return cl.enqueue_nd_range_kernel(self.rt.queue, k, (size,), (LOCAL_SIZE,))

    # -- the two ray-casting stages, overridable (e.g. by an Embree-backed subclass) -----------
    def extend(self, n_active: int, qin, qout):
        """Closest hit for the n_active paths of queue qin into hit_t/prim/u/v. Returns an event
        (or None when the work was done synchronously on the host)."""
        return self._launch("extend", n_active, qin, qout, n_active)

    def shadow(self, n_active: int, qin, qout):
        """Any-hit test of the counters[COUNTER_SHADOW] queued shadow rays (at most n_active)."""
        return self._launch("shadow", n_active, qin, qout)

    def run(self, film: Film, passes: int | None = None, time_limit: float | None = None,
            progress=None, profile: bool = False, first_pass: int = 0, cancel=None) -> RunStats:
        """Render passes [first_pass, first_pass + passes) (or until time_limit seconds) into film.

        Returns when every started pass is complete; on KeyboardInterrupt the passes in flight are
        dropped and what is complete stays in the film (stats.interrupted is set).  ``cancel``, a
        callable checked once per iteration (between whole passes' film updates), does the same
        when it returns true: signal handlers and other threads stop a render at a safe point.
        """
        import pyopencl as cl

        if passes is None and time_limit is None:
            raise ValueError("give passes, time_limit or both")
        P = self.n_pixels
        queue = self.rt.queue
        stats = RunStats()
        self.next_sample = first_pass * P
        self.oldest_pass = first_pass
        end_sample = (first_pass + passes) * P if passes is not None else None
        start = time.perf_counter()
        qin, qout = self.queue_a, self.queue_b
        zeros3 = np.zeros(3, np.int32)
        ring_host = np.empty((P, 3), np.float32)
        events = []
        try:
            while True:
                if cancel is not None and cancel():
                    raise KeyboardInterrupt
                now = time.perf_counter() - start
                if time_limit is not None and now >= time_limit and end_sample is None or (
                    time_limit is not None and now >= time_limit and self.next_sample < (end_sample or 0)
                ):
                    # time is up: finish the passes already started, start no new one
                    end_sample = -(-self.next_sample // P) * P
                limit = (self.oldest_pass + self.ring_size) * P
                if end_sample is not None:
                    limit = min(limit, end_sample)
                n_gen = int(min(self.n_free, max(0, limit - self.next_sample)))
                if n_gen:
                    ev = self._launch("generate", n_gen, qin, qout, n_gen, self.next_sample // P,
                                      self.next_sample % P, self.n_active, self.n_free)
                    events.append(("generate", ev))
                    self.n_active += n_gen
                    self.n_free -= n_gen
                    self.next_sample += n_gen
                if self.n_active == 0:
                    if end_sample is not None and self.next_sample >= end_sample:
                        break
                    continue
                cl.enqueue_copy(queue, self.counters, zeros3)
                n = self.n_active
                events.append(("extend", self.extend(n, qin, qout)))
                events.append(("shade", self._launch("shade", n, qin, qout, n)))
                events.append(("shadow", self.shadow(n, qin, qout)))
                events.append(("accumulate", self._launch("accumulate", n, qin, qout, 0, 0, 0, 0, self.n_free)))
                cl.enqueue_copy(queue, self.counters_host, self.counters)  # blocking: the only sync
                c = self.counters_host
                stats.iterations += 1
                stats.rays_extend += n
                stats.rays_shadow += int(c[1])
                self.n_free += int(c[2])
                self.n_active = int(c[0])
                qin, qout = qout, qin
                if profile:
                    for name, ev in events:
                        if ev is not None:
                            stats.stage_seconds[name] += (ev.profile.end - ev.profile.start) * 1e-9
                events.clear()
                # completed passes, in order, into the film
                while c[N_COUNTERS + self.oldest_pass % self.ring_size] == P:
                    ring = self.oldest_pass % self.ring_size
                    cl.enqueue_copy(queue, ring_host, self.pass_ring, src_offset=ring * P * 12)
                    cl.enqueue_copy(queue, self.counters, np.zeros(1, np.int32),
                                    dst_offset=(N_COUNTERS + ring) * 4)
                    c[N_COUNTERS + ring] = 0
                    film.add_pass(ring_host)
                    self.oldest_pass += 1
                    stats.passes += 1
                    if progress is not None:
                        progress(stats.passes, time.perf_counter() - start)
        except KeyboardInterrupt:
            stats.interrupted = True
            self._reset_wave()
        queue.finish()
        cl.enqueue_copy(queue, self.counters_host, self.counters)
        stats.nonfinite = int(self.counters_host[3])
        stats.samples = stats.passes * P
        stats.seconds = time.perf_counter() - start
        return stats

    def _reset_wave(self):
        """Forget the paths in flight (after an interrupt): every slot free, counters zero."""
        import pyopencl as cl

        queue = self.rt.queue
        queue.finish()
        W = self.wave_size
        cl.enqueue_copy(queue, self.free_q, np.arange(W, dtype=np.int32))
        nonfinite = self.counters_host[3]
        self.counters_host[:] = 0
        self.counters_host[3] = nonfinite
        cl.enqueue_copy(queue, self.counters, self.counters_host)
        self.n_active, self.n_free = 0, W
