"""``pyopencl-rt bench convergence``: error against a reference as a function of render time.

It renders SCENE progressively (1, 2, 3, 4, 6, 8, 12, ... spp, one growing film per curve) on
each device x integrator x intersector, optionally with Mitsuba 3 beside it (:mod:`.mitsuba`),
and measures after each step the wall time of the passes so far (kernel build and a warm-up pass
reported apart) and the error against a reference image (the metrics, fits, schema, plot and
table are in :mod:`.convergence_analysis`).  Without ``--reference`` the reference is rendered
first (our ``path`` integrator, its own seed) and cached under ``~/.cache/pyopencl_rt/references``
keyed by a hash of the scene file's bytes, the settings that change the image and the kernel
sources.
"""
from __future__ import annotations

import hashlib
import json
import os
import platform
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import UserError
from .convergence_analysis import (EPS, FLOOR_FACTOR, SCHEMA, TARGETS, analyse, fit_slope, mean_points, metrics,
                                   print_table, reference_floor, seed_estimate, spp_schedule, time_to_reach, validate,
                                   write_plot)
from .mitsuba_host import DEFAULT_VARIANT, find_mitsuba_python, mitsuba_env, run_mitsuba_curve

# the names the tests and other callers reach through this module, the benchmark's public face
__all__ = ["EPS", "FLOOR_FACTOR", "MITSUBA_SAMPLERS", "SCHEMA", "TARGETS", "analyse", "fit_slope",
           "find_mitsuba_python", "mean_points", "metrics", "mitsuba_env", "print_table", "reference_floor",
           "run_convergence", "seed_estimate", "spp_schedule", "time_to_reach", "validate", "write_plot"]

# Mitsuba's sampler plugins a curve can use (those other than independent round a sample count up:
# each point then records the count rendered, see mitsuba_runner.py)
MITSUBA_SAMPLERS = ("independent", "stratified", "multijitter", "ldsampler", "orthogonal")
REFERENCE_SHARE = 0.3  # of the budget, when the reference must be rendered
REFERENCE_SEED = 0x5EED5EED
SECONDS_PER_CURVE_WITHOUT_BUDGET = 10.0


# --------------------------------------------------------------------------------------------
# reference


