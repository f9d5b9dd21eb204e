"""``pyopencl-rt bench render``: samples/s of the path tracer on each device, and optionally with
the extend and shadow stages on Embree (``--intersector opencl,embree``) beside our traversal, with
each path schedule (``--kernel-mode wavefront,megakernel``), and Mitsuba 3 on the same scene in the
same run (``--mitsuba``: the scene exported by :mod:`.mitsuba_export`, rendered at the same size and
depth).  Several scenes are benchmarked one after the other, each with its own Mitsuba process.

Kernel build and BVH upload are not timed (see :func:`.timing.interleaved_render_rates`); every
device x intersector is timed in each repetition and the median is reported.  Mitsuba renders the
scene in every repetition too, right after ours (its JIT warm-up untimed), so each repetition gives
a ratio of two renders run back to back; their median is the figure a shared machine's drifting
load disturbs least.

The results (and the ``--json`` file): for one scene, the scene's result (``devices``: a row per
variant, ``mitsuba``: Mitsuba's renders) with ``summary`` beside it; for several, ``scenes``: a list
of such results, and ``summary``.  ``summary`` has a row per scene and variant: our and Mitsuba's
median samples/s, the median of the per-round ratios, and the lane width with its reason.
"""
from __future__ import annotations

import contextlib
import os
import statistics
import time

from ..device.isa import target_cpu
from ..errors import UserError
from .mitsuba_host import DEFAULT_VARIANT
from .timing import interleaved_render_rates, machine_info, write_results

MITSUBA = "mitsuba"  # its rates' key beside our variants' labels
# idle seconds before each timed render when Mitsuba takes turns with us: without them, each
# renderer's worker threads still running after its render slowed the other's next one (7 rounds
# on 2 cores: Mitsuba 2.30 Msamples/s without the pause, 2.45 with it; ours 2.72 and 2.86)
MITSUBA_PAUSE = 1.0


def run_render_bench(scene_paths, devices=None, width=512, height=512, spp=16, max_depth=8, repeat=3,
                     wave_size=None, intersectors=("opencl",), kernel_modes=("auto",), mitsuba=None, json_path=None,
                     samplers=(None,), echo=print) -> dict:
    """Rows are labelled by device, prefixed by "<intersector>: " when more than one intersector
    and by "<kernel mode>: " when more than one schedule is timed, "<sampler>: " when more than one
    of ``samplers`` (None: the scene's) is.  ``scene_paths``: one path or several.  ``mitsuba``:
    None, or the options of :class:`.mitsuba_host.MitsubaServer` (its samples/s are then reported,
    with the ratio of ours to it).  ``max_depth``: None for each scene's own."""
    from ..render.settings import ImageSettings
    from ..scene.loaders import load_scene

    paths = [scene_paths] if isinstance(scene_paths, (str, os.PathLike)) else list(scene_paths)
    scenes = []
    for path in paths:  # every scene read, and exported where Mitsuba renders it, before any timing
        scene = load_scene(path)
        settings = ImageSettings.resolve(scene, width=width, height=height, max_depth=max_depth)
        if mitsuba is not None:
            check_exportable(path, scene, settings)
        scenes.append((path, scene, settings))
    if mitsuba is not None:  # looked for once, not for each scene
        from .mitsuba_host import require_mitsuba_python

        python = require_mitsuba_python(mitsuba.get("mitsuba_python"), mitsuba.get("variant", DEFAULT_VARIANT),
                                        mitsuba.get("llvm_path"), echo)
        mitsuba = {**mitsuba, "python": python}
    per_scene = []
    for path, scene, settings in scenes:
        if len(scenes) > 1:
            echo(f"== {path}")
        per_scene.append(bench_scene(path, scene, settings, devices=devices, spp=spp, repeat=repeat,
                                     wave_size=wave_size, intersectors=intersectors, kernel_modes=kernel_modes,
                                     mitsuba=mitsuba, samplers=samplers, echo=echo))
    summary = [row for result in per_scene for row in summary_rows(result)]
    if len(per_scene) > 1 or mitsuba is not None:
        print_summary(summary, echo)
    if len(per_scene) == 1:
        results = {**per_scene[0], "summary": summary}
    else:
        results = {"scenes": per_scene, "summary": summary, "width": width, "height": height, "spp": spp,
                   "max_depth": max_depth, "repeat": repeat, "machine": machine_info()}
    if json_path:
        write_results(json_path, results, echo)
    return results


