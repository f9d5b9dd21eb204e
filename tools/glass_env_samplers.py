"""Variance per sample of two pixel classes of scenes/glass-env-preview.xml (issue 34) under our
samplers and Mitsuba's: the caustic on the plane and the pixels that see the sun through the
sphere, where stratification matters most.

    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \\
    python tools/glass_env_samplers.py --spp 64 --seeds 48 --max-depth 4 --bsdf dielectric \\
        --ours sobol,stratified --mitsuba multijitter,independent

Printed per sampler: the luminance variance over the seeds times spp, summed over the caustic's
pixels (the reference, the mean of all renders, above 1.5 in the image's lower quarter), over the
sun seen through the glass (above 10 in the upper three quarters) and over the rest.  An entry of
``--ours`` may add kernel defines after ``+``: ``sobol+AUDIT_INDEPENDENT_PIXEL`` draws the pixel
jitter, ``sobol+AUDIT_INDEPENDENT_LOBE`` every lobe choice (the glass's Fresnel branch),
``sobol+AUDIT_INDEPENDENT_BSDF`` every BSDF direction unstratified, the rest from the sampler (cl/render/path.h), to find which samples' stratification
a class's variance depends on.  The figures of docs/BENCHMARKS.md, "Glass under an environment
(issue 34)".
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))
sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

from glass_env_audit import LUM, mitsuba_renders, ours_renders  # noqa: E402

SCENE = str(Path(__file__).resolve().parents[1] / "scenes" / "glass-env-preview.xml")


def main(argv=None):
    from pyopencl_rt.device.devices import select_device

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--width", type=int, default=64)
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seeds", type=int, default=48)
    parser.add_argument("--max-depth", type=int, default=4)
    parser.add_argument("--bsdf", default="dielectric")
    parser.add_argument("--ours", default="sobol,stratified")
    parser.add_argument("--mitsuba", default="multijitter,independent")
    parser.add_argument("--mitsuba-variant", default="llvm_ad_rgb")
    args = parser.parse_args(argv)
    device = select_device("cpu")
    W, params, cfg = args.width, {"bsdf": args.bsdf}, {"max_depth": args.max_depth}
    res = {}
    for s in filter(None, args.ours.split(",")):
        sampler, *switches = s.split("+")  # sobol+AUDIT_INDEPENDENT_LOBE: with that kernel define
        res[f"ours {s}"] = ours_renders(SCENE, W, args.spp, args.seeds,
                                        {**cfg, "sampler": sampler, "defines": {d: 1 for d in switches}}, device,
                                        params=params) @ LUM
    for s in filter(None, args.mitsuba.split(",")):
        res[f"Mitsuba {s}"] = mitsuba_renders(SCENE, W, args.spp, args.seeds, cfg, s, args.mitsuba_variant,
                                              params=params) @ LUM
    ref = np.mean([a.mean(0) for a in res.values()], 0)
    low = np.arange(W)[:, None] >= W * 46 // 64
    caustic, sun = (ref > 1.5) & low, (ref > 10) & ~low
    print(f"caustic: {caustic.sum()} pixels, sun through the glass: {sun.sum()} pixels")
    for name, a in res.items():
        v = a.var(0, ddof=1) * args.spp
        print(f"{name:36s} variance x spp: caustic {v[caustic].sum():9.1f}  sun through the glass "
              f"{v[sun].sum():9.1f}  rest {v[~caustic & ~sun].sum():9.1f}", flush=True)


if __name__ == "__main__":
    main()
