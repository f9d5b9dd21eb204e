"""Error per sample of render settings, without a reference: the variance over seeds.

    python tools/variance_audit.py SCENE --width 64 --spp 64,256 --seeds 8 \\
        --config '{"sampler": "sobol"}' --config '{"sampler": "sobol", "defines": {"RR_NO_ETA": 1}}'

Every sampler is unbiased, so the variance of a pixel over renders with different seeds is its
mean squared error; averaged as relMSE (variance / (mean^2 + 1e-2), the mean over the seeds
standing in for the reference) it is the error of one render at that spp, with no reference
noise in it.  Each ``--config`` is ImageSettings overrides (sampler, rr_depth, max_depth, ...) and
optionally ``defines``: extra kernel defines, for the switches kept for such audits (RR_NO_ETA in
cl/render/path.h, SOBOL_LOG2_ROUND in pyopencl_rt/device/abi.py).  Also printed: the relMSE of
the image averaged over 2x2 pixel blocks (lower, relatively, when neighbouring pixels' errors
are anticorrelated: blue noise).  Seconds are render seconds per render, not interleaved: for
speed use ``pyopencl-rt bench render``.  The figures of docs/SAMPLING.md and the variance audit of
docs/BENCHMARKS.md come from this script.
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None):
    from pyopencl_rt.device.devices import select_device
    from pyopencl_rt.render import wavefront as wavefront_module
    from pyopencl_rt.render.film import Film
    from pyopencl_rt.scene.loaders import load_scene

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--width", type=int, default=64, help="and height")
    parser.add_argument("--spp", default="64,256", help="comma-separated, rendered progressively")
    parser.add_argument("--seeds", type=int, default=8)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--config", action="append", required=True, help="JSON: ImageSettings overrides + defines")
    args = parser.parse_args(argv)
    device = select_device(args.device)
    scene = load_scene(args.scene)
    spps = sorted(int(s) for s in args.spp.split(","))
    width = args.width
    features = wavefront_module.kernel_features
    try:
        for text in args.config:
            config = json.loads(text)
            defines = config.pop("defines", {})
            wavefront_module.kernel_features = lambda *a, _d=defines, **k: {**features(*a, **k), **_d}
            images, seconds = {n: [] for n in spps}, 0.0
            for seed in range(args.seeds):
                wf = wavefront_module.Wavefront(scene, device, width=width, height=width, seed=100 + seed, **config)
                film, done = Film(width, width), 0
                for n in spps:
                    seconds += wf.run(film, passes=n - done, first_pass=done).seconds
                    done = n
                    images[n].append(film.image().astype(np.float64))
            rows = {}
            for n in spps:
                a = np.array(images[n])
                blocks = a.reshape(len(a), width // 2, 2, width // 2, 2, 3).mean(axis=(2, 4))
                rows[n] = {"relmse": relmse_over_seeds(a), "relmse_2x2": relmse_over_seeds(blocks)}
            print(json.dumps({"config": config, "defines": defines, "seconds_per_render": seconds / args.seeds,
                              "spp": rows}), flush=True)
    finally:
        wavefront_module.kernel_features = features


def relmse_over_seeds(images: np.ndarray) -> float:
    mean = images.mean(axis=0)
    return float(np.mean(images.var(axis=0, ddof=1) / (mean * mean + 1e-2)))


if __name__ == "__main__":
    main()
