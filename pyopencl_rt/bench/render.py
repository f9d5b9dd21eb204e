"""``pyopencl-rt bench render``: samples/s of the path tracer on each device, and optionally with
the extend and shadow stages on Embree (``--intersector opencl,embree``) beside our traversal.

Kernel build and BVH upload are not timed (see :func:`.timing.interleaved_render_rates`); every
device x intersector is timed in each repetition and the median is reported.
"""
from __future__ import annotations

import statistics
import time

from .timing import interleaved_render_rates, machine_info, write_results


def run_render_bench(scene_path, devices=None, width=512, height=512, spp=16, max_depth=8, repeat=3,
                     wave_size=None, intersectors=("opencl",), json_path=None, echo=print) -> dict:
    """Rows are labelled by device, or "<intersector>: <device>" when more than one intersector is
    timed."""
    from ..device import devices as device_registry
    from ..render.wavefront import Wavefront
    from ..scene.loaders import load_scene

    scene = load_scene(scene_path)
    chosen = device_registry.resolve(devices)
    variants, setup_seconds, intersector_of = {}, {}, {}
    for device in chosen:
        for intersector in intersectors:
            label = device_registry.device_label(device)
            if len(intersectors) > 1:
                label = f"{intersector}: {label}"
            start = time.perf_counter()
            wavefront = Wavefront(scene, device, width=width, height=height, max_depth=max_depth, wave_size=wave_size,
                                  intersector=intersector)
            setup_seconds[label] = time.perf_counter() - start
            variants[label] = (scene, wavefront)
            intersector_of[label] = intersector
    rates, last_info = interleaved_render_rates(variants, spp, repeat, profile=True)
    results = {"scene": str(scene_path), "width": width, "height": height, "spp": spp, "max_depth": max_depth,
               "repeat": repeat, "machine": machine_info(), "devices": {}}
    echo(f"{'device':<60} {'Msamples/s':>10} {'rays/sample':>11} {'setup s':>8}")
    for label, (_scene, wavefront) in variants.items():
        info = last_info[label]
        median = statistics.median(rates[label])
        rays_per_sample = (info["rays_extend"] + info["rays_shadow"]) / max(info["samples"], 1)
        results["devices"][label] = {
            "samples_per_second_median": median, "samples_per_second_all": rates[label],
            "intersector": intersector_of[label], "setup_seconds": setup_seconds[label],
            "kernel_build_seconds": wavefront.timings.get("build_seconds"),
            "bvh_seconds": wavefront.timings.get("bvh_seconds"), "wave_size": wavefront.wave_size,
            "rays_per_sample": rays_per_sample, "stage_seconds": info.get("stage_seconds"),
            "features": info["features"],
        }
        echo(f"{label[:60]:<60} {median / 1e6:10.3f} {rays_per_sample:11.2f} {setup_seconds[label]:8.2f}")
    if json_path:
        write_results(json_path, results, echo)
    return results
