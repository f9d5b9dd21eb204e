"""Render an exported scene with Mitsuba 3, progressively, in the Mitsuba interpreter.

    python pyopencl_rt/bench/mitsuba_runner.py SCENE.npz OUTDIR --checkpoints 1,2,4,8 [--variant llvm_ad_rgb]
        [--budget SECONDS] [--max-samples-per-call N]
    python -m pyopencl_rt.bench.mitsuba_runner ...      (where pyopencl_rt imports)

SCENE.npz comes from :func:`pyopencl_rt.bench.mitsuba_export.save_scene_npz`.  The runner first renders
1 spp once to compile (JIT) the kernels and reports that time apart (``warmup_seconds``); then it
renders batches with distinct seeds, accumulating a sample-weighted mean, and at each checkpoint
spp writes ``OUTDIR/mitsuba_<spp>.npy`` (H x W x 3 float32) with the cumulative render time.  A
batch is at most ``--max-samples-per-call`` samples (the JIT variants hold a whole call's
samples in memory).  With ``--sampler`` other than ``independent`` (``stratified``,
``multijitter``, ``ldsampler``: Mitsuba's sampler plugins, which stratify the samples of one
render), each checkpoint is a render of its own at that spp, timed alone: batches of such
samplers would not be stratified together; as those samplers round a sample count up (to a square,
a power of two, a prime's square), a checkpoint records the count rendered.  Such a curve renders
only the checkpoints of at least twice the samples of the one before (so that its renders add up
to twice its last at most), and ``--budget`` bounds all of its renders together, as it bounds an
independent curve's batches.  ``--seeds K``: K such curves, with batch seeds of their own
(``(--seed-offset + k) x 1000003`` up), taking turns at each checkpoint (so that they have the
same points and ``--budget`` bounds them together; ``OUTDIR/mitsuba_s<k>_<spp>.npy``).  The result is
``OUTDIR/mitsuba.json`` (``points``: the first curve's, ``seed_points``: every curve's).

    python pyopencl_rt/bench/mitsuba_runner.py SCENE.npz OUTDIR --serve --warmup-spp 64 [--variant ...]

serves timed renders for ``bench render --mitsuba`` (:class:`.mitsuba_host.MitsubaServer`): the scene
is loaded and rendered once at ``--warmup-spp`` (the JIT compilation), one JSON line describes it,
then every stdin line ``SPP`` is one more render of the whole image, timed until its pixels are on
the host and answered with one JSON line ``{"spp": SPP, "seconds": ...}``, so that the renders take
turns with ours and load on a shared machine falls on both alike.  Only numpy and mitsuba are needed:
``mitsuba_export.py`` is loaded from beside this file, not through the package.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import time


# a render of a stratifying sampler is one call: allow it this many times the batch limit
STRATIFIED_CALL_FACTOR = 8


def _export_module():
    here = os.path.dirname(os.path.abspath(__file__))
    spec = importlib.util.spec_from_file_location("_pyopencl_rt_mitsuba_export", os.path.join(here, "mitsuba_export.py"))
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


# Mitsuba's LLVM vector width for this process: Dr.Jit compiles for the host's widest vectors (16
# lanes with AVX-512).  "8" gives the width of our AVX2 lanes with the host's instruction set, as
# our PoCL build at 8 lanes has on the same host; "avx2" 8 lanes compiled for Haswell (AVX2, FMA,
# no AVX-512), the code Mitsuba runs on an AVX2 machine (docs/BENCHMARKS.md)
LANES_ENV = "PYOPENCL_RT_MITSUBA_LANES"
LANES_CHOICES = ("4", "8", "16", "avx2")
AVX2_FEATURES = (b"+sse,+sse2,+sse3,+ssse3,+sse4.1,+sse4.2,+popcnt,+avx,+avx2,+fma,+f16c,+bmi,+bmi2,+lzcnt,"
                 b"+movbe,+cx16,+xsave,-avx512f,-avx512vl,-avx512bw,-avx512dq,-avx512cd,-evex512")


def set_llvm_lanes(dr, variant):
    """Dr.Jit's LLVM target from ``$PYOPENCL_RT_MITSUBA_LANES`` (:data:`LANES_CHOICES`); returns
    the vector width its kernels use and the CPU they are compiled for (Nones outside llvm_*
    variants).  The setter is Dr.Jit's C function ``jit_llvm_set_target``, which its Python
    bindings do not expose, so it is called through ctypes on libdrjit-core; a Dr.Jit without it
    is reported, not ignored."""
    if not variant.startswith("llvm"):
        return None, None
    import ctypes

    wanted = os.environ.get(LANES_ENV, "").strip()
    if wanted and wanted not in LANES_CHOICES:
        raise SystemExit(f"${LANES_ENV}={wanted}: use one of {', '.join(LANES_CHOICES)}")
    core = ctypes.CDLL(os.path.join(os.path.dirname(dr.__file__), "libdrjit-core.so"))
    try:
        cpu, features = core._Z19jit_llvm_target_cpuv, core._Z24jit_llvm_target_featuresv
        width, set_target = core._Z21jit_llvm_vector_widthv, core._Z19jit_llvm_set_targetPKcS0_j
    except AttributeError:
        if wanted:
            raise SystemExit(f"${LANES_ENV}: this Dr.Jit ({dr.__version__}) has no jit_llvm_set_target")
        return None, None
    cpu.restype = features.restype = ctypes.c_char_p
    width.restype = ctypes.c_uint32
    if wanted == "avx2":
        set_target(b"haswell", AVX2_FEATURES, 8)
    elif wanted:
        set_target(cpu(), features(), int(wanted))
    return int(width()), cpu().decode()


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("outdir")
    parser.add_argument("--checkpoints", default="1,2,4,8,16")
    parser.add_argument("--variant", default="llvm_ad_rgb")
    parser.add_argument("--budget", type=float, default=None, help="stop before a batch that would start after this")
    parser.add_argument("--max-samples-per-call", type=int, default=1 << 22)
    parser.add_argument("--seed-offset", type=int, default=0, help="the first curve's batch seeds: this x 1000003 up")
    parser.add_argument("--seeds", type=int, default=1, help="curves, each with seeds of its own (the next offset)")
    parser.add_argument("--sampler", default="independent", help="Mitsuba's sampler plugin")
    parser.add_argument("--serve", action="store_true", help="time a render of each stdin line's spp")
    parser.add_argument("--warmup-spp", type=int, default=1, help="with --serve: the untimed first render's spp")
    args = parser.parse_args(argv)

    import numpy as np

    t_import = time.perf_counter()
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    lanes, target_cpu = set_llvm_lanes(dr, args.variant)
    t_loaded = time.perf_counter()
    export = _export_module()
    arrays = export.load_scene_npz(args.scene)
    os.makedirs(args.outdir, exist_ok=True)
    start = time.perf_counter()
    scene_dict = export.dict_from_arrays(arrays, mi, tmpdir=args.outdir)
    scene_dict["sensor"]["sampler"]["type"] = args.sampler
    scene = mi.load_dict(scene_dict)
    load_seconds = time.perf_counter() - start
    settings = json.loads(arrays["settings"])
    pixels = int(settings["width"]) * int(settings["height"])
    if args.serve:
        return serve(scene, args, {"renderer": "mitsuba", "version": mi.__version__, "drjit_version": dr.__version__,
                                   "variant": args.variant, "lanes": lanes, "target_cpu": target_cpu,
                                   "sampler": args.sampler, "width": int(settings["width"]),
                                   "height": int(settings["height"]), "max_depth": settings["max_depth"],
                                   "load_seconds": load_seconds, "import_seconds": t_loaded - t_import})

    start = time.perf_counter()
    image = mi.render(scene, spp=1, seed=(0xFFFF0000 + args.seed_offset) & 0xFFFFFFFF)
    np.asarray(image)
    warmup = time.perf_counter() - start

    checkpoints = sorted({int(value) for value in args.checkpoints.split(",") if value.strip()})
    per_call = max(1, args.max_samples_per_call // pixels)
    shape = (int(settings["height"]), int(settings["width"]), 3)
    seeds = max(1, args.seeds)
    seed_points = curves(scene, mi, np, args, checkpoints, seeds, per_call, pixels, shape)
    results = seed_points[0]
    info = {
        "renderer": "mitsuba", "version": mi.__version__, "drjit_version": dr.__version__,
        "variant": args.variant, "lanes": lanes, "target_cpu": target_cpu, "import_seconds": t_loaded - t_import,
        "load_seconds": load_seconds, "warmup_seconds": warmup, "points": results,
        "max_depth": settings["max_depth"], "rr_depth": settings["rr_depth"], "width": settings["width"],
        "height": settings["height"],
        "samples_per_call": per_call, "sampler": args.sampler,
        "seeds": seeds, "seed_offset": args.seed_offset,
        "seed_points": seed_points,
    }
    with open(os.path.join(args.outdir, "mitsuba.json"), "w") as fh:
        json.dump(info, fh, indent=2)
    print(json.dumps({"ok": True, "points": len(results)}))
    return 0


def curves(scene, mi, np, args, checkpoints, seeds, per_call, pixels, shape) -> list[list[dict]]:
    """``seeds`` curves taking turns: at each checkpoint every curve renders up to it (curve k with
    the batch seeds ``(--seed-offset + k) x 1000003`` up), so that they have the same points and
    ``--budget`` bounds all their renders together.  A point per curve and checkpoint: the image
    ``OUTDIR/mitsuba_<spp>.npy`` (the first curve's, named as before seeds) or
    ``mitsuba_s<k>_<spp>.npy``, and the curve's render time so far (a stratifying sampler's: that
    render's alone)."""
    stratified = args.sampler != "independent"
    accumulated = [np.zeros(shape, np.float64) for _ in range(seeds)]
    seed = [(args.seed_offset + k) * 1000003 for k in range(seeds)]
    seconds = [0.0] * seeds  # independent: each curve's render time so far; stratifying: its last render's
    spent = 0.0  # every render of every curve so far: what the budget bounds
    done = 0
    points = [[] for _ in range(seeds)]
    sampler = scene.sensors()[0].sampler()
    for checkpoint in checkpoints:
        target = checkpoint
        if stratified:  # one render per checkpoint and curve
            sampler.set_sample_count(target)
            target = int(sampler.sample_count())  # what the sampler renders: it may round up
            if target < 2 * done:  # twice the samples of the render before, at least
                continue
            if target * pixels > STRATIFIED_CALL_FACTOR * args.max_samples_per_call:
                break  # one call holds every sample of the render in memory
            # the next renders from the last ones' median: the first render of a new sample count
            # also pays Dr.Jit's compilation of its kernels
            projected = spent + seeds * sorted(seconds)[seeds // 2] * target / done if done else 0.0
        else:
            projected = spent * target / done if done else 0.0
        if args.budget is not None and projected > args.budget:
            break
        for k in range(seeds):
            if stratified:
                start = time.perf_counter()
                image = mi.render(scene, spp=target, seed=seed[k] & 0xFFFFFFFF)  # Mitsuba's seed: 32 bits
                accumulated[k] = np.asarray(image, np.float64)[..., :3] * target
                seconds[k] = time.perf_counter() - start
                spent += seconds[k]
                seed[k] += 1
            else:
                have = done
                while have < target:
                    batch = min(per_call, target - have)
                    start = time.perf_counter()
                    image = mi.render(scene, spp=batch, seed=seed[k] & 0xFFFFFFFF)
                    batch_image = np.asarray(image, np.float64)[..., :3]
                    elapsed = time.perf_counter() - start
                    seconds[k] += elapsed
                    spent += elapsed
                    accumulated[k] += batch_image * batch
                    have += batch
                    seed[k] += 1
            path = os.path.join(args.outdir, f"mitsuba_{target}.npy" if k == 0 else f"mitsuba_s{k}_{target}.npy")
            np.save(path, (accumulated[k] / target).astype(np.float32))
            points[k].append({"spp": target, "seconds": seconds[k], "image": path})
        done = target
    return points


def serve(scene, args, info) -> int:
    import drjit as dr
    import mitsuba as mi
    import numpy as np

    def timed(spp):
        start = time.perf_counter()
        image = mi.render(scene, spp=spp)
        dr.eval(image)
        np.asarray(image)
        return {"spp": spp, "seconds": time.perf_counter() - start}

    warmup = timed(args.warmup_spp)
    print(json.dumps({**info, "warmup": warmup}), flush=True)
    for line in sys.stdin:
        if line.strip():
            print(json.dumps(timed(int(line))), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
