"""Samples/s of kernel variants, interleaved: the A/B measurement behind the CPU speed steps.

    python tools/kernel_ab.py scenes/mitsuba-cbox.toml --width 256 --spp 16 --rounds 7 \\
        --variant '{}' --variant '{"defines": {"RT_PORTABLE_BUILTINS": 1}}'

Each ``--variant`` is ImageSettings overrides (kernel_mode, sampler, max_depth, ...) and
optionally ``defines``: extra kernel defines (switches such as RT_PORTABLE_BUILTINS in
cl/cpu_builtins.h), and ``env``: environment variables set while the variant is built (such as
``{"PYOPENCL_RT_LANES": "0"}``, the megakernel with one path per work-item), ``device``: another
device than ``--device`` for that variant (``"intel"``: two OpenCL implementations side by side), and, where it names a
variable the loaders read (``PYOPENCL_RT_INSTANCING``: flattened or two-level instances), while
its own copy of the scene is loaded, and ``cl``: the
kernel sources of another tree for that variant (a folder holding ``accel/``, ``render/``, ...,
as ``/tmp/wt-x/cl``), or ``rev``: a git revision of this repository whose ``cl/`` is taken
(``git archive``), so that kernel changes are compared in one process:

    python tools/kernel_ab.py scenes/textured-sky.toml --variant '{"rev": "main"}' --variant '{}'

(only the kernels differ there: the host code is this tree's, so the revision's kernels must take
this tree's ABI). Every variant is
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
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


ROOT = Path(__file__).resolve().parents[1]


def revision_cl(rev: str, scratch: Path) -> Path:
    """The cl/ folder of git revision ``rev``, extracted under ``scratch``."""
    out = scratch / rev.replace("/", "_")
    out.mkdir(parents=True, exist_ok=True)
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", rev, "cl"], check=True, capture_output=True).stdout
    subprocess.run(["tar", "-x", "-C", str(out)], input=archive, check=True)
    return out / "cl"


def main(argv=None):
    from pyopencl_rt.device import kernels as kernels_module
    from pyopencl_rt.device.devices import select_device
    from pyopencl_rt.render import wavefront as wavefront_module
    from pyopencl_rt.render.film import Film
    from pyopencl_rt.scene.loaders import load_scene
    from pyopencl_rt.scene.loaders.instancing import INSTANCING_ENV

    loader_env = {INSTANCING_ENV}  # read when a file is loaded, not when the kernels are built

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
    own_cl_dir = kernels_module.cl_dir
    scratch = Path(tempfile.mkdtemp(prefix="kernel_ab_"))
    engines = []
    try:
        for index, text in enumerate(args.variant):
            config = json.loads(text)
            defines = config.pop("defines", {})
            env = config.pop("env", {})
            tree = config.pop("cl", None)
            rev = config.pop("rev", None)
            own_device = select_device(config.pop("device")) if "device" in config else device
            if rev is not None:
                tree = revision_cl(rev, scratch)
            if tree is not None:
                # another tree's kernels: read while this variant builds; the define keeps its
                # programs apart from the others' in the runtime's cache
                kernels_module.cl_dir = lambda _t=Path(tree).resolve(): _t
                defines = {**defines, "RT_KERNEL_AB_TREE": index + 1}
            saved = {k: os.environ.get(k) for k in env}
            os.environ.update(env)
            own_scene = load_scene(args.scene) if loader_env & set(env) else scene
            # the features are read when the kernels are built, in the constructor
            wavefront_module.kernel_features = lambda *a, _d=defines, **k: {**features(*a, **k), **_d}
            wf = wavefront_module.Wavefront(own_scene, own_device, width=args.width, height=args.width, **config)
            for k, v in saved.items():
                if v is None:
                    os.environ.pop(k, None)
                else:
                    os.environ[k] = v
            wf.run(Film(args.width, args.width), passes=1)  # warm-up
            engines.append((text, wf))
            kernels_module.cl_dir = own_cl_dir
    finally:
        wavefront_module.kernel_features = features
        kernels_module.cl_dir = own_cl_dir
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
