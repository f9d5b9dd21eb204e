"""The megakernel schedule: one work-item per sample follows its whole path (cl/megakernel/path.cl).

The wavefront (:mod:`pyopencl_rt.render.wavefront`) keeps every path's state in memory between
five small kernels and compacts queues after each bounce, which keeps a GPU's SIMD lanes busy.  On
a CPU each work-item runs as scalar code anyway, so those round trips are pure cost: the
megakernel keeps the path in registers and traces its shadow ray at once.  It computes the same
samples in the same order with the same random numbers, so the image is identical, bit for bit;
only the speed differs (docs/BENCHMARKS.md, "Samples per second against Mitsuba on the CPU").

Which schedule a render uses (:func:`kernel_mode`): ``"megakernel"`` on CPU devices, the wavefront
on the others, when the Embree intersector traces on the host (it needs the wavefront's ray
queues) and when film AOVs are requested (their per-path state lives in the wavefront's buffers).
``$PYOPENCL_RT_KERNEL_MODE`` or the ``kernel_mode`` argument overrides the choice.  Scenes with
participating media follow the same rule: both schedules take the one volumetric step
(cl/render/volpath.h, ``volpath_vertex``), so the image is the same bit for bit, and on a CPU the lane
megakernel is the faster (docs/BENCHMARKS.md, "Participating media: wavefront against megakernel").

Paths in SIMD lanes (:func:`lane_choice`): on PoCL's CPU device of an x86 host, each work-item
follows 16 or 8 paths at once in the lanes of its vectors (cl/megakernel/path.cl compiled with
PACKET_WIDTH; the one integrator, cl/render/path.h, is written over lanes): their rays are traced
as packets and their hits shaded together, as Mitsuba's LLVM backend runs its paths, for every
scene (every material, light, texture and integrator).  Same samples, bit for bit, except where
two triangles give a ray exactly the same distance.  ``$PYOPENCL_RT_LANES`` = 0 turns it off.
"""
from __future__ import annotations

import os
import time

import numpy as np

from ..accel.device_bvh import LANES_ENV, lanes_setting, packet_choice  # noqa: F401 (LANES_ENV: tests, tools)
from ..device import abi
from ..errors import UserError
from .film import Film, RunStats

KERNEL_MODES = ("wavefront", "megakernel")
KERNEL_MODE_ENV = "PYOPENCL_RT_KERNEL_MODE"
SOURCES = ("megakernel/path.cl",)
LANE_BLOCK = 16           # samples per work-item, in units of the lane width, taken in turn by its lanes
# work-items per group on CPUs: PoCL compiles a group of one without its work-item loop, which
# cuts a cold build of the megakernel by 20-55% and runs as fast (docs/BENCHMARKS.md, "Kernel
# builds"); GPUs keep the wave's group size (WAVE_LOCAL_SIZE) at one path per work-item
LANE_GROUP = 1


def kernel_mode(device, intersector: str, film_aovs, requested: str | None = None, media: bool = False) -> str:
    """The schedule for a render on ``device`` (see the module docstring).  ``media``: the scene has
    participating media or index-matched shapes, which take no film AOVs in either schedule."""
    import pyopencl as cl

    requested = requested or os.environ.get(KERNEL_MODE_ENV) or "auto"
    if requested not in KERNEL_MODES + ("auto",):
        raise UserError(f"unknown kernel mode {requested!r}: use auto, wavefront or megakernel "
                        f"(argument or ${KERNEL_MODE_ENV})")
    can_megakernel = intersector == "opencl" and not film_aovs
    if requested == "megakernel" and not can_megakernel:
        raise UserError("--kernel-mode megakernel traces in OpenCL and has no AOVs: it cannot be combined with "
                        "--intersector embree or film AOVs")
    if media and film_aovs:
        # the wavefront would record the first hit behind a null boundary with the depth of the ray from it
        raise UserError("film AOVs (albedo, normal, depth, position; the guides of --denoise) are not recorded in "
                        "scenes with participating media or index-matched shapes: render without those AOVs and "
                        "--denoise")
    if requested == "auto":
        return "megakernel" if can_megakernel and device.type & cl.device_type.CPU else "wavefront"
    return requested


