"""The host side of the wavefront path tracer: buffers, the stage loop, the film.

One :class:`Wavefront` drives one device.  Each iteration of :meth:`Wavefront.run` enqueues
the five stages of ``cl/wavefront/`` and does one small blocking read (the queue counters); a
sample pass whose paths have all finished is read back and added to the film (float64, in pass
order, so the image is the same whatever order the atomics gave the queues).
"""
from __future__ import annotations

import math
import numbers
import time
from dataclasses import dataclass, field

import numpy as np

from .. import validate
from ..errors import UsageError
from ..device import abi
from ..device.host_memory import aligned
from ..host_stages import host_stage
from ..scene.instances import scene_bvh
from ..accel.shape_bvh import build_shape_bvh
from ..scene.shapes import bounds as shape_bounds
from . import filters
from .film import Film, RunStats
from .kernel_build import KernelBuild
from .lights import build_lights, environment_buffers
from .settings import (ImageSettings, environment_row, feature_names, has_light_tree, kernel_features,
                       max_component_value)
from ..scene.model import INTEGRATORS, Scene

STAGES = ("generate", "extend", "shade", "shadow", "accumulate")  # cl/wavefront/<stage>.cl, kernel wf_<stage>
SOURCES = tuple(f"wavefront/{s}.cl" for s in STAGES)
LOCAL_SIZE = abi.WAVE_LOCAL_SIZE
# the per-stage scalars of abi.WAVE_PARAMS, set (0 unless given) at every launch
STAGE_SCALARS = tuple(p.name for p in abi.WAVE_PARAMS if p.launch and p.kind == "scalar")

# Wave sizes: large on a GPU to fill it; on a CPU large enough to amortise the launches and
# small enough that the path state stays in cache (measured with `pyopencl-rt bench wave`).
DEFAULT_WAVE_GPU = 1 << 20
DEFAULT_WAVE_CPU = 1 << 16
# The megakernel keeps no path state in memory, so its wave is only how many samples one launch
# renders: 4x the wavefront's amortises the host's wait for each launch and its last groups'
# tail (+7% samples/s at 256 x 256, tools/kernel_ab.py; docs/BENCHMARKS.md).
DEFAULT_WAVE_MEGAKERNEL = 1 << 18


def check_pass_range(first_pass, passes) -> None:
    """Passes [first_pass, first_pass + passes): whole numbers, never negative (a negative first
    pass would index the pass ring out of bounds)."""
    if isinstance(first_pass, bool) or not isinstance(first_pass, numbers.Integral) or first_pass < 0:
        raise ValueError(f"first_pass must be an integer >= 0, got {first_pass!r}")
    if passes is not None and (isinstance(passes, bool) or not isinstance(passes, numbers.Integral) or passes < 0):
        raise ValueError(f"passes must be an integer >= 0 or None, got {passes!r}")


def default_wave_size(device, kernel_mode: str = "wavefront") -> int:
    import pyopencl as cl

    if device.type & cl.device_type.GPU:
        return DEFAULT_WAVE_GPU
    return DEFAULT_WAVE_MEGAKERNEL if kernel_mode == "megakernel" else DEFAULT_WAVE_CPU


MAX_WAVE_SIZE = 1 << 26  # paths in flight; the device's memory is checked too (check_wave_memory)


def wave_bytes(wave_size: int) -> tuple[int, int]:
    """(total, largest single buffer) bytes of a wave's path state and queues (abi.WAVE_PARAMS)."""
    sizes = [p.per_slot * p.itemsize * wave_size for p in abi.WAVE_PARAMS if p.per_slot]
    sizes += [4 * wave_size] * 3  # the two queues that swap and the free list
    return sum(sizes), max(sizes)


def check_wave_memory(device, wave_size: int) -> None:
    """Refuse a wave whose path state does not fit the device (before any buffer is made)."""
    total, largest = wave_bytes(wave_size)
    mem, alloc = int(device.global_mem_size), int(device.max_mem_alloc_size)
    if total > 0.75 * mem or largest > alloc:
        from ..device.devices import device_label

        raise UsageError(f"--wave-size {wave_size} needs {total / 2**30:.2f} GiB of path state; "
                         f"{device_label(device)} has {mem / 2**30:.2f} GiB "
                         f"(at most {alloc / 2**30:.2f} GiB per buffer): use a smaller wave")


