"""``pyopencl-rt bench rays``: rays/s of the OpenCL traversal beside embreex on the very same rays,
and the host BVH build time, on bumpy tori of several sizes.

Two ray sets per mesh: *primary* (pinhole camera rays, coherent) and *diffuse* (one
cosine-distributed bounce from each primary hit, incoherent).

Ours is :func:`pyopencl_rt.trace`'s OpenCL path (rays in host memory, the kernel, the hits back in
host memory) on rays checked once beforehand, untimed: the API's input validation is not ray
casting, and Embree's figure is embreex's ``run`` alone.  Embree is timed twice: single-threaded (embreex's ``run`` alone: one ``rtcIntersect1`` per ray on
the calling thread) and with as many workers as PoCL has threads (the CPU devices' compute units,
``--embree-threads`` to override): embreex holds the GIL while it traces, so the workers are
processes (:mod:`pyopencl_rt.bench.embree_pool`).  Ratios are given against both.

Every backend is timed once per repetition, in turn, after a short pause (:data:`PAUSE`); besides
the medians, each row records its per-repetition ratios to the Embree processes and their median.
Each backend's CPU seconds are recorded too (this process's for ours, PoCL's threads included;
the workers' together for the pool): rays per CPU second is the work per thread, which a shared,
loaded machine disturbs much less than the wall time.
"""
from __future__ import annotations

import contextlib
import statistics
import time

import numpy as np

from .timing import machine_info, timed_repeats, write_results
from .workloads import bumpy_torus, diffuse_rays, primary_rays

# idle seconds before each timed run, so that the threads or processes of the run before (PoCL's,
# Embree's workers) have gone to sleep and take no core from the next
PAUSE = 0.2


def pocl_threads(devices) -> int:
    """The threads PoCL runs a kernel on: the largest compute-unit count among the CPU devices
    (PoCL's pthread device has one thread per compute unit), else the host's CPU count."""
    import os

    import pyopencl as cl

    cpus = [int(d.max_compute_units) for d in devices if d.type & cl.device_type.CPU]
    return max(cpus) if cpus else (os.cpu_count() or 1)


def run_ray_bench(devices=None, sizes=(10_000, 100_000, 1_000_000), n_rays=1_000_000, repeat=3,
                  embree=True, json_path=None, echo=print, layouts=None, embree_threads=None) -> dict:
    """``layouts``: BVH layouts to time on each device (e.g. ``("binary", "wide", "wide8")``; their rows
    are labelled "<layout>: <device>"); None times each device's default layout under its plain label.
    ``embree_threads``: Embree's worker processes for the parallel figure (default: :func:`pocl_threads`)."""
    from ..accel.bvh import build_bvh
    from ..accel.device_bvh import bvh_layout
    from ..accel.embree import embree_scene
    from ..device import devices as device_registry
    from ..trace import trace
    from .embree_pool import EmbreePool

    chosen = device_registry.resolve(devices)
    # (row label, device, layout) of every OpenCL configuration timed
    if layouts:
        configs = [(f"{layout}: {device_registry.device_label(device)}", device, bvh_layout(device, layout))
                   for device in chosen for layout in layouts]
    else:
        configs = [(device_registry.device_label(device), device, bvh_layout(device)) for device in chosen]
    threads = int(embree_threads or pocl_threads(chosen))
    rng = np.random.default_rng(7)
    results = {"machine": machine_info(), "devices": [device_registry.device_label(d) for d in chosen],
               "repeat": repeat, "embree_threads": threads if embree else None, "meshes": []}
    echo(f"{'mesh':>10} {'rays':>10} {'set':>8} {'backend':<40} {'Mrays/s':>9} "
         f"{'vs embree x' + str(threads):>14} {'per round':>10} {'vs embree x1':>13} {'Mrays/cpu-s':>11}")
    with (EmbreePool(threads) if embree else contextlib.nullcontext()) as pool:
        for size in sizes:
            vertices, faces = bumpy_torus(size)
            bvh = None

            def build():
                nonlocal bvh
                bvh = build_bvh(vertices, faces)

            build_seconds = statistics.median(timed_repeats(build, repeat))
            entry = {"triangles": int(len(faces)), "bvh_build_seconds": build_seconds,
                     "bvh_stats": {k: v for k, v in bvh.stats.items() if k != "leaf_size_histogram"}, "sets": []}
            if embree:
                start = time.perf_counter()
                embree_scene(bvh)
                entry["embree_build_seconds"] = time.perf_counter() - start
                pool.load(vertices, faces)
            echo(f"{len(faces):>10} triangles: BVH build {build_seconds:.3f} s (median of {repeat}), "
                 f"SAH cost {bvh.stats['sah_cost']:.2f}"
                 + (f"; embree build {entry['embree_build_seconds']:.3f} s" if embree else ""))
            origins, directions = primary_rays(bvh.bounds.astype(np.float64), n_rays)
            reference_hits = trace(bvh, origins, directions, backend="embree")
            bounce = diffuse_rays(reference_hits, origins, directions, rng)
            for set_name, (set_origins, set_directions) in (("primary", (origins, directions)), ("diffuse", bounce)):
                entry["sets"].append(_time_ray_set(bvh, set_name, set_origins, set_directions, configs, pool,
                                                   repeat, len(faces), echo))
            results["meshes"].append(entry)
    if json_path:
        write_results(json_path, results, echo)
    return results