def lane_choice(mode: str, device, features: dict, requested=None) -> tuple[int, str]:
    """Paths per work-item of the megakernel, and why: the packet width of the device
    (:func:`~pyopencl_rt.accel.device_bvh.packet_choice`: 16, 8 or 0 from what PoCL compiles for)
    where the lane kernel applies (the megakernel on PoCL's CPU device of an x86 host, a scene
    whose triangles are in the 8-wide BVH the packets traverse), else 0 (one path per work-item).  ``requested`` or
    ``$PYOPENCL_RT_LANES`` overrides: 0 (off), 8 or 16 (where it applies and is safe)."""
    lanes_setting(requested)  # checks the setting first, whatever the scene
    if mode != "megakernel":
        return 0, f"one path per work-item: the {mode} schedule"
    if "HAS_TRIANGLES" in features and "BVH_WIDE8" not in features:
        return 0, "one path per work-item: the packets traverse the 8-wide BVH, not this device's layout"
    return packet_choice(device, requested)


def lane_features(width: int) -> dict:
    """The defines of the lane kernel (none for one path per work-item)."""
    return {"PACKET_WIDTH": width, "PACKET_BLOCK": LANE_BLOCK * width, "LANE_GROUP": LANE_GROUP} if width else {}


def group_features(device, width: int) -> dict:
    """The defines of the megakernel at ``width`` paths per work-item on ``device``: the lanes',
    and at one path per work-item the CPU's group size (GPUs: the wave's)."""
    import pyopencl as cl

    if width:
        return lane_features(width)
    return {"LANE_GROUP": LANE_GROUP} if device.type & cl.device_type.CPU else {}


