"""Render an exported scene with Mitsuba 3, progressively, in the Mitsuba interpreter.

    python pyopencl_rt/mitsuba_runner.py SCENE.npz OUTDIR --checkpoints 1,2,4,8 [--variant llvm_ad_rgb]
        [--budget SECONDS] [--max-samples-per-call N]
    python -m pyopencl_rt.mitsuba_runner ...      (where pyopencl_rt imports)

SCENE.npz comes from :func:`pyopencl_rt.mitsuba_export.save_scene_npz`.  The runner first renders
1 spp once to compile (JIT) the kernels and reports that time apart (``warmup_seconds``); then it
renders batches with distinct seeds, accumulating a sample-weighted mean, and at each checkpoint
spp writes ``OUTDIR/mitsuba_<spp>.npy`` (H x W x 3 float32) with the cumulative render time.  A
batch is at most ``--max-samples-per-call`` samples (the JIT variants hold a whole call's
samples in memory).  The result is ``OUTDIR/mitsuba.json``.  Only numpy and mitsuba are needed:
``mitsuba_export.py`` is loaded from beside this file, not through the package.
"""
from __future__ import annotations

import argparse
import importlib.util
import json
import os
import sys
import time


def _export_module():
    here = os.path.dirname(os.path.abspath(__file__))
    spec = importlib.util.spec_from_file_location("_pyopencl_rt_mitsuba_export", os.path.join(here, "mitsuba_export.py"))
    mod = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(mod)
    return mod


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scene")
    ap.add_argument("outdir")
    ap.add_argument("--checkpoints", default="1,2,4,8,16")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    ap.add_argument("--budget", type=float, default=None, help="stop before a batch that would start after this")
    ap.add_argument("--max-samples-per-call", type=int, default=1 << 22)
    ap.add_argument("--seed-offset", type=int, default=0)
    args = ap.parse_args(argv)

    import numpy as np

    t_import = time.perf_counter()
    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    t_loaded = time.perf_counter()
    ex = _export_module()
    arrays = ex.load_scene_npz(args.scene)
    os.makedirs(args.outdir, exist_ok=True)
    t0 = time.perf_counter()
    scene = mi.load_dict(ex.dict_from_arrays(arrays, mi, tmpdir=args.outdir))
    load_seconds = time.perf_counter() - t0
    s = json.loads(arrays["settings"])
    pixels = int(s["width"]) * int(s["height"])

    t0 = time.perf_counter()
    img = mi.render(scene, spp=1, seed=0xFFFF0000 + args.seed_offset)
    np.asarray(img)
    warmup = time.perf_counter() - t0

    checkpoints = sorted({int(c) for c in args.checkpoints.split(",") if c.strip()})
    per_call = max(1, args.max_samples_per_call // pixels)
    acc = np.zeros((int(s["height"]), int(s["width"]), 3), np.float64)
    done = 0
    seconds = 0.0
    seed = args.seed_offset * 1000003
    results = []
    for target in checkpoints:
        stop = False
        while done < target:
            if args.budget is not None and seconds >= args.budget:
                stop = True
                break
            n = min(per_call, target - done)
            t0 = time.perf_counter()
            img = mi.render(scene, spp=n, seed=seed)
            arr = np.asarray(img, np.float64)[..., :3]
            seconds += time.perf_counter() - t0
            acc += arr * n
            done += n
            seed += 1
        if stop:
            break
        path = os.path.join(args.outdir, f"mitsuba_{target}.npy")
        np.save(path, (acc / done).astype(np.float32))
        results.append({"spp": target, "seconds": seconds, "image": path})
    info = {
        "renderer": "mitsuba", "version": mi.__version__, "drjit_version": dr.__version__,
        "variant": args.variant, "import_seconds": t_loaded - t_import,
        "load_seconds": load_seconds, "warmup_seconds": warmup, "points": results,
        "max_depth": s["max_depth"], "rr_depth": s["rr_depth"], "width": s["width"], "height": s["height"],
        "samples_per_call": per_call,
    }
    with open(os.path.join(args.outdir, "mitsuba.json"), "w") as fh:
        json.dump(info, fh, indent=2)
    print(json.dumps({"ok": True, "points": len(results)}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
