"""``pyopencl-rt bench samplers``: error per sample of each sampler at equal spp, ours beside Mitsuba 3.

For SCENE it renders a reference (Mitsuba's ``independent`` sampler at ``reference_spp`` with
``--compare mitsuba``, else ours, independent, cached as :mod:`.convergence` caches it), then
``seeds`` renders at ``spp`` per sampler of ours (:mod:`pyopencl_rt.render.settings` samplers)
and, with Mitsuba, per Mitsuba sampler plugin (each render one call, so that the plugin
stratifies all its samples), and reports relMSE (eps = 1e-2, as ``bench convergence``) against
the reference: the median over seeds, and each render's seconds.  The reference's own noise (its
variance over batches of passes) is reported as the floor every figure contains.

This is the table of docs/BENCHMARKS.md "Less error per sample"; time to a given error is
``bench convergence``'s.
"""
from __future__ import annotations

import json
import shutil
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import UserError
from .convergence_analysis import EPS, metrics
from .mitsuba_host import DEFAULT_VARIANT, HERE, failure_reason, mitsuba_env, require_mitsuba_python

MITSUBA_SAMPLERS = ("independent", "stratified", "multijitter", "ldsampler")
REFERENCE_CALL = 64  # spp per Mitsuba call of the reference
REFERENCE_BATCHES = 32  # the reference's variance comes from the means of this many batches
REFERENCE_SEEDS = 4001  # Mitsuba seeds of the reference: this * 1000003 + batch (fits 32 bits)


def _mitsuba_run(python, scene_npz, workdir, *, variant, llvm_path, checkpoints, sampler, seed_offset,
                 max_samples_per_call=None):
    import subprocess

    command = [python, str(HERE / "mitsuba_runner.py"), str(scene_npz), str(workdir), "--variant", variant,
               "--checkpoints", ",".join(str(c) for c in checkpoints), "--sampler", sampler,
               "--seed-offset", str(seed_offset)]
    if max_samples_per_call:
        command += ["--max-samples-per-call", str(max_samples_per_call)]
    run = subprocess.run(command, capture_output=True, text=True, env=mitsuba_env(llvm_path))
    if run.returncode != 0:
        raise UserError(failure_reason(run.stdout + run.stderr, variant))
    return json.loads((Path(workdir) / "mitsuba.json").read_text())


