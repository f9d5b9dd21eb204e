"""Error per sample of our path estimator against Mitsuba's on one Mitsuba XML scene that both
renderers load (issue 34: scenes/glass-env.xml), split by settings: the variance audit.

    DRJIT_LIBLLVM_PATH=/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1 \\
    python tools/glass_env_audit.py scenes/glass-env.xml --width 64 --spp 64 --seeds 12 \\
        --config '{}' --config '{"max_depth": 3}' --config '{"rr_depth": 100}' \\
        --config '{"compensated": false}' --mitsuba-sampler independent

Each ``--config`` is applied to both renderers alike where it can be: ``max_depth`` and
``rr_depth`` (Mitsuba's integrator takes them as the XML's parameters ``max_depth``/``rr_depth``,
so the scene must declare them with ``<default>``), and to ours only: ``sampler``, ``defines``
(extra kernel defines, as tools/variance_audit.py) and ``compensated`` (false: the environment's
complete light-sampling tables instead of the MIS-compensated ones, pyopencl_rt/render/lights.py).
Per config, over ``--seeds`` renders of each:

* relMSE x spp: the variance of each pixel over the seeds / (mean^2 + 1e-2), averaged over the
  image, times spp (the per-sample error; both estimators being unbiased, the variance over seeds
  is the mean squared error, with no reference noise in it), ours, Mitsuba's and the ratio;
* the same in luminance, and the mean |error| per render (|render - mean over both renderers'
  renders|, averaged over pixels and seeds) and its ratio;
* where the excess is: relMSE x spp over the pixels of the plane (the camera ray's first hit is
  the plane: a diffuse AOV of ours) and of the objects, and the share of the variance in the 1%
  of pixels with the largest variance (outliers);
* bright outliers: the (render, pixel) pairs whose luminance exceeds the reference's by more than
  2 (at 256 spp a single sample 512 above it: caustics and the sun seen through glass), their
  count and summed excess, ours and Mitsuba's;
* the image means and their z (a bias check over the seeds).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

LUM = np.array([0.2126, 0.7152, 0.0722])
OUTLIER = 2.0  # a render's pixel this far above the reference (luminance) is a bright outlier


def ours_renders(path, width, spp, seeds, config, device, first_seed=1000, params=None):
    """(seeds, W, W, 3) float64 renders of ours with config's overrides."""
    from pyopencl_rt.render import lights as lights_module
    from pyopencl_rt.render import wavefront as wavefront_module
    from pyopencl_rt.render.film import Film
    from pyopencl_rt.scene.loaders import load_scene

    config = dict(config)
    defines = config.pop("defines", {})
    compensated = config.pop("compensated", None)
    scene = load_scene(path, params or None)
    features, buffers = wavefront_module.kernel_features, wavefront_module.environment_buffers
    wavefront_module.kernel_features = lambda *a, **k: {**features(*a, **k), **defines}
    if compensated is not None:  # the wavefront asks for the compensated tables with integrator "path"
        wavefront_module.environment_buffers = lambda s, compensated=False, _on=bool(compensated): (
            lights_module.environment_buffers(s, compensated=compensated and _on))
    try:
        out = []
        for k in range(seeds):
            wf = wavefront_module.Wavefront(scene, device, width=width, height=width, seed=first_seed + k, **config)
            film = Film(width, width)
            wf.run(film, passes=spp)
            out.append(film.image()[..., :3].astype(np.float64))
    finally:
        wavefront_module.kernel_features, wavefront_module.environment_buffers = features, buffers
    return np.array(out)


def mitsuba_renders(path, width, spp, seeds, config, sampler, variant, first_seed=5000, params=None):
    import mitsuba as mi

    mi.set_variant(variant)
    params = {**(params or {}), "res": str(width), "spp": str(spp)}
    for key in ("max_depth", "rr_depth"):
        if key in config:
            params[key] = str(config[key])
    scene = mi.load_file(str(path), **params)
    sensor = scene.sensors()[0]
    if sampler != "independent":
        sensor = _with_sampler(mi, path, params, sampler)
    return np.array([np.array(mi.render(scene, sensor=sensor, spp=spp, seed=first_seed + k))[..., :3]
                     for k in range(seeds)], np.float64)


def _with_sampler(mi, path, params, sampler):
    """The scene's sensor with Mitsuba's ``sampler`` instead of the file's."""
    text = Path(path).read_text().replace('<sampler type="independent">', f'<sampler type="{sampler}">')
    tmp = Path(path).with_name(f".audit-{sampler}-{Path(path).name}")
    tmp.write_text(text)
    try:
        return mi.load_file(str(tmp), **params).sensors()[0]
    finally:
        tmp.unlink()