def run(wf, film: Film, passes=None, time_limit=None, progress=None, profile=False, first_pass=0,
        cancel=None, pixels=None) -> RunStats:
    """:meth:`Wavefront.run` for the megakernel: whole passes per launch, as many as the wave
    size allows, added to the film in pass order.  ``pixels`` (adaptive sampling; already in the
    ``pixel_list`` buffer): the passes cover those pixels only, and the kernel writes each launch's
    results in order at the start of the ring, so that a short list still fills the wave.

    One launch is kept in flight: launch N+1 is queued (after launch N's result copies, which the
    in-order queue runs between the two) before the host adds launch N's passes to the film, so
    the device does not wait for the host's sums (docs/BENCHMARKS.md).  An interrupt waits for
    what is queued and adds it: nothing computed is lost."""
    import pyopencl as cl

    if passes is None and time_limit is None:
        raise ValueError("give passes, time_limit or both")
    n_pixels = wf.n_pixels if pixels is None else len(pixels)  # samples of a pass
    queue = wf.rt.queue
    kernel = wf.kernels["path"]
    counters = wf.buffer("counters")
    stats = RunStats()
    if pixels is None:
        passes_per_launch = max(1, min(wf.wave_size // n_pixels, wf.ring_size))
    else:  # the ring holds ring_size * wf.n_pixels results in order: every launch's
        passes_per_launch = max(1, min(wf.wave_size, wf.ring_size * wf.n_pixels) // n_pixels)
    # at most the wave; with pixels, passes_per_launch already
    # keeps a launch within the ring's ring_size * wf.n_pixels entries (n_pixels <= wf.n_pixels)
    samples_per_launch = min(passes_per_launch * n_pixels, wf.wave_size)
    # two sets of host buffers: one being filled by the queue while the host sums the other
    results = [np.empty((passes_per_launch, n_pixels, 3), np.float32) for _ in range(2)]
    ray_counts = [np.zeros(2, np.int32) for _ in range(2)]
    local = wf.features.get("LANE_GROUP", abi.WAVE_LOCAL_SIZE)  # as the kernel was built
    block = wf.features.get("PACKET_BLOCK", 1)  # samples per work-item
    end = None if passes is None else first_pass + passes
    zero_rays = np.zeros(2, np.int32)
    rays_at = abi.COUNTER_RAYS_EXTEND * 4  # both ray counters, read and zeroed as one pair

    def enqueue(first, count, slot):
        """Queues the launches of passes first .. first + count - 1 and the copies of their
        results and ray counts into host buffer set `slot`; returns what finish() needs."""
        events = []
        # one launch renders at most the wave size, so a pass bigger than it takes several
        for first_pixel in range(0, count * n_pixels, samples_per_launch):
            n = min(samples_per_launch, count * n_pixels - first_pixel)
            wf.args.set("path", n_items=n, first_pass=first, first_pixel=first_pixel,
                        queue_in=wf.queue_a, queue_out=wf.queue_b, queue_base=0, free_base=0,
                        n_listed=0 if pixels is None else n_pixels)
            items = -(-n // block)
            event = cl.enqueue_nd_range_kernel(queue, kernel, (-(-items // local) * local,), (local,))
            if profile:
                event.wait()
                stats.stage_seconds["path"] = stats.stage_seconds.get("path", 0.0) + \
                    (event.profile.end - event.profile.start) * 1e-9
            if pixels is not None:  # n results in order, before the next launch overwrites them
                flat = results[slot].reshape(-1, 3)
                events.append(cl.enqueue_copy(queue, flat[first_pixel:first_pixel + n], wf.buffer("pass_ring"),
                                              is_blocking=False))
        if pixels is None:
            for k in range(count):
                ring = (first + k) % wf.ring_size
                events.append(cl.enqueue_copy(queue, results[slot][k], wf.buffer("pass_ring"),
                                              src_offset=ring * n_pixels * 12, is_blocking=False))
        # the int32 counters hold one launch's rays, never a whole run's (2^31 rays is minutes)
        events.append(cl.enqueue_copy(queue, ray_counts[slot], counters, src_offset=rays_at, is_blocking=False))
        cl.enqueue_copy(queue, counters, zero_rays, dst_offset=rays_at, is_blocking=False)
        queue.flush()
        return {"events": events, "slot": slot, "count": count, "added": 0, "counted": False, "gathered": False}

    def finish(launch):
        """Waits for a launch's copies and adds its passes to the film; resumable (an interrupt
        inside leaves the launch's flags at what is already in)."""
        cl.wait_for_events(launch["events"])
        slot, count = launch["slot"], launch["count"]
        if not launch["counted"]:
            stats.rays_extend += int(ray_counts[slot][0])
            stats.rays_shadow += int(ray_counts[slot][1])
            launch["counted"] = True
        if pixels is not None and not launch["gathered"]:  # gathered once: add_pass's sums, pass after pass
            film.add_passes(results[slot][:count], pixels)
            launch["gathered"] = True
        while launch["added"] < count:
            if pixels is None:
                film.add_pass(results[slot][launch["added"]])
            launch["added"] += 1
            stats.passes += 1
            stats.iterations += 1
            if progress is not None:
                progress(stats.passes, time.perf_counter() - start)

    next_pass = first_pass
    pending = []  # queued launches whose passes are not in the film yet, oldest first
    # rays of an earlier run's launch that an interrupt left uncounted are not this run's
    cl.enqueue_copy(queue, counters, zero_rays, dst_offset=rays_at, is_blocking=False)
    start = time.perf_counter()
    try:
        while end is None or next_pass < end:
            if cancel is not None and cancel():
                raise KeyboardInterrupt
            if time_limit is not None and time.perf_counter() - start >= time_limit:
                break
            count = passes_per_launch if end is None else min(passes_per_launch, end - next_pass)
            slot = 1 - pending[-1]["slot"] if pending else 0
            pending.append(enqueue(next_pass, count, slot))
            next_pass += count
            while len(pending) > 1:  # the launch before this one, while this one runs
                finish(pending[0])
                pending.pop(0)
    except KeyboardInterrupt:
        stats.interrupted = True
    try:
        queue.finish()
        while pending:  # what is queued (or was being added when interrupted)
            finish(pending[0])
            pending.pop(0)
    except KeyboardInterrupt:  # a second interrupt while the last launches are added: keep what is in
        stats.interrupted = True
    cl.enqueue_copy(queue, wf.counters_host, counters)
    stats.nonfinite = int(wf.counters_host[abi.COUNTER_NONFINITE])
    stats.samples = stats.passes * n_pixels
    stats.seconds = time.perf_counter() - start
    return stats
