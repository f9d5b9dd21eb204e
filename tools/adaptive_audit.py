"""Adaptive sampling against plain sampling at equal samples: the error and the cost of each.

    python tools/adaptive_audit.py scenes/mitsuba-cbox.toml --reference out/ref-mitsuba-cbox-128-8192.exr \\
        --width 128 --spp 256 --sampler sobol,independent --repeat 2

For each sampler, one Wavefront renders, interleaved ``--repeat`` times, a plain render of
``--spp`` and an adaptive one with the same budget (``--adaptive --spp N`` without a target: N
samples per pixel on average, docs/SAMPLING.md), and prints their relMSE against the reference
(eps = 1e-2), their wall and process-CPU seconds per sample, and the time-to-error gain: relMSE
falls as 1/time, so the gain is (plain relMSE x plain seconds) / (adaptive relMSE x adaptive
seconds).  Process-CPU time is the work done: on a machine shared with other jobs it is steadier
than the wall clock.  The figures of docs/BENCHMARKS.md "Adaptive sampling" come from this script.
"""
from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None):
    from pyopencl_rt.bench.convergence_analysis import metrics
    from pyopencl_rt.device.devices import select_device
    from pyopencl_rt.imageio import read_exr
    from pyopencl_rt.render import adaptive
    from pyopencl_rt.render.film import Film
    from pyopencl_rt.render.wavefront import Wavefront
    from pyopencl_rt.scene.loaders import load_scene

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--reference", required=True, help="EXR of the same size")
    parser.add_argument("--width", type=int, default=128, help="and height")
    parser.add_argument("--spp", type=int, default=256)
    parser.add_argument("--sampler", default="sobol,independent")
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--seed", type=int, default=1)
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args(argv)
    size = args.width
    reference = read_exr(args.reference).astype(np.float64)
    scene = load_scene(args.scene)
    print(f"{args.scene} {size}x{size}, {args.spp} spp (adaptive: on average), reference {args.reference}")
    print(f"{'sampler':<12} {'mode':<9} {'relMSE':>10} {'wall us/sample':>15} {'cpu us/sample':>14} "
          f"{'spp min..max':>14}")
    for sampler in args.sampler.split(","):
        wf = Wavefront(scene, select_device(args.device), width=size, height=size, seed=args.seed, sampler=sampler)
        warm = Film.new(size, size)
        wf.run(warm, passes=4, first_pass=1 << 20)  # PoCL's compilations, both kinds of launch
        wf.run(Film.new(size, size), passes=4, first_pass=1 << 20, pixels=np.arange(0, size * size, 2))
        rows = {"plain": [], "adaptive": []}
        for _ in range(args.repeat):
            for mode in rows:
                film = Film.new(size, size)
                cpu, wall = time.process_time(), time.perf_counter()
                if mode == "plain":
                    wf.run(film, passes=args.spp)
                else:
                    adaptive.run(wf, film, max_spp=args.spp)
                cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
                counts = film.pixel_counts()
                rows[mode].append((metrics(film.image(), reference)["relmse"], wall / counts.sum(), cpu / counts.sum(),
                                   counts.min(), counts.max()))
        for mode, runs in rows.items():
            relmse, wall, cpu = (float(np.median([r[k] for r in runs])) for k in range(3))
            print(f"{sampler:<12} {mode:<9} {relmse:>10.3e} {wall * 1e6:>15.3f} {cpu * 1e6:>14.3f} "
                  f"{f'{runs[0][3]}..{runs[0][4]}':>14}")
        (p_err, p_wall, p_cpu), (a_err, a_wall, a_cpu) = (
            [float(np.median([r[k] for r in rows[m]])) for k in range(3)] for m in ("plain", "adaptive"))
        print(f"{sampler:<12} gain: relMSE at equal samples {p_err / a_err:.2f}x; time to equal relMSE "
              f"{p_err * p_wall / (a_err * a_wall):.2f}x (wall), {p_err * p_cpu / (a_err * a_cpu):.2f}x (CPU)")


if __name__ == "__main__":
    main()