def mitsuba_reference(python, scene_npz, workdir, *, spp, width, height, variant, llvm_path, echo=print) -> dict:
    """Mean and variance of the mean of ``spp`` independent samples, from REFERENCE_BATCHES batches
    (each batch ends at a checkpoint of the runner, which saves the mean of the batches so far)."""
    batch = max(1, spp // REFERENCE_BATCHES)
    checkpoints = [batch * (k + 1) for k in range(REFERENCE_BATCHES)]
    start = time.perf_counter()
    info = _mitsuba_run(python, scene_npz, workdir, variant=variant, llvm_path=llvm_path, checkpoints=checkpoints,
                        sampler="independent", seed_offset=REFERENCE_SEEDS,
                        max_samples_per_call=min(batch, REFERENCE_CALL) * width * height)
    means = [np.load(p["image"]).astype(np.float64) for p in info["points"]]
    # batch k's own mean from the running means: (k+1) m_(k+1) - k m_k
    own = [means[0]] + [(k + 1) * means[k] - k * means[k - 1] for k in range(1, len(means))]
    own = np.array(own)
    image = own.mean(axis=0)
    variance = own.var(axis=0, ddof=1) / len(own)
    echo(f"reference: Mitsuba {info['version']} {variant}, {len(own) * batch} spp in "
         f"{time.perf_counter() - start:.0f} s")
    return {"image": image, "variance": variance,
            "info": {"renderer": "mitsuba", "version": info["version"], "variant": variant, "spp": len(own) * batch}}


def run_samplers(scene_path, *, spp=256, samplers=("sobol", "stratified", "independent"), seeds=2, device=None,
                 width=None, height=None, reference_spp=16384, compare=(), mitsuba_samplers=MITSUBA_SAMPLERS,
                 mitsuba_python=None, mitsuba_variant=DEFAULT_VARIANT, llvm_path=None, json_path=None,
                 use_cache=True, save_reference=None, echo=print) -> dict:
    """The table (see the module docstring); ``save_reference``: also write the reference image as
    an OpenEXR there (``bench convergence --reference`` takes it)."""
    from ..device.devices import resolve
    from ..render.api import render_full
    from ..render.settings import ImageSettings
    from ..scene.loaders import load_scene
    from .convergence import load_or_render_reference
    from .convergence_analysis import reference_floor
    from .mitsuba_export import save_scene_npz, scene_arrays

    for peer in compare:
        if peer != "mitsuba":
            raise UserError(f"--compare {peer}: only 'mitsuba' is supported")
    scene = load_scene(scene_path)
    settings = ImageSettings.resolve(scene, width=width, height=height)
    width, height = settings.width, settings.height
    device = resolve([device] if device else ["cpu"])[0]
    python = None
    workdir = Path(tempfile.mkdtemp(prefix="pyopencl_rt_samplers_"))
    try:
        if "mitsuba" in compare:
            python = require_mitsuba_python(mitsuba_python, mitsuba_variant, llvm_path, echo)
            scene_npz = workdir / "scene.npz"
            save_scene_npz(scene_npz, scene_arrays(scene, settings, spp=spp))
            ref = mitsuba_reference(python, scene_npz, workdir / "reference", spp=reference_spp, width=width,
                                    height=height, variant=mitsuba_variant, llvm_path=llvm_path, echo=echo)
        else:
            ref = load_or_render_reference(scene, scene_path, width=width, height=height,
                                           max_depth=settings.max_depth, rr_depth=settings.rr_depth, device=device,
                                           spp=reference_spp, use_cache=use_cache, echo=echo)
        floor = reference_floor(ref["image"], ref["variance"])
        if save_reference:
            from ..imageio import write_exr

            Path(save_reference).parent.mkdir(parents=True, exist_ok=True)
            write_exr(save_reference, ref["image"].astype(np.float32))
            echo(f"wrote {save_reference}")
        rows = []
        for sampler in samplers:
            runs = []
            for seed in range(seeds):
                result = render_full(scene, spp=spp, device=device, seed=1 + seed, sampler=sampler,
                                     width=width, height=height)
                runs.append({"seed": 1 + seed, "seconds": result.info["render_seconds"],
                             **metrics(result.image, ref["image"])})
            rows.append(_row("pyopencl_rt", sampler, spp, runs, echo))
        for sampler in (mitsuba_samplers if python else ()):
            runs = []
            for seed in range(seeds):
                info = _mitsuba_run(python, scene_npz, workdir / f"{sampler}{seed}", variant=mitsuba_variant,
                                    llvm_path=llvm_path, checkpoints=[spp], sampler=sampler, seed_offset=1 + seed,
                                    max_samples_per_call=spp * width * height)
                if not info["points"]:
                    raise UserError(f"Mitsuba's {sampler} rendered nothing at {spp} spp")
                point = info["points"][-1]
                runs.append({"seed": 1 + seed, "seconds": point["seconds"],
                             **metrics(np.load(point["image"]).astype(np.float64), ref["image"])})
            rows.append(_row(f"mitsuba {mitsuba_variant}", sampler, spp, runs, echo))
    finally:
        shutil.rmtree(workdir, ignore_errors=True)
    result = {"scene": str(scene_path), "width": width, "height": height, "spp": spp, "eps": EPS,
              "max_depth": settings.max_depth, "rr_depth": settings.rr_depth,
              "reference": {**ref["info"], "floor": floor}, "rows": rows,
              "created": time.strftime("%Y-%m-%dT%H:%M:%S")}
    echo(f"reference noise in every figure: relMSE {floor['relmse']:.3g}")
    if json_path:
        from .timing import write_results

        write_results(json_path, result, echo)
    return result


def _row(renderer, sampler, spp, runs, echo) -> dict:
    relmse = float(np.median([r["relmse"] for r in runs]))
    seconds = float(np.median([r["seconds"] for r in runs]))
    each = ", ".join(f"{r['relmse']:.3e}" for r in runs)
    echo(f"{renderer:<26} {sampler:<12} {spp:>5} spp  relMSE {relmse:.3e}  ({each})  {seconds:.1f} s")
    return {"renderer": renderer, "sampler": sampler, "spp": spp, "relmse": relmse, "seconds": seconds, "runs": runs}
