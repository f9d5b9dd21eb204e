"""Light samplers side by side (issue 34): for each scene, renders with light_sampler "power" and
"bvh" interleaved (seed by seed), and prints per sampler the relMSE over the seeds (eps 1e-2, as
tools/variance_audit.py) times the spp (the error of one sample per pixel: lower is better), the
render's seconds (kernel runs only, not builds or the light tree's host build) and samples per
second (the ratio: the median over the seeds of the back-to-back renders' ratio), and the image's mean with its standard error over the seeds (means_z: the two means'
difference in standard errors), as JSON lines; then the ratios power / bvh.

    PYTHONPATH=. python tools/light_sampler_ab.py scenes/many-lights.toml --width 96 --spp 16 --seeds 8
"""
from __future__ import annotations

import argparse
import dataclasses
import json
import time

import numpy as np

SAMPLERS = ("power", "bvh")


def relmse_over_seeds(images: np.ndarray) -> float:
    mean = images.mean(axis=0)
    return float(np.mean(images.var(axis=0, ddof=1) / (mean * mean + 1e-2)))


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("scenes", nargs="+")
    ap.add_argument("--width", type=int, default=96)
    ap.add_argument("--spp", type=int, default=16)
    ap.add_argument("--seeds", type=int, default=8)
    ap.add_argument("--device", default=None)
    args = ap.parse_args()

    from pyopencl_rt.device.devices import select_device
    from pyopencl_rt.render.film import Film
    from pyopencl_rt.render.wavefront import Wavefront
    from pyopencl_rt.scene.loaders import load_scene

    device = select_device(args.device)
    for path in args.scenes:
        scene = load_scene(path)
        st = scene.settings
        height = max(1, round(args.width * st.height / st.width))
        images = {s: [] for s in SAMPLERS}
        seconds = dict.fromkeys(SAMPLERS, 0.0)
        per_seed = {sampler: [] for sampler in SAMPLERS}
        host = dict.fromkeys(SAMPLERS, 0.0)
        for seed in range(args.seeds):
            for sampler in (SAMPLERS if seed % 2 == 0 else SAMPLERS[::-1]):  # interleaved, alternating order
                scene.settings = dataclasses.replace(st, light_sampler=sampler)
                t0 = time.perf_counter()
                wf = Wavefront(scene, device, width=args.width, height=height, seed=100 + seed)
                host[sampler] += time.perf_counter() - t0
                film = Film(args.width, height)
                wf.run(Film(args.width, height), passes=1, first_pass=args.spp)  # warm (another pass)
                taken = wf.run(film, passes=args.spp, first_pass=0).seconds
                seconds[sampler] += taken
                per_seed[sampler].append(taken)
                images[sampler].append(film.image().astype(np.float64))
        rows = {}
        for sampler in SAMPLERS:
            a = np.array(images[sampler])
            rows[sampler] = {"relmse_per_sample": relmse_over_seeds(a) * args.spp,
                             "mean": float(a.mean()),
                             "mean_stderr": float(a.mean(axis=(1, 2, 3)).std(ddof=1) / np.sqrt(len(a))),
                             "seconds": seconds[sampler] / args.seeds,
                             "samples_per_second": args.width * height * args.spp * args.seeds / seconds[sampler],
                             "setup_seconds_incl_first_build": host[sampler] / args.seeds}
        # the speed ratio: the median over the seeds of the two renders' ratio (each pair back to back:
        # robust to a shared machine's load drifting between seeds)
        rows["power_over_bvh"] = {"relmse_per_sample": rows["power"]["relmse_per_sample"] / rows["bvh"]["relmse_per_sample"],
                                  "samples_per_second": float(np.median(np.array(per_seed["bvh"])
                                                                        / np.array(per_seed["power"])))}
        rows["means_z"] = abs(rows["power"]["mean"] - rows["bvh"]["mean"]) / np.hypot(
            rows["power"]["mean_stderr"], rows["bvh"]["mean_stderr"])
        rows["power_over_bvh"]["time_to_error"] = (rows["power_over_bvh"]["relmse_per_sample"]
                                                   / rows["power_over_bvh"]["samples_per_second"])
        print(json.dumps({"scene": path, "width": args.width, "height": height, "spp": args.spp, "seeds": args.seeds,
                          "device": device.name.strip(), **rows}), flush=True)


if __name__ == "__main__":
    main()