def cache_dir() -> Path:
    base = os.environ.get("PYOPENCL_RT_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "pyopencl_rt")
    return Path(base) / "references"


def reference_key(scene_path, settings: dict) -> str:
    """Cache key of a reference: the scene file, the settings, and the kernel sources, so that a
    cached reference does not outlive a change to the renderer."""
    from ..device.kernels import cl_dir

    digest = hashlib.sha256()
    digest.update(Path(scene_path).read_bytes())
    digest.update(json.dumps(settings, sort_keys=True).encode())
    for source in sorted(cl_dir().rglob("*")):
        if source.suffix in (".h", ".cl"):
            digest.update(source.name.encode())
            digest.update(source.read_bytes())
    return digest.hexdigest()[:24]


def load_or_render_reference(scene, scene_path, *, width, height, max_depth, rr_depth, device, seconds=None,
                             spp=None, use_cache=True, echo=print) -> dict:
    """The reference image (float64 H x W x 3), its variance (or None) and a description."""
    from ..render.api import render_full

    # independent samples: the film's variance is then the reference's error (the floor drawn on
    # the plot); with Sobol it would overstate it (docs/SAMPLING.md)
    settings = {"width": width, "height": height, "max_depth": max_depth, "rr_depth": rr_depth,
                "integrator": "path", "seed": REFERENCE_SEED, "sampler": "independent"}
    key = reference_key(scene_path, settings)
    folder = cache_dir()
    arrays_path, meta_path = folder / f"{key}.npz", folder / f"{key}.json"
    if use_cache and arrays_path.exists() and meta_path.exists():
        info = json.loads(meta_path.read_text())
        if spp is None or info.get("spp", 0) >= spp:
            with np.load(arrays_path) as cached:
                echo(f"reference: cached {arrays_path} ({info['spp']} spp)")
                return {"image": cached["image"], "variance": cached["variance"],
                        "info": {**info, "source": "cache", "path": str(arrays_path)}}
    echo(f"reference: rendering ({'%d spp' % spp if spp else '%.0f s' % seconds}) ...")
    result = render_full(scene, spp=spp, time_limit=None if spp else seconds, device=device, seed=REFERENCE_SEED,
                         width=width, height=height, max_depth=max_depth, rr_depth=rr_depth, integrator="path",
                         sampler="independent")
    if result.stats.passes < 2:
        raise UserError("the reference got fewer than 2 passes: raise --budget or give --reference-spp")
    info = {**settings, "spp": result.info["spp"], "seconds": result.info["render_seconds"],
            "device": result.info["device"], "key": key, "scene": str(scene_path)}
    image, variance = result.film.image().astype(np.float64), result.film.variance_of_mean()
    if use_cache:
        folder.mkdir(parents=True, exist_ok=True)
        partial = folder / f".{key}.{os.getpid()}.npz"  # renamed when complete: readers never see half a file
        np.savez_compressed(partial, image=image.astype(np.float32), variance=variance.astype(np.float32))
        os.replace(partial, arrays_path)
        meta_path.write_text(json.dumps(info, indent=2))
    return {"image": image, "variance": variance,
            "info": {**info, "source": "rendered", "path": str(arrays_path) if use_cache else None}}


# --------------------------------------------------------------------------------------------
# our renderer, progressively


def short_device(device) -> str:
    if "portable" in device.platform.name.lower():
        return "PoCL " + ("CPU" if "cpu" in str(device.type).lower() or device.type == 2 else device.name[:20])
    return device.name.strip()[:28]


def run_curve(scene, *, device, integrator, intersector, width, height, max_depth, rr_depth, reference, seconds,
              seed=1, seeds=None, denoise=False, sampler=None, adaptive=False, echo=print) -> dict:
    """One curve: a growing film, metrics after each step of :func:`spp_schedule`, until ``seconds``.
    ``denoise``: the film also sums the albedo and normal AOVs, and each point is Open Image
    Denoise's image of the film so far (its time: the passes so far plus that one denoising),
    with the raw image's errors beside it (``raw_rmse``, ``raw_relmse``).  ``sampler``: ours
    (docs/SAMPLING.md; default the scene's).  ``adaptive``: one adaptive render of ``seconds``
    without a target (it refines the pixels of largest estimated error, render/adaptive.py), a
    point each time its pass count reaches a step of the schedule; its spp is the mean per pixel.
    ``seeds`` (default ``[seed]``): one film per seed, rendered with that seed, the films taking
    turns at each step, ``seconds`` for them all (adaptive: one after the other, each for its
    share); with more than one, the curve's ``points`` are their mean
    (:func:`.convergence_analysis.mean_points`) and ``seed_curves`` has each seed's own."""
    from ..device.devices import device_label, select_device
    from ..render.aovs import GUIDES
    from ..render.film import Film
    from ..render.wavefront import Wavefront

    seeds = [int(s) for s in seeds] if seeds else [seed]
    device = select_device(device)
    start = time.perf_counter()
    wavefront = Wavefront(scene, device, width=width, height=height, integrator=integrator, max_depth=max_depth,
                          rr_depth=rr_depth, seed=seeds[0], intersector=intersector,
                          aovs=GUIDES if denoise else (), sampler=sampler)
    setup = time.perf_counter() - start
    start = time.perf_counter()
    # warm-up, not timed: PoCL compiles its work-group functions at the first launches, and again
    # for the first launch of a whole wave (measured: 2.4 s on the first curve of a program)
    wave_passes = -(-wavefront.wave_size // (width * height)) + 1
    wavefront.run(Film.new(width, height, denoise), passes=wave_passes, first_pass=1 << 20)
    if adaptive:  # and the launches over a pixel list
        wavefront.run(Film.new(width, height), passes=wave_passes, first_pass=1 << 20,
                      pixels=np.arange(0, width * height, 2))
    warmup = time.perf_counter() - start
    if adaptive:  # an adaptive render of its share of the time per seed, one after the other
        runs, total = [], 0.0
        for render_seed in seeds:
            wavefront.reseed(render_seed)
            points = []
            elapsed, _ = _adaptive_points(wavefront, Film.new(width, height), reference, seconds / len(seeds), points)
            runs.append({"seed": render_seed, "points": points})
            total += elapsed
    else:
        runs, total = _film_points(wavefront, seeds, reference, seconds, denoise)
    points = mean_points([r["points"] for r in runs], width * height)
    sampler = wavefront.settings.sampler
    label = (f"{short_device(device)} / {integrator} / {sampler}" + (" / embree" if intersector == "embree" else "")
             + (" + OIDN" if denoise else "") + (" / adaptive" if adaptive else ""))
    spp_done = points[-1]["spp"] if points else 0
    echo(f"  {label}: " + (f"{len(seeds)} seeds x " if len(seeds) > 1 else "")
         + f"{spp_done} spp in {total:.2f} s (build {wavefront.timings.get('build_seconds', 0):.2f} s, "
         f"warm-up {warmup:.2f} s)")
    curve = {"label": label, "renderer": "pyopencl_rt", "device": device_label(device), "integrator": integrator,
             "intersector": intersector, "sampler": sampler, "denoised": denoise, "adaptive": adaptive,
             "build_seconds": wavefront.timings.get("build_seconds"),
             "bvh_seconds": wavefront.timings.get("bvh_seconds"), "setup_seconds": setup, "warmup_seconds": warmup,
             "seeds": seeds, "points": points}
    if len(seeds) > 1:
        curve["seed_curves"] = runs
    return curve


def _film_points(wavefront, seeds, reference, seconds, denoise) -> tuple[list[dict], float]:
    """A film per seed, rendered along :func:`spp_schedule` with that seed, the films taking turns
    at each step (so that they have the same points, and load that changes falls on all alike),
    a point per film after each step, until the next step would overrun ``seconds`` for them all;
    returns ([{"seed", "points"} per seed], seconds)."""
    from ..render.aovs import GUIDES, aov_layers
    from ..render.film import Film

    width, height = wavefront.width, wavefront.height
    films = [Film.new(width, height, denoise) for _ in seeds]
    runs = [{"seed": s, "points": []} for s in seeds]
    elapsed = [0.0] * len(seeds)
    done, denoise_seconds = 0, 0.0
    for target in spp_schedule():
        if done and (sum(elapsed) * target / done + len(seeds) * denoise_seconds > seconds):
            break  # the next step would overrun the share
        for k, (render_seed, film, run) in enumerate(zip(seeds, films, runs)):
            wavefront.reseed(render_seed)  # the sample keys are (seed, pixel, pass): each film its seed
            stats = wavefront.run(film, passes=target - done, first_pass=done)
            elapsed[k] += stats.seconds
            point = {"spp": target, "seconds": elapsed[k], **metrics(film.image(), reference),
                     "samples_per_second": target * width * height / elapsed[k] if elapsed[k] > 0 else None}
            if denoise:
                from ..render.denoise import denoise as oidn

                t0 = time.perf_counter()
                guides = aov_layers(film, GUIDES)
                image = oidn(film.image(), guides["albedo"], guides["normal"])[0]
                denoise_seconds = time.perf_counter() - t0
                point = {**point, "seconds": elapsed[k] + denoise_seconds, **metrics(image, reference),
                         "raw_rmse": point["rmse"], "raw_relmse": point["relmse"], "denoise_seconds": denoise_seconds}
            run["points"].append(point)
        done = target
    return runs, sum(elapsed)


def _adaptive_points(wavefront, film, reference, seconds, points) -> tuple[float, int]:
    """An adaptive render of ``seconds`` into ``film``, its points appended to ``points``;
    returns (seconds, mean spp)."""
    from ..render import adaptive

    def observe(film, elapsed):
        counts = film.pixel_counts()
        points.append({"spp": int(round(counts.mean())), "seconds": elapsed, **metrics(film.image(), reference),
                       "samples_per_second": float(counts.sum()) / elapsed if elapsed > 0 else None,
                       "passes": film.passes, "spp_max": int(counts.max())})

    stats, _ = adaptive.run(wavefront, film, time_limit=seconds, observe=observe, stops=spp_schedule())
    return stats.seconds, points[-1]["spp"] if points else 0


# --------------------------------------------------------------------------------------------
# the command


def run_convergence(scene_path, *, devices=None, integrators=("path",), intersectors=("opencl",), reference=None,
                    reference_spp=None, budget=60.0, width=None, height=None, max_depth=None, compare=(),
                    mitsuba_python=None, mitsuba_variant=DEFAULT_VARIANT, llvm_path=None,
                    json_path="out/convergence.json", plot_path=None, use_cache=True, denoise=False,
                    samplers=(None,), mitsuba_samplers=("independent",), adaptive=False, seeds=1, first_seed=0,
                    echo=print) -> dict:
    """The benchmark.  ``samplers``: one curve of ours per sampler (None: the scene's), and with
    ``adaptive`` an adaptive one beside each (docs/SAMPLING.md, "Adaptive sampling"); with
    ``compare=("mitsuba",)``, one Mitsuba curve per entry of ``mitsuba_samplers`` (its sampler
    plugins, :data:`MITSUBA_SAMPLERS`).  ``seeds``: each curve is rendered with that many seeds
    (ours: render seeds 1 + ``first_seed`` + k; Mitsuba's: ``mitsuba_runner.py --seed-offset
    first_seed --seeds``), its share of the budget split between them, and its points are their
    mean (each seed's in ``seed_curves``): see :func:`.convergence_analysis.seed_estimate`."""
    from ..device.devices import resolve
    from ..imageio import read_exr, write_json
    from ..scene.loaders import load_scene

    start = time.perf_counter()
    seeds, first_seed = int(seeds), int(first_seed)
    if seeds < 1 or first_seed < 0:
        raise UserError(f"seeds {seeds}, first seed {first_seed}: expected at least 1 seed, from 0 up")
    if denoise:
        from ..render.denoise import _pyoidn

        _pyoidn()  # what to install, before the reference
    for peer in compare:
        if peer != "mitsuba":
            raise UserError(f"--compare {peer}: only 'mitsuba' is supported")
    scene = load_scene(scene_path)
    scene_settings = scene.settings
    width, height = int(width or scene_settings.width), int(height or scene_settings.height)
    max_depth = int(scene_settings.max_depth if max_depth is None else max_depth)
    rr_depth = int(scene_settings.rr_depth)
    chosen = resolve(list(devices)) if devices else resolve(["cpu"])
    skipped, notes = [], []
    mitsuba_python_found = None
    if "mitsuba" in compare:
        # Mitsuba is optional: when it cannot run, say why and how to fix it, and go on without it
        mitsuba_python_found, how = find_mitsuba_python(mitsuba_python, mitsuba_variant, llvm_path)
        if mitsuba_python_found is None:
            message = f"Mitsuba comparison skipped: {how}"
            echo(message)
            skipped.append({"what": "mitsuba", "why": message})
        else:
            echo(f"Mitsuba: {mitsuba_python_found} ({how})")

    if reference is not None:
        reference_image = read_exr(reference).astype(np.float64)
        if reference_image.shape != (height, width, 3):
            raise UserError(f"{reference}: {reference_image.shape[1]}x{reference_image.shape[0]}, "
                            f"but the benchmark renders {width}x{height}")
        ref = {"image": reference_image, "variance": None, "info": {"source": "file", "path": str(reference)}}
    else:
        ref = load_or_render_reference(scene, scene_path, width=width, height=height, max_depth=max_depth,
                                       rr_depth=rr_depth, device=chosen[0],
                                       seconds=None if budget is None else REFERENCE_SHARE * budget,
                                       spp=reference_spp if (reference_spp or budget is None) else None,
                                       use_cache=use_cache, echo=echo)
    floor = (reference_floor(ref["image"], ref["variance"]) if ref["variance"] is not None
             else {"mse": None, "relmse": None})

    jobs = [("ours", device, integrator, intersector, den, sampler, ad) for device in chosen
            for integrator in integrators for intersector in intersectors for sampler in samplers
            for den, ad in ((False, False),) + ((False, True),) * adaptive + ((True, False),) * denoise]
    if mitsuba_python_found:
        jobs += [("mitsuba", None, "path", "mitsuba", False, sampler, False) for sampler in mitsuba_samplers]
    curves = []
    for index, (renderer, device, integrator, intersector, den, sampler, ad) in enumerate(jobs):
        if budget is not None:
            left = budget - (time.perf_counter() - start)
            # a share of what is left, less a guess of the fixed costs (build, warm-up, start-up)
            share = max(0.5, left / (len(jobs) - index) - (4.0 if renderer == "mitsuba" else 1.0))
        else:
            share = SECONDS_PER_CURVE_WITHOUT_BUDGET
        if renderer == "ours":
            curves.append(run_curve(scene, device=device, integrator=integrator, intersector=intersector, width=width,
                                    height=height, max_depth=max_depth, rr_depth=rr_depth, reference=ref["image"],
                                    seconds=share, denoise=den, sampler=sampler, adaptive=ad,
                                    seeds=[1 + first_seed + k for k in range(seeds)], echo=echo))
        else:
            workdir = tempfile.mkdtemp(prefix="pyopencl_rt_mitsuba_")
            try:
                curves.append(run_mitsuba_curve(scene, mitsuba_python_found, width=width, height=height,
                                                max_depth=max_depth, rr_depth=rr_depth, reference=ref["image"],
                                                seconds=share, variant=mitsuba_variant, workdir=workdir,
                                                llvm_path=llvm_path, sampler=sampler, seeds=seeds,
                                                first_seed=first_seed, echo=echo))
            finally:
                shutil.rmtree(workdir, ignore_errors=True)
    analyse(curves, floor)
    result = {
        "schema": SCHEMA, "scene": str(scene_path), "width": width, "height": height, "max_depth": max_depth,
        "rr_depth": rr_depth, "eps": EPS, "budget_seconds": None if budget is None else float(budget),
        "seeds": seeds, "first_seed": first_seed,
        "host": platform.node(), "cpu_count": os.cpu_count(), "created": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "reference": {**ref["info"], "floor": floor}, "curves": curves, "skipped": skipped, "notes": notes,
        "total_seconds": 0.0,
    }
    json_path = Path(json_path)
    json_path.parent.mkdir(parents=True, exist_ok=True)
    plot_path = Path(plot_path) if plot_path else json_path.with_suffix(".png")
    result["total_seconds"] = time.perf_counter() - start
    result["plot"] = write_plot(plot_path, result)
    if result["plot"] is None:
        message = "plot skipped: matplotlib is not installed (pip install 'pyopencl-rt[plot]')"
        echo(message)
        skipped.append({"what": "plot", "why": message})
    validate(result)
    write_json(json_path, result)
    print_table(result, echo)
    echo(f"wrote {json_path}" + (f" and {result['plot']}" if result["plot"] else ""))
    return result
