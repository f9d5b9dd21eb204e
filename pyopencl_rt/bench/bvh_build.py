"""``pyopencl-rt bench bvh``: build time and SAH quality of the host BVH builder.

For each size, the binned SAH builder (the default) runs on each mesh kind of
:data:`.workloads.MESH_KINDS` (median of ``repeat`` builds).  On the meshes of ``sweep_size``
triangles the full-sweep SAH builder runs too, as the quality reference, and the ratio of the
two SAH costs is reported (binned / sweep: 1 is as good as the sweep).  Embree (embreex) builds
each mesh too, timed alternately with ours, for scale: Embree builds its BVH when the scene is
committed, which embreex does on the first ``run``, so ``embree_build_seconds`` is that first
``run`` of one ray, and ``embree_scene_seconds`` the embreex scene and mesh creation before it
(what ``bench rays`` reports as its embree build time).  ``cpu_seconds`` is the process CPU time
of our build (all its threads): on a machine shared with other jobs the wall time stretches, the
CPU time much less.

The binned builder is compiled with numba: the first build in a process compiles it or loads it
from numba's on-disk cache.  That one-off cost is measured on its own before anything else
(``jit_seconds``) and is not in the build times.
"""
from __future__ import annotations

import statistics

from .timing import machine_info, timed_repeats, write_results
from .workloads import MESH_KINDS, synthetic_mesh


def _timed_build(vertices, faces, method, repeat, embree=False):
    """(BVH, its stats with the median build time, Embree's median (scene, commit) seconds or None)
    over ``repeat`` builds, ours and Embree's alternately."""
    import time

    import numpy as np

    from ..accel.bvh import build_bvh
    from ..accel.embree import embree_scene

    latest = {}

    def build():
        latest["bvh"] = build_bvh(vertices, faces, method=method)

    def build_embree():
        latest["bvh"].__dict__.pop("_embree_scene", None)     # embree_scene caches its scene on the BVH
        start = time.perf_counter()
        scene = embree_scene(latest["bvh"])
        created = time.perf_counter()
        scene.run(np.zeros((1, 3), np.float32), np.array([[0, 0, 1]], np.float32), output=1)
        return created - start, time.perf_counter() - created

    seconds, cpu_seconds, embree_seconds = [], [], []
    for _ in range(repeat):
        cpu = time.process_time()
        seconds += timed_repeats(build, 1)
        cpu_seconds.append(time.process_time() - cpu)
        if embree:
            embree_seconds.append(build_embree())
    stats = dict(latest["bvh"].stats)
    stats["build_seconds"] = statistics.median(seconds)
    stats["build_seconds_all"] = seconds
    stats["cpu_seconds"] = statistics.median(cpu_seconds)    # every thread's: what a loaded machine stretches
    if not embree:
        return latest["bvh"], stats, None
    return latest["bvh"], stats, tuple(statistics.median(s) for s in zip(*embree_seconds))


def run_bvh_bench(sizes=(10_000, 100_000, 1_000_000), kinds=MESH_KINDS, sweep_size=100_000, repeat=3,
                  check=False, json_path=None, echo=print) -> dict:
    """Build every (kind, size) with binned SAH, and with the sweep too at ``sweep_size`` (0: never);
    ``check`` validates every tree (slow on big meshes)."""
    from ..accel.bvh_binned import thread_count, warm_up
    from ..accel.bvh_validate import validate

    jit_seconds = warm_up()
    echo(f"binned builder: {thread_count()} threads; first call in this process (numba compile or cache "
         f"load) {jit_seconds:.2f} s, not in the build times")
    results = {"machine": machine_info(), "repeat": repeat, "sweep_size": sweep_size, "threads": thread_count(),
               "jit_seconds": jit_seconds, "results": []}
    for size in sizes:
        for kind in kinds:
            vertices, faces = synthetic_mesh(kind, size)
            bvh, binned, (embree_scene, embree_build) = _timed_build(vertices, faces, "binned", repeat, embree=True)
            if check:
                validate(bvh)
            row = {"kind": kind, "size": int(size), "triangles": int(len(faces)), "binned": binned,
                   "embree_build_seconds": embree_build, "embree_scene_seconds": embree_scene}
            if sweep_size and size == sweep_size:
                sweep_bvh, sweep, _ = _timed_build(vertices, faces, "sweep", 1)  # the sweep is slow: one build
                if check:
                    validate(sweep_bvh)
                row["sweep"] = sweep
                row["sah_ratio"] = binned["sah_cost"] / sweep["sah_cost"]
            results["results"].append(row)
            echo(format_row(row))
    if json_path:
        write_results(json_path, results, echo)
    return results


def format_row(row) -> str:
    binned = row["binned"]
    text = (f"{row['kind']:8s} {row['triangles']:>9d}  binned {binned['build_seconds']:7.3f}s "
            f"(cpu {binned['cpu_seconds']:.3f}s) SAH {binned['sah_cost']:8.2f}  nodes {binned['node_count']:>8d} depth {binned['depth']:>2d}")
    if row.get("embree_build_seconds") is not None:
        text += f"  embree {row['embree_build_seconds']:6.3f}s (+{row['embree_scene_seconds']:.3f}s scene)"
    if "sweep" in row:
        sweep = row["sweep"]
        text += f" | sweep {sweep['build_seconds']:7.2f}s SAH {sweep['sah_cost']:8.2f}  ratio {row['sah_ratio']:.4f}"
    histogram = binned["leaf_size_histogram"]
    text += "  leaves " + " ".join(f"{size}:{count}" for size, count in sorted(histogram.items())[:8])
    if len(histogram) > 8:
        text += f" ... (max {max(histogram)})"
    return text