def _time_ray_set(bvh, set_name, origins, directions, configs, pool, repeat, n_triangles, echo) -> dict:
    """Every configuration, Embree on one thread and Embree on the pool's workers, timed in turn
    within each repetition (so that load on the machine hits them alike); medians reported."""
    from ..accel.embree import embree_scene
    from ..trace import _opencl, _rays

    n = len(origins)
    row = {"set": set_name, "rays": n, "backends": {}}
    o, d, tmin, tmax = _rays(origins, directions, 0.0, np.inf)  # checked once, untimed

    def trace(device, layout, count=None):
        return _opencl(bvh, o[:count], d[:count], tmin[:count], tmax[:count], device, any_hit=False, layout=layout)

    for _name, device, layout in configs:  # warm-up: kernel build, BVH collapse and upload are not timed
        trace(device, layout, 1024)
    seconds = {name: [] for name, _device, _layout in configs}
    cpu = {name: [] for name in seconds}
    parallel, parallel_cpu = [], []
    if pool is not None:
        seconds["embree"], cpu["embree"] = [], []
        pool.set_rays(origins, directions)
    for _ in range(repeat):
        for name, device, layout in configs:
            time.sleep(PAUSE)
            start, cpu_start = time.perf_counter(), time.process_time()
            trace(device, layout)
            seconds[name].append(time.perf_counter() - start)
            cpu[name].append(time.process_time() - cpu_start)
        if pool is not None:  # embreex's own call alone, so Embree is not charged for our wrapper
            scene = embree_scene(bvh)
            time.sleep(PAUSE)
            start, cpu_start = time.perf_counter(), time.process_time()
            scene.run(origins, directions, output=1)
            seconds["embree"].append(time.perf_counter() - start)
            cpu["embree"].append(time.process_time() - cpu_start)
            time.sleep(PAUSE)
            parallel.append(pool.run())
            parallel_cpu.append(pool.cpu_seconds)
    one = statistics.median(seconds["embree"]) if pool is not None else None
    many = statistics.median(parallel) if pool is not None else None
    if pool is not None:
        row["embree_parallel"] = {"workers": pool.workers, "seconds_median": many, "seconds_all": parallel,
                                  "rays_per_second": n / many,
                                  "speedup_over_one_thread": one / many,
                                  "rays_per_cpu_second": n / statistics.median(parallel_cpu)}
    layouts = {name: layout for name, _device, layout in configs}
    rows = list(seconds.items()) + ([(f"embree x{pool.workers} (processes)", parallel)] if pool is not None else [])
    cpu[rows[-1][0]] = parallel_cpu
    for name, times in rows:
        median = statistics.median(times)
        rate = n / median
        cpu_rate = n / max(statistics.median(cpu[name]), 1e-9)
        # each repetition's ratio: this backend and the Embree processes ran one after the other
        per_round = [b / a for a, b in zip(times, parallel)] if many else None
        if name in seconds:
            row["backends"][name] = {"seconds_median": median, "seconds_all": times, "rays_per_second": rate,
                                     "rays_per_cpu_second": cpu_rate,
                                     "ratio_to_embree": (one / median) if one else None,
                                     "ratio_to_embree_parallel": (many / median) if many else None}
            if many:
                row["backends"][name]["ratio_to_embree_parallel_per_round"] = per_round
                row["backends"][name]["ratio_to_embree_parallel_per_round_median"] = statistics.median(per_round)
            if layouts.get(name):
                row["backends"][name]["layout"] = layouts[name]
        vs_many = f"{many / median:14.2f}" if many else f"{'-':>14}"
        vs_round = f"{statistics.median(per_round):10.2f}" if many else f"{'-':>10}"
        vs_one = f"{one / median:13.2f}" if one else f"{'-':>13}"
        echo(f"{n_triangles:>10} {n:>10} {set_name:>8} {name[:40]:<40} {rate / 1e6:9.3f} {vs_many} {vs_round}"
             f" {vs_one} {cpu_rate / 1e6:11.3f}")
    return row
