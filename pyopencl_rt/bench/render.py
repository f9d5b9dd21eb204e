"""``pyopencl-rt bench render``: samples/s of the path tracer on each device, and optionally with
the extend and shadow stages on Embree (``--intersector opencl,embree``) beside our traversal, with
each path schedule (``--kernel-mode wavefront,megakernel``), and Mitsuba 3 on its own Cornell box
in the same run (``--mitsuba``; compare with ``scenes/mitsuba-cbox.toml``, its transcription; Mitsuba's
film is given the scene's pixel filter, so that both filter alike).

Kernel build and BVH upload are not timed (see :func:`.timing.interleaved_render_rates`); every
device x intersector is timed in each repetition and the median is reported.  Mitsuba renders its
box in every repetition too, right after ours (its JIT warm-up untimed), so each repetition gives
a ratio of two renders run back to back; their median is the figure a shared machine's drifting
load disturbs least.
"""
from __future__ import annotations

import contextlib
import statistics
import time

from ..device.isa import target_cpu
from .timing import interleaved_render_rates, machine_info, write_results

MITSUBA = "mitsuba"  # its rates' key beside our variants' labels
# idle seconds before each timed render when Mitsuba takes turns with us: without them, each
# renderer's worker threads still running after its render slowed the other's next one (7 rounds
# on 2 cores: Mitsuba 2.30 Msamples/s without the pause, 2.45 with it; ours 2.72 and 2.86)
MITSUBA_PAUSE = 1.0


def mitsuba_filter(scene) -> dict:
    """Mitsuba's rfilter for the scene's pixel filter, so that both renderers filter alike (a
    UserError for one Mitsuba has no equivalent of)."""
    from ..errors import UserError
    from ..render.settings import ImageSettings
    from .mitsuba_export import mitsuba_rfilter

    flt = ImageSettings.resolve(scene).filter
    try:
        return mitsuba_rfilter(flt.as_dict())
    except ValueError as exc:
        raise UserError(f"--mitsuba: the scene's pixel filter cannot be given to Mitsuba ({exc})") from None


def run_render_bench(scene_path, devices=None, width=512, height=512, spp=16, max_depth=8, repeat=3,
                     wave_size=None, intersectors=("opencl",), kernel_modes=("auto",), mitsuba=None, json_path=None,
                     samplers=(None,), echo=print) -> dict:
    """Rows are labelled by device, prefixed by "<intersector>: " when more than one intersector
    and by "<kernel mode>: " when more than one schedule is timed, "<sampler>: " when more than one
    of ``samplers`` (None: the scene's) is.  ``mitsuba``: None, or the
    options of :func:`.mitsuba_host.run_mitsuba_cornell_box` (its samples/s are then reported, with
    the ratio of ours to it)."""
    from ..device import devices as device_registry
    from ..render.wavefront import Wavefront
    from ..scene.loaders import load_scene

    scene = load_scene(scene_path)
    chosen = device_registry.resolve(devices)
    variants, setup_seconds, intersector_of = {}, {}, {}
    for device in chosen:
        for intersector in intersectors:
            for mode, sampler in ((m, s) for m in kernel_modes for s in samplers):
                if mode == "megakernel" and intersector != "opencl":
                    continue  # Embree traces the wavefront's queues
                label = device_registry.device_label(device)
                if len(samplers) > 1:
                    label = f"{sampler}: {label}"
                if len(intersectors) > 1:
                    label = f"{intersector}: {label}"
                if len(kernel_modes) > 1:
                    label = f"{mode}: {label}"
                start = time.perf_counter()
                wavefront = Wavefront(scene, device, width=width, height=height, max_depth=max_depth,
                                      wave_size=wave_size, intersector=intersector, kernel_mode=mode, sampler=sampler)
                setup_seconds[label] = time.perf_counter() - start
                variants[label] = (scene, wavefront)
                intersector_of[label] = intersector
    with contextlib.ExitStack() as stack:
        others = {}
        if mitsuba is not None:  # warmed up (JIT) with one render of spp, then timed in our rounds
            from .mitsuba_host import MitsubaCornellBoxServer

            server = stack.enter_context(MitsubaCornellBoxServer(warmup_spp=spp, echo=echo,
                                                                 rfilter=mitsuba_filter(scene), **mitsuba))
            others[MITSUBA] = server.render
        rates, last_info = interleaved_render_rates(variants, spp, repeat, profile=True, others=others,
                                                    pause=MITSUBA_PAUSE if others else 0.0)
    results = {"scene": str(scene_path), "width": width, "height": height, "spp": spp, "max_depth": max_depth,
               "repeat": repeat, "machine": machine_info(), "devices": {}}
    echo(f"{'device':<60} {'Msamples/s':>10} {'rays/sample':>11} {'setup s':>8} {'lanes':>5}")
    for label, (_scene, wavefront) in variants.items():
        info = last_info[label]
        median = statistics.median(rates[label])
        rays_per_sample = (info["rays_extend"] + info["rays_shadow"]) / max(info["samples"], 1)
        results["devices"][label] = {
            "samples_per_second_median": median, "samples_per_second_all": rates[label],
            "intersector": intersector_of[label], "kernel_mode": wavefront.kernel_mode,
            "setup_seconds": setup_seconds[label],
            "kernel_build_seconds": wavefront.timings.get("build_seconds"),
            "bvh_seconds": wavefront.timings.get("bvh_seconds"), "wave_size": wavefront.wave_size,
            "rays_per_sample": rays_per_sample, "stage_seconds": info.get("stage_seconds"),
            "features": info["features"],
            # the width and why, with what PoCL compiles for (pyopencl_rt/device/isa.py)
            "lanes": wavefront.lane_width, "lanes_reason": wavefront.lane_reason,
            "target_cpu": target_cpu(wavefront.device),
        }
        echo(f"{label[:60]:<60} {median / 1e6:10.3f} {rays_per_sample:11.2f} {setup_seconds[label]:8.2f} "
             f"{wavefront.lane_width or 1:5d}")
    if mitsuba is not None:
        theirs_rates = rates[MITSUBA]
        theirs = {**server.info, "renders": server.renders, "samples_per_second_all": theirs_rates,
                  "samples_per_second_median": statistics.median(theirs_rates)}
        results["mitsuba"] = theirs
        echo(f"{'Mitsuba ' + theirs['version'] + ' ' + theirs['variant'] + ' (mi.cornell_box(), our filter)':<60} "
             f"{theirs['samples_per_second_median'] / 1e6:10.3f}")
        for label, row in results["devices"].items():
            row["ratio_to_mitsuba"] = row["samples_per_second_median"] / theirs["samples_per_second_median"]
            # each round's ratio: ours and Mitsuba's renders of that round ran back to back
            row["ratio_to_mitsuba_per_round"] = [a / b for a, b in zip(rates[label], theirs_rates)]
            row["ratio_to_mitsuba_per_round_median"] = statistics.median(row["ratio_to_mitsuba_per_round"])
            echo(f"  {label[:58]}: {row['ratio_to_mitsuba']:.2f}x Mitsuba's samples/s (ratio of medians); "
                 f"per round {', '.join(f'{r:.2f}' for r in row['ratio_to_mitsuba_per_round'])}, "
                 f"median {row['ratio_to_mitsuba_per_round_median']:.2f}x")
    if json_path:
        write_results(json_path, results, echo)
    return results