class Wavefront:
    """A scene loaded on one device, ready to render passes.

    ``settings`` (an :class:`~pyopencl_rt.render.settings.ImageSettings`) fixes the image; without
    it the scene's own settings are used, with ``overrides`` (width=, seed=, ...) taking precedence.
    ``intersector`` traces the extend and shadow rays (:mod:`pyopencl_rt.render.intersectors`):
    a name ("opencl", "embree") or an :class:`~pyopencl_rt.render.intersectors.Intersector`.
    ``kernel_mode`` ("auto", "wavefront", "megakernel"): how the paths are scheduled
    (:mod:`pyopencl_rt.render.megakernel`); the image is the same either way.
    """

    def __init__(self, scene: Scene, device, settings: ImageSettings | None = None, *, wave_size=None, bvh=None,
                 intersector="opencl", kernel_mode=None, **overrides):
        import pyopencl as cl

        from ..accel.device_bvh import bvh_layout
        from ..device.kernel_args import KernelArgs
        from ..device.kernels import runtime
        from . import megakernel
        from .intersectors import make_intersector

        if settings is None:
            settings = ImageSettings.resolve(scene, **overrides)
        elif overrides:
            raise TypeError(f"give either settings or overrides, not both ({', '.join(overrides)})")
        self.settings = settings
        self.intersector = make_intersector(intersector)
        if (self.intersector.name != "opencl" or scene.has_media()) and bvh is None:
            from ..scene.instances import flattened

            # Embree, and the volumetric integrator (no instance step), trace one copy per instance
            scene = flattened(scene)
        self.intersector.check(scene)
        self.scene = scene
        self.device = device
        if wave_size is not None:
            check_wave_memory(device, validate.integer(wave_size, "--wave-size", minimum=1, maximum=MAX_WAVE_SIZE))
        self.timings = {}

        t0 = time.perf_counter()
        if bvh is None:  # a BVH passed in was built by the caller from scene.camera_relative()
            scene = scene.camera_relative()
            self.scene = scene
        with host_stage("bvh"):
            self.bvh = bvh if bvh is not None else scene_bvh(scene)  # two-level with blas_groups
        self.timings["bvh_seconds"] = time.perf_counter() - t0
        with host_stage("lights"):
            lights, tri_light, shape_light, light_nodes = build_lights(scene, self.bvh)
        self.n_lights = len(lights)
        self.light_tree = has_light_tree(lights)
        if self.n_lights == 0:
            import warnings

            warnings.warn("scene has no lights: the image will be black", stacklevel=2)
        self.bvh_layout = bvh_layout(device)  # wide (cl/accel/bvh_wide.h) on CPUs; $PYOPENCL_RT_BVH_LAYOUT overrides
        self.features = kernel_features(scene, settings, lights, self.bvh_layout)
        self.kernel_mode = megakernel.kernel_mode(device, self.intersector.name, getattr(settings, "film_aovs", None),
                                                  kernel_mode, media="HAS_MEDIA" in self.features)
        self.wave_size = int(wave_size or default_wave_size(device, self.kernel_mode))

        self.rt = runtime(device)
        # the kernels build (or come from PoCL's cache) on a thread of their own while this one
        # collapses the BVH and makes the buffers: PoCL's compiler releases the GIL (issue 35)
        building = KernelBuild(self, device, SOURCES, STAGES)
        try:
            from ..accel.device_bvh import LAYOUT_WIDTHS, node_buffer

            ctx = self.rt.context
            mf = cl.mem_flags
            # a CPU device reads the host's arrays where they are (device/host_memory.py; the arrays
            # are kept with the buffers); a GPU gets its own copy
            on_host = bool(device.type & cl.device_type.CPU)
            self._host_arrays = []

            def const(a):
                a = np.ascontiguousarray(a)
                if a.nbytes == 0:
                    a = np.zeros(16, np.uint8)
                if on_host:  # the scene's own arrays among them: a scene is not changed under a render
                    a = aligned(a)
                    self._host_arrays.append(a)
                    return cl.Buffer(ctx, mf.READ_ONLY | mf.USE_HOST_PTR, hostbuf=a)
                return cl.Buffer(ctx, mf.READ_ONLY | mf.COPY_HOST_PTR, hostbuf=a)

            def filled(shape, dtype, fill):
                """A read-only buffer of ``shape``, written by ``fill(array)`` through a mapping: no host
                array beside the device's (the largest per-triangle buffers of a big scene)."""
                nbytes = int(np.prod(shape)) * np.dtype(dtype).itemsize
                if nbytes == 0:
                    return const(np.zeros(0, np.uint8))
                buf = cl.Buffer(ctx, mf.READ_ONLY, nbytes)
                mapped, _ = cl.enqueue_map_buffer(self.rt.queue, buf, cl.map_flags.WRITE_INVALIDATE_REGION, 0, shape,
                                                  dtype)
                try:
                    fill(mapped)
                finally:
                    mapped.base.release(self.rt.queue)
                return buf

            # the triangle records (48 bytes a triangle) are what the binary layout's traversal reads;
            # the wide layouts' packets hold the vertices themselves (gathered from the mesh), and
            # shading reads the mesh (vertices, faces, prim_ids: MESH_PARAMS in cl/scene/scene.h): our own
            # BVH's records go before the packets are made (build_lights has read them)
            binary = LAYOUT_WIDTHS[self.bvh_layout] == 2
            own = bvh is None and not hasattr(self.bvh, "world")
            if own and not binary:
                self.bvh.triangles = None
            with host_stage("bvh_collapse"):  # the device's node layout (8-wide on CPUs)
                # our own BVH's binary records go as the collapse reads them (consume)
                nodes = node_buffer(getattr(self.bvh, "world", self.bvh), self.bvh_layout, consume=own)
            if bvh is None:  # the wide BVH cached on a BVH of our own: in the blob now
                getattr(self.bvh, "world", self.bvh).__dict__.pop("_wide", None)
            if own:  # its binary records are in the node buffer now (padded or collapsed): not read again
                self.bvh.nodes = None
            upload_stage = host_stage("upload")  # every buffer made and copied (the scene's, the wave's)
            upload_stage.__enter__()
            nodes = const(nodes)
            tris = const(self.bvh.triangles if binary else np.zeros(0, np.uint8))
            if own:  # the records (binary) are the device's now: the host does not read them again
                self.bvh.triangles = None

            def scratch(nbytes):
                return cl.Buffer(ctx, mf.READ_WRITE, max(int(nbytes), 16))

            prim = self.bvh.prim_ids
            face_materials = np.asarray(scene.face_materials, np.int32)
            tri_material = filled(prim.shape, np.int32, lambda out: np.take(face_materials, prim, out=out, mode="clip"))
            cam = scene.camera.record(self.width, self.height)
            filter_cdf = filters.apply(cam, settings.filter)  # the pixel filter's fields and tables
            W, P = self.wave_size, self.n_pixels
            # enough ring slots for every pass a full wave can span, plus the one draining
            self.ring_size = int(min(max(2, math.ceil(W / P) + 2), 1 << 12))
            self.counters_host = np.zeros(abi.COUNTER_PASS_DONE + self.ring_size, np.int32)
            # MIS compensation of the environment's light sampling where MIS combines it with BSDF
            # sampling: light sampling alone ("nee") needs the complete density
            env_map, env_cdf = environment_buffers(scene, compensated=self.settings.integrator == "path")
            buffers = dict(
                nodes=nodes,
                tris=tris, **self._instance_buffers(const), **self._mesh_buffers(const),
                tri_material=tri_material, tri_light=const(tri_light), shapes=const(scene.shapes),
                shape_nodes=const(build_shape_bvh(*shape_bounds(scene.shapes))),
                shape_material=const(scene.shape_materials.astype(np.int32)), shape_light=const(shape_light),
                materials=const(scene.material_records()), lights=const(lights), camera=const(cam),
                camera_motion=const(camera_motion_record(scene)),
                light_nodes=const(light_nodes if len(light_nodes) else np.zeros(1, abi.LIGHT_NODE)),
                **self._texture_buffers(const), **self._shading_buffers(const, filled),
                **self._aov_buffers(scratch, W, P),
                **self._media_buffers(const), **self._media_path_buffers(const),
                free_q=cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=np.arange(W, dtype=np.int32)),
                counters=cl.Buffer(ctx, mf.READ_WRITE | mf.COPY_HOST_PTR, hostbuf=self.counters_host),
                pass_ring=scratch(3 * 4 * P * self.ring_size), env_map=const(env_map), env_cdf=const(env_cdf),
                filter_cdf=const(filter_cdf),
                pixel_list=scratch(4 * P),  # filled by run(pixels=) (adaptive sampling)
                n_lights=self.n_lights, n_pixels=P, ring_size=self.ring_size,
                max_depth=self.settings.max_depth, rr_depth=self.settings.rr_depth, seed=self.settings.seed,
                integrator=INTEGRATORS.index(self.settings.integrator), env_light=environment_row(lights),
                sampler=abi.SAMPLERS[self.settings.sampler], max_component=max_component_value(scene),
                light_tree=int(self.light_tree),
            )
        except BaseException:
            building.wait()  # PoCL is not left compiling under a failed render
            raise
        upload_stage.__exit__(None, None, None)
        with host_stage("kernel_wait"):  # what of the build the collapse and the buffers did not hide
            building.join()  # the kernels, their width and their defines
        upload_stage = host_stage("upload")
        upload_stage.__enter__()
        # arguments by parameter name (abi.WAVE_PARAMS), set once on every stage
        self.args = KernelArgs(self.kernels)
        self.args.bind(**buffers)
        # the rest of the path state and queues, sized by the table, written by the kernels first
        # (the megakernel keeps them in registers: it gets placeholders)
        per_slot = 0 if self.kernel_mode == "megakernel" else W
        self.args.bind(**{p.name: scratch(p.per_slot * p.itemsize * per_slot) for p in abi.WAVE_PARAMS
                          if p.per_slot and not p.launch and p.name not in self.args.values})
        queue_bytes = abi.WAVE_PARAM["queue_in"].itemsize * W
        self.queue_a, self.queue_b = scratch(queue_bytes), scratch(queue_bytes)  # queue_in/out, swapped
        unbound = set(self.args.unbound()) - {p.name for p in abi.WAVE_PARAMS if p.launch}
        if unbound:
            raise AssertionError(f"wavefront parameters never bound: {sorted(unbound)}")
        del nodes, tris
        upload_stage.__exit__(None, None, None)
        # host-side state of the wave, carried across run() calls
        self.n_active = 0
        self.n_free = W
        self.next_sample = 0  # linear index pass * P + pixel of the next sample to start
        self.oldest_pass = 0  # the first pass not yet added to the film

    def reseed(self, seed: int) -> None:
        """Render the following passes with ``seed`` (the 32-bit key of the samplers and RNG): the
        images of a Wavefront built with that seed, without building one (the convergence
        benchmark averages its curves over seeds).  Between runs only: every run returns drained."""
        from dataclasses import replace

        self.settings = replace(self.settings, seed=validate.seed(seed))
        self.args.bind(seed=self.settings.seed)

    def description(self) -> dict:
        """What the sidecar records of this engine (a Dask worker sends the same back)."""
        return {
            "wave_size": self.wave_size,
            "intersector": self.intersector.name,
            "kernel_mode": self.kernel_mode,
            "lanes": self.lane_width,  # paths per work-item of the lane megakernel (0: one)
            "lanes_reason": self.lane_reason,  # why that width (pyopencl_rt/device/isa.py)
            "features": feature_names(self.features),
            "lights": self.n_lights,
            "light_tree": self.light_tree,  # lights picked by the light BVH (light_sampler "bvh")
            "bvh_seconds": self.timings.get("bvh_seconds"),
            "kernel_build_seconds": self.timings.get("build_seconds"),
        }

    @property
    def width(self) -> int:
        return self.settings.width

    @property
    def height(self) -> int:
        return self.settings.height

    @property
    def n_pixels(self) -> int:
        return self.settings.n_pixels

    def _instance_buffers(self, const) -> dict:
        """tlas, instances, blas_nodes (cl/accel/instances.h); 16-byte dummies without two-level instances."""
        if not hasattr(self.bvh, "world"):
            return dict.fromkeys(("tlas", "instances", "blas_nodes", "instance_motion"), const(np.zeros(16, np.uint8)))
        return {k: const(a) for k, a in self.bvh.buffers(self.bvh_layout).items()}

    def _mesh_buffers(self, const) -> dict:
        """vertices, faces, prim_ids (MESH_PARAMS, cl/scene/scene.h): what shading reads of a
        triangle, the scene's own arrays (read in place by a CPU device)."""
        return {"vertices": const(np.asarray(self.scene.vertices, np.float32).reshape(-1)),
                "faces": const(np.asarray(self.scene.faces, np.int32).reshape(-1)),
                "prim_ids": const(np.asarray(self.bvh.prim_ids, np.int32))}

    def _texture_buffers(self, const) -> dict:
        """tri_uv, textures and tex_data (cl/scene/textures.h); 16-byte dummies when the scene has
        no textures (tri_uv is kept for the tangent of anisotropic materials)."""
        if not self.scene.has_textures():
            dummy = const(np.zeros(0, np.uint8))
            uv = dummy
            if self.scene.has_anisotropy() and len(self.scene.faces):  # the tangent's dp/du (shading.h)
                uv = const(self.scene.face_uvs()[self.bvh.prim_ids].reshape(-1, 2))
            return {"tri_uv": uv, "textures": dummy, "tex_data": dummy}
        from ..scene.textures import pack_textures

        uv = self.scene.face_uvs()[self.bvh.prim_ids].reshape(-1, 2)
        table, texels = pack_textures(self.scene.textures(), self.scene.world_origin)
        return {"tri_uv": const(uv), "textures": const(table), "tex_data": const(texels)}

    def _shading_buffers(self, const, filled) -> dict:
        """face_normal (cl/scene/shading.h): each face's three unit corner normals in the scene's
        order (the scene's own array where it holds them already: Scene.normals_unit), and
        tri_color: each reordered triangle's corner colours, 9 floats each; 16-byte dummies when no
        kernel reads them."""
        dummy = const(np.zeros(0, np.uint8))
        prim = self.bvh.prim_ids
        normals = dummy
        if "HAS_SHADING_NORMALS" in self.features:
            scene = self.scene
            if scene.normals_unit and not scene.normals_as_given:
                normals = const(np.asarray(scene.normals, np.float32).reshape(-1))
            else:
                normals = filled((len(scene.faces), 3, 3), np.float32, lambda out: scene.face_normals(out=out))
        colors = const(self.scene.face_colors()[prim]) if "HAS_VERTEX_COLORS" in self.features else dummy
        return {"face_normal": normals, "tri_color": colors}

    def _media_buffers(self, const) -> dict:
        """abi.MEDIA_PARAMS' scene buffers (scene/media.py:pack_media, tri_interface in the BVH's triangle
        order); 16-byte dummies and camera_medium -1 when the scene has no media."""
        if "HAS_MEDIA" not in self.features:
            dummy = const(np.zeros(0, np.uint8))
            return {**{p.name: dummy for p in abi.MEDIA_PARAMS if p.kind != "scalar" and not p.per_slot},
                    "camera_medium": -1, "spectral_mis": 0}
        from ..scene.media import pack_media

        packed = pack_media(self.scene)
        packed["tri_interface"] = packed["tri_interface"][self.bvh.prim_ids]
        return {k: v if k in ("camera_medium", "spectral_mis") else const(v) for k, v in packed.items()}

    def _media_path_buffers(self, const) -> dict:
        """Dummies for the per-path media state (abi.MEDIA_PARAMS' per-slot buffers) where no kernel keeps it
        in memory: a scene without media, or the megakernel; the wavefront with media gets them sized by the
        table, as the rest of the path state."""
        if "HAS_MEDIA" in self.features and self.kernel_mode == "wavefront":
            return {}
        dummy = const(np.zeros(0, np.uint8))
        return {p.name: dummy for p in abi.MEDIA_PARAMS if p.per_slot}

    def _aov_buffers(self, scratch, W, P) -> dict:
        """aov_path and aov_ring (cl/render/aov.h) when the settings ask for AOVs, else dummies."""
        n = abi.AOV_FLOATS * 4 if self.settings.film_aovs else 0
        return {"aov_path": scratch(n * W), "aov_ring": scratch(n * P * self.ring_size)}

    def buffer(self, name: str):
        """The buffer bound to the wavefront kernels' parameter ``name`` (abi.WAVE_PARAMS)."""
        return self.args[name]

    @staticmethod
    def counter_slot(name: str) -> int:
        """The counters[] slot of a queue counter: "queue_out", "shadow", "term" or "nonfinite"."""
        return abi.COUNTERS[name]

    # -- one stage launch ------------------------------------------------------------------
    def launch(self, stage, count, queue_in, queue_out, **scalars):
        """Enqueue ``stage`` on ``count`` work-items with the given per-stage scalars (by name,
        :data:`STAGE_SCALARS`; the others are 0)."""
        import pyopencl as cl

        self.args.set(stage, queue_in=queue_in, queue_out=queue_out, **(dict.fromkeys(STAGE_SCALARS, 0) | scalars))
        # A fixed work-group size: PoCL compiles a work-group function per local size, so letting
        # it choose one per launch (global sizes vary every iteration) recompiled constantly.
        size = max(LOCAL_SIZE, (count + LOCAL_SIZE - 1) // LOCAL_SIZE * LOCAL_SIZE)
        return cl.enqueue_nd_range_kernel(self.rt.queue, self.kernels[stage], (size,), (LOCAL_SIZE,))

    def run(self, film: Film, passes: int | None = None, time_limit: float | None = None,
            progress=None, profile: bool = False, first_pass: int = 0, cancel=None, pixels=None) -> RunStats:
        """Render passes [first_pass, first_pass + passes) (or until time_limit seconds) into film.

        ``pixels`` (adaptive sampling, :mod:`pyopencl_rt.render.adaptive`): the passes cover only
        these pixels (distinct indices), each added to the film with ``add_pass(..., pixels=)``.

        Returns when every started pass is complete; on KeyboardInterrupt the passes in flight are
        dropped and what is complete stays in the film (stats.interrupted is set).  ``cancel``, a
        callable checked once per iteration (between whole passes' film updates), does the same
        when it returns true: signal handlers and other threads stop a render at a safe point.
        """
        import pyopencl as cl

        check_pass_range(first_pass, passes)
        pixels = self._upload_pixels(pixels)
        if self.kernel_mode == "megakernel":
            from . import megakernel

            return megakernel.run(self, film, passes, time_limit, progress, profile, first_pass, cancel, pixels)
        if passes is None and time_limit is None:
            raise ValueError("give passes, time_limit or both")
        P = self.n_pixels if pixels is None else len(pixels)  # samples of a pass
        n_listed = 0 if pixels is None else P
        queue = self.rt.queue
        stats = RunStats(stage_seconds=dict.fromkeys(STAGES, 0.0))
        host_before = dict(self.intersector.host_seconds)
        self.next_sample = first_pass * P
        self.oldest_pass = first_pass
        end_sample = (first_pass + passes) * P if passes is not None else None
        start = time.perf_counter()
        qin, qout = self.queue_a, self.queue_b
        counters = self.buffer("counters")
        iteration_zeros = np.zeros(abi.ITERATION_COUNTERS, np.int32)
        ring_host = np.empty((self.n_pixels, 3), np.float32)
        aov_host = np.empty((self.n_pixels, abi.AOV_FLOATS), np.float32) if self.settings.film_aovs else None
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
                    ev = self.launch("generate", n_gen, qin, qout, n_items=n_gen, first_pass=self.next_sample // P,
                                     first_pixel=self.next_sample % P, queue_base=self.n_active,
                                     free_base=self.n_free, n_listed=n_listed)
                    events.append(("generate", ev))
                    self.n_active += n_gen
                    self.n_free -= n_gen
                    self.next_sample += n_gen
                if self.n_active == 0:
                    if end_sample is not None and self.next_sample >= end_sample:
                        break
                    continue
                cl.enqueue_copy(queue, counters, iteration_zeros)
                n = self.n_active
                events.append(("extend", self.intersector.extend(self, n, qin, qout)))
                events.append(("shade", self.launch("shade", n, qin, qout, n_items=n)))
                events.append(("shadow", self.intersector.shadow(self, n, qin, qout)))
                events.append(("accumulate", self.launch("accumulate", n, qin, qout, free_base=self.n_free)))
                cl.enqueue_copy(queue, self.counters_host, counters)  # blocking: the only sync
                c = self.counters_host
                stats.iterations += 1
                stats.rays_extend += n
                stats.rays_shadow += int(c[abi.COUNTER_SHADOW])
                self.n_free += int(c[abi.COUNTER_TERM])
                self.n_active = int(c[abi.COUNTER_QUEUE_OUT])
                qin, qout = qout, qin
                if profile:
                    for name, ev in events:
                        if ev is not None:
                            stats.stage_seconds[name] += (ev.profile.end - ev.profile.start) * 1e-9
                events.clear()
                # completed passes, in order, into the film
                while c[abi.COUNTER_PASS_DONE + self.oldest_pass % self.ring_size] == P:
                    ring = self.oldest_pass % self.ring_size
                    cl.enqueue_copy(queue, ring_host, self.buffer("pass_ring"), src_offset=ring * ring_host.nbytes)
                    if aov_host is not None:
                        cl.enqueue_copy(queue, aov_host, self.buffer("aov_ring"), src_offset=ring * aov_host.nbytes)
                    cl.enqueue_copy(queue, counters, np.zeros(1, np.int32),
                                    dst_offset=(abi.COUNTER_PASS_DONE + ring) * 4)
                    c[abi.COUNTER_PASS_DONE + ring] = 0
                    if pixels is None:
                        film.add_pass(ring_host, aov_host)
                    else:  # the ring is indexed by pixel: the listed ones
                        film.add_pass(ring_host[pixels], None if aov_host is None else aov_host[pixels], pixels=pixels)
                    self.oldest_pass += 1
                    stats.passes += 1
                    if progress is not None:
                        progress(stats.passes, time.perf_counter() - start)
        except KeyboardInterrupt:
            stats.interrupted = True
            self._reset_wave()
        queue.finish()
        cl.enqueue_copy(queue, self.counters_host, counters)
        stats.nonfinite = int(self.counters_host[abi.COUNTER_NONFINITE])
        stats.samples = stats.passes * P
        stats.seconds = time.perf_counter() - start
        if profile:  # stages that ran on the host have no event: their host time instead
            for name, seconds in self.intersector.host_seconds.items():
                stats.stage_seconds[name] += seconds - host_before[name]
        return stats

    def _upload_pixels(self, pixels):
        """The pixel list of an adaptive run, checked and copied to ``pixel_list`` (None: every pixel)."""
        if pixels is None:
            return None
        import pyopencl as cl

        pixels = np.ascontiguousarray(pixels, np.int32)
        if pixels.ndim != 1 or not 0 < len(pixels) <= self.n_pixels or pixels.min() < 0 \
                or pixels.max() >= self.n_pixels or len(np.unique(pixels)) != len(pixels):
            raise ValueError(f"pixels must be 1 to {self.n_pixels} distinct pixel indices")
        cl.enqueue_copy(self.rt.queue, self.buffer("pixel_list"), pixels)
        return pixels

    def _reset_wave(self):
        """Forget the paths in flight (after an interrupt): every slot free, counters zero."""
        import pyopencl as cl

        queue = self.rt.queue
        queue.finish()
        W = self.wave_size
        cl.enqueue_copy(queue, self.buffer("free_q"), np.arange(W, dtype=np.int32))
        nonfinite = self.counters_host[abi.COUNTER_NONFINITE]
        self.counters_host[:] = 0
        self.counters_host[abi.COUNTER_NONFINITE] = nonfinite
        cl.enqueue_copy(queue, self.buffer("counters"), self.counters_host)
        self.n_active, self.n_free = 0, W


def camera_motion_record(scene) -> np.ndarray:
    """The abi.MOTION record of a moving camera's way (cl/render/path.h camera_moved); where the
    camera stays, a record of zeros (its b 0: every-feature programs, which compile the camera's
    motion in, leave the rays as they are)."""
    if getattr(scene, "camera_motion", None) is None:
        return np.zeros(1, abi.MOTION)
    from ..accel.motion import Motion

    return np.array([Motion(*scene.camera_motion).record(scene.motion_time)])