def plane_mask(path, width, device, params=None):
    """Pixels whose camera ray first hits a diffuse surface (the plane), from our albedo AOV:
    glass has no albedo there (its AOV is the tint, 1) - the plane's checker is 0.1 or 0.7."""
    import pyopencl_rt as rt

    r = rt.render_full(rt.load_scene(path, params or None), device=device, spp=4, width=width, height=width, seed=7,
                       aovs=["albedo"])
    albedo = np.asarray(r.layers["albedo"])[..., :3]
    return albedo.mean(-1) < 0.9


def stats(a, ref, spp, mask):
    var = a.var(0, ddof=1)
    rel = (var / (ref ** 2 + 1e-2)).mean(-1) * spp
    lum_var = (a @ LUM).var(0, ddof=1)
    lum_rel = lum_var / ((ref @ LUM) ** 2 + 1e-2) * spp
    excess = a @ LUM - (ref @ LUM)[None]
    bright = excess > OUTLIER
    flat = np.sort(rel.ravel())[::-1]
    top = flat[: max(1, len(flat) // 100)].sum() / flat.sum()
    return {"relmse_spp": float(rel.mean()), "relmse_spp_lum": float(lum_rel.mean()),
            "mae": float(np.abs(a - ref).mean()), "mse_lum": float(lum_var.mean()),
            "plane": float(rel[mask].mean()), "objects": float(rel[~mask].mean()) if (~mask).any() else 0.0,
            "top1pct_share": float(top), "outliers": int(bright.sum()), "outlier_excess": float(excess[bright].sum()),
            "mean": float(a.mean()),
            "mean_se": float(a.mean((1, 2, 3)).std(ddof=1) / np.sqrt(len(a)))}


def main(argv=None):
    from pyopencl_rt.device.devices import select_device

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene")
    parser.add_argument("--width", type=int, default=64, help="and height")
    parser.add_argument("--spp", type=int, default=64)
    parser.add_argument("--seeds", type=int, default=12)
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--config", action="append", required=True, help="JSON, see the docstring")
    parser.add_argument("--mitsuba-sampler", default="independent")
    parser.add_argument("--mitsuba-variant", default="llvm_ad_rgb")
    parser.add_argument("--no-mitsuba", action="store_true", help="ours only (the mean of ours as reference)")
    parser.add_argument("--define", action="append", default=[], help="NAME=VALUE: an XML parameter, both renderers")
    parser.add_argument("--save", help="a folder for the renders (.npy per config)")
    args = parser.parse_args(argv)
    device = select_device(args.device)
    params = dict(d.split("=", 1) for d in args.define)
    mask = plane_mask(args.scene, args.width, device, params)
    for index, text in enumerate(args.config):
        config = json.loads(text)
        ours = ours_renders(args.scene, args.width, args.spp, args.seeds, config, device, params=params)
        mits = None
        if not args.no_mitsuba:
            mits = mitsuba_renders(args.scene, args.width, args.spp, args.seeds, config, args.mitsuba_sampler,
                                   args.mitsuba_variant, params=params)
        ref = ours.mean(0) if mits is None else 0.5 * (ours.mean(0) + mits.mean(0))
        row = {"config": config, "define": params, "spp": args.spp, "seeds": args.seeds, "ours": stats(ours, ref, args.spp, mask)}
        if mits is not None:
            row["mitsuba"] = stats(mits, ref, args.spp, mask)
            row["ratio"] = {k: row["ours"][k] / max(row["mitsuba"][k], 1e-30)
                            for k in ("relmse_spp", "relmse_spp_lum", "mae", "mse_lum", "plane", "objects")}
            diff = ours.mean((1, 2, 3)) - mits.mean((1, 2, 3))
            row["mean_z"] = float(diff.mean() / np.sqrt(row["ours"]["mean_se"] ** 2 + row["mitsuba"]["mean_se"] ** 2))
        print(json.dumps(row), flush=True)
        if args.save:
            Path(args.save).mkdir(parents=True, exist_ok=True)
            np.save(Path(args.save) / f"ours-{index}.npy", ours.astype(np.float32))
            if mits is not None:
                np.save(Path(args.save) / f"mitsuba-{index}.npy", mits.astype(np.float32))


if __name__ == "__main__":
    main()
