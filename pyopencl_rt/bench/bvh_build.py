"""``pyopencl-rt bench bvh``: build time and SAH quality of the host BVH builder.

For each size, the binned SAH builder (the default) runs on each mesh kind of
:data:`.workloads.MESH_KINDS` (median of ``repeat`` builds).  On the meshes of ``sweep_size``
triangles the full-sweep SAH builder runs too, as the quality reference, and the ratio of the
two SAH costs is reported (binned / sweep: 1 is as good as the sweep).
"""
from __future__ import annotations

import statistics

from .timing import machine_info, timed_repeats, write_results
from .workloads import MESH_KINDS, synthetic_mesh


def _timed_build(vertices, faces, method, repeat):
    """(BVH, its stats with the median build time) over ``repeat`` builds."""
    from ..accel.bvh import build_bvh

    latest = {}

    def build():
        latest["bvh"] = build_bvh(vertices, faces, method=method)

    seconds = timed_repeats(build, repeat)
    stats = dict(latest["bvh"].stats)
    stats["build_seconds"] = statistics.median(seconds)
    stats["build_seconds_all"] = seconds
    return latest["bvh"], stats


def run_bvh_bench(sizes=(10_000, 100_000, 1_000_000), kinds=MESH_KINDS, sweep_size=100_000, repeat=3,
                  check=False, json_path=None, echo=print) -> dict:
    """Build every (kind, size) with binned SAH, and with the sweep too at ``sweep_size`` (0: never);
    ``check`` validates every tree (slow on big meshes)."""
    from ..accel.bvh_validate import validate

    results = {"machine": machine_info(), "repeat": repeat, "sweep_size": sweep_size, "results": []}
    for size in sizes:
        for kind in kinds:
            vertices, faces = synthetic_mesh(kind, size)
            bvh, binned = _timed_build(vertices, faces, "binned", repeat)
            if check:
                validate(bvh)
            row = {"kind": kind, "size": int(size), "triangles": int(len(faces)), "binned": binned}
            if sweep_size and size == sweep_size:
                sweep_bvh, sweep = _timed_build(vertices, faces, "sweep", 1)  # the sweep is slow: one build
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
            f"SAH {binned['sah_cost']:8.2f}  nodes {binned['node_count']:>8d} depth {binned['depth']:>2d}")
    if "sweep" in row:
        sweep = row["sweep"]
        text += f" | sweep {sweep['build_seconds']:7.2f}s SAH {sweep['sah_cost']:8.2f}  ratio {row['sah_ratio']:.4f}"
    histogram = binned["leaf_size_histogram"]
    text += "  leaves " + " ".join(f"{size}:{count}" for size, count in sorted(histogram.items())[:8])
    if len(histogram) > 8:
        text += f" ... (max {max(histogram)})"
    return text
