"""Error per sample, ours against Mitsuba 3 on the same scene (our export), without a reference:
the variance of each pixel over renders with different seeds, per 8x8-pixel block.

    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \\
    python tools/variance_vs_mitsuba.py scenes/materials.toml --width 64 --spp 64 --seeds 16 \\
        --sampler independent --mitsuba-sampler independent

Both renderers are unbiased, so a pixel's variance over seeds is its mean squared error; printed
as relMSE times spp (variance / (mean^2 + 1e-2), the mean of both renderers' means standing in
for the reference: the per-sample error, which the time to a target error is proportional to),
for the whole image and per block of 8x8 blocks, and their ratio ours / Mitsuba's: above 1 where
our estimator (or sampler) leaves more noise per sample.  One render's relMSE is heavy-tailed
(a firefly moves it by tens of percent), so use several seeds; the time-to-error curves of
``bench set`` are one render per point.  The images' means are printed too (a bias check).
"""
from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None):
    import pyopencl_rt as rt
    from pyopencl_rt.bench.mitsuba_export import to_mitsuba_dict
    from pyopencl_rt.render.settings import ImageSettings

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--width", type=int, default=64, help="and height (a multiple of 8)")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seeds", type=int, default=16)
    parser.add_argument("--sampler", default="sobol", help="ours: sobol, stratified, independent")
    parser.add_argument("--mitsuba-sampler", default="independent")
    parser.add_argument("--mitsuba-variant", default="llvm_ad_rgb")
    args = parser.parse_args(argv)
    W, spp = args.width, args.spp
    scene = rt.load_scene(args.scene)
    ours = np.array([rt.render_full(scene, device="cpu", spp=spp, width=W, height=W, seed=1000 + k,
                                    sampler=args.sampler).film.image()[..., :3] for k in range(args.seeds)], np.float64)
    import mitsuba as mi

    mi.set_variant(args.mitsuba_variant)
    d = to_mitsuba_dict(scene, ImageSettings.resolve(scene, width=W, height=W), spp=spp)
    d["sensor"]["sampler"]["type"] = args.mitsuba_sampler
    ms = mi.load_dict(d)
    mits = np.array([np.array(mi.render(ms, spp=spp, seed=5000 + k))[..., :3] for k in range(args.seeds)], np.float64)
    ref = 0.5 * (ours.mean(0) + mits.mean(0))
    per = [(a.var(0, ddof=1) / (ref ** 2 + 1e-2)).mean(-1) * spp for a in (ours, mits)]
    print(f"relMSE x spp: ours ({args.sampler}) {per[0].mean():.4f}, Mitsuba ({args.mitsuba_sampler}) "
          f"{per[1].mean():.4f}, ratio {per[0].mean() / per[1].mean():.3f}; means {ours.mean():.5f} / {mits.mean():.5f}")
    B = W // 8
    blocks = [p.reshape(8, B, 8, B).mean((1, 3)) for p in per]
    np.set_printoptions(precision=2, suppress=True, linewidth=160)
    print("per block, ours:\n", blocks[0], "\nMitsuba:\n", blocks[1], "\nratio:\n", blocks[0] / np.maximum(blocks[1], 1e-9))
    print("block mean radiance:\n", ref.mean(-1).reshape(8, B, 8, B).mean((1, 3)))


if __name__ == "__main__":
    main()