def check_exportable(path, scene, settings) -> None:
    """A UserError naming the scene when Mitsuba cannot be given the same scene."""
    from .mitsuba_export import scene_arrays

    try:
        scene_arrays(scene, settings)
    except ValueError as exc:
        raise UserError(f"{path}: Mitsuba cannot render the same scene: {exc}") from None


def bench_scene(scene_path, scene, settings, *, devices, spp, repeat, wave_size, intersectors, kernel_modes,
                mitsuba, samplers, echo) -> dict:
    """One scene's rows (see :func:`run_render_bench`)."""
    from ..device import devices as device_registry
    from ..render.wavefront import Wavefront

    width, height, max_depth = settings.width, settings.height, settings.max_depth
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
            from .mitsuba_host import MitsubaServer

            server = stack.enter_context(MitsubaServer(scene, settings, warmup_spp=spp, echo=echo, **mitsuba))
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
        theirs = {**server.info, "scene": "the export of mitsuba_export.py", "renders": server.renders,
                  "samples_per_second_all": theirs_rates, "samples_per_second_median": statistics.median(theirs_rates)}
        results["mitsuba"] = theirs
        lanes = f", {theirs['lanes']} lanes for {theirs['target_cpu']}" if theirs.get("lanes") else ""
        echo(f"{'Mitsuba ' + theirs['version'] + ' ' + theirs['variant'] + lanes + ' (the same scene)':<60} "
             f"{theirs['samples_per_second_median'] / 1e6:10.3f}")
        for label, row in results["devices"].items():
            row["ratio_to_mitsuba"] = row["samples_per_second_median"] / theirs["samples_per_second_median"]
            # each round's ratio: ours and Mitsuba's renders of that round ran back to back
            row["ratio_to_mitsuba_per_round"] = [a / b for a, b in zip(rates[label], theirs_rates)]
            row["ratio_to_mitsuba_per_round_median"] = statistics.median(row["ratio_to_mitsuba_per_round"])
            echo(f"  {label[:58]}: {row['ratio_to_mitsuba']:.2f}x Mitsuba's samples/s (ratio of medians); "
                 f"per round {', '.join(f'{r:.2f}' for r in row['ratio_to_mitsuba_per_round'])}, "
                 f"median {row['ratio_to_mitsuba_per_round_median']:.2f}x")
    return results


def summary_rows(result: dict) -> list[dict]:
    """A row per variant of one scene's result: samples/s, Mitsuba's, the ratio, the lanes."""
    theirs = result.get("mitsuba")
    return [{"scene": result["scene"], "variant": label, "samples_per_second": row["samples_per_second_median"],
             "mitsuba_samples_per_second": theirs["samples_per_second_median"] if theirs else None,
             "ratio_to_mitsuba": row.get("ratio_to_mitsuba_per_round_median"),
             "lanes": row["lanes"] or 1, "lanes_reason": row["lanes_reason"],
             "mitsuba_lanes": theirs.get("lanes") if theirs else None}
            for label, row in result["devices"].items()]


def print_summary(rows, echo=print) -> None:
    """scene | ours | Mitsuba | ratio (median of the per-round ratios) | lanes; the variant column
    only when a scene has more than one."""
    several = len(rows) > len({row["scene"] for row in rows})
    scene_width = max([len("scene")] + [len(row["scene"]) for row in rows])
    echo(f"{'scene':<{scene_width}} " + (f"{'variant':<40} " if several else "")
         + f"{'ours Ms/s':>10} {'Mitsuba Ms/s':>12} {'ratio':>6} {'lanes':>7}")
    for row in rows:
        theirs, ratio = row["mitsuba_samples_per_second"], row["ratio_to_mitsuba"]
        echo(f"{row['scene']:<{scene_width}} " + (f"{row['variant'][:40]:<40} " if several else "")
             + f"{row['samples_per_second'] / 1e6:10.3f} " + (f"{theirs / 1e6:12.3f} " if theirs else f"{'-':>12} ")
             + (f"{ratio:5.2f}x " if ratio else f"{'-':>6} ") + f"{lanes_text(row):>7}")
    if any(row["ratio_to_mitsuba"] for row in rows):
        echo("ratio: ours / Mitsuba's samples/s, the median of the rounds' ratios (renders back to back); "
             "lanes: ours/Mitsuba's")


def lanes_text(row) -> str:
    """Our lane width, and Mitsuba's LLVM vector width where it is known: "16/16"."""
    theirs = row.get("mitsuba_lanes")
    return f"{row['lanes']}/{theirs}" if theirs else str(row["lanes"])
