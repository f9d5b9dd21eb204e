"""Samples/s of kernel variants, interleaved: the A/B measurement behind the CPU speed steps.

    python tools/kernel_ab.py scenes/mitsuba-cbox.toml --width 256 --spp 16 --rounds 7 \\
        --variant '{}' --variant '{"defines": {"RT_PORTABLE_BUILTINS": 1}}'

Each ``--variant`` is ImageSettings overrides (kernel_mode, sampler, max_depth, ...) and
optionally ``defines``: extra kernel defines (switches such as RT_PORTABLE_BUILTINS in
cl/cpu_builtins.h), and ``env``: environment variables set while the variant is built (such as
``{"PYOPENCL_RT_LANES": "0"}``, the megakernel with one path per work-item). Every variant is
built and warmed up first; then each round renders every variant once, in turn, so a shared
machine's load falls on all of them alike. Printed per variant: the median Msamples/s over the
rounds, and its ratio to the first variant's median, plus the median of the per-round ratios
(robust to load that drifts between rounds). The images are compared too: variants that should
compute the same thing report their max relative difference.
"""
from __future__ import annotations

import argparse
import json
import os
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
    parser.add_argument("--width", type=int, default=256, help="and height")
    parser.add_argument("--spp", type=int, default=16, help="per timed render")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--variant", action="append", required=True, help="JSON: ImageSettings overrides + defines")
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args(argv)
    device = select_device(args.device)
    scene = load_scene(args.scene)
    features = wavefront_module.kernel_features
    engines = []
    try:
        for text in args.variant:
            config = json.loads(text)
            defines = config.pop("defines", {})
            env = config.pop("env", {})
            saved = {k: os.environ.get(k) for k in env}
            os.environ.update(env)
            # the features are read when the kernels are built, in the constructor
            wavefront_module.kernel_features = lambda *a, _d=defines, **k: {**features(*a, **k), **_d}
            wf = wavefront_module.Wavefront(scene, device, width=args.width, height=args.width, **config)
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
            wf.run(Film(args.width, args.width), passes=1)  # warm-up
            engines.append((text, wf))
    finally:
        wavefront_module.kernel_features = features
    rates = np.zeros((args.rounds, len(engines)))
    images = [None] * len(engines)
    for r in range(args.rounds):
        for i, (_, wf) in enumerate(engines):
            film = Film(args.width, args.width)
            stats = wf.run(film, passes=args.spp)
            rates[r, i] = stats.samples / stats.seconds * 1e-6
            images[i] = film.image()
    medians = np.median(rates, axis=0)
    round_ratios = np.median(rates / rates[:, :1], axis=0)
    rows = []
    for i, (text, _) in enumerate(engines):
        diff = float(np.max(np.abs(images[i] - images[0]) / (np.abs(images[0]) + 1e-3)))
        rows.append({"variant": json.loads(text), "msamples_per_s": rates[:, i].tolist(),
                     "median": float(medians[i]), "ratio_of_medians": float(medians[i] / medians[0]),
                     "median_round_ratio": float(round_ratios[i]), "max_rel_image_diff_vs_first": diff})
        print(f"{medians[i]:7.3f} Msamples/s  x{medians[i] / medians[0]:.3f} (per round x{round_ratios[i]:.3f})"
              f"  image diff {diff:.2e}  {text}", flush=True)
    if args.json:
        Path(args.json).write_text(json.dumps({"scene": args.scene, "width": args.width, "spp": args.spp,
                                               "rounds": args.rounds, "device": device.name, "results": rows},
                                              indent=1))


if __name__ == "__main__":
    main()
