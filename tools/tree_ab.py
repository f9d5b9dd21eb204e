"""Samples/s of whole renders from two source trees, alternating in one loop: where the host code
changed too, so that tools/kernel_ab.py (which swaps cl/ alone) cannot compare them.

    git worktree add --detach /tmp/base REV
    python tools/tree_ab.py --base /tmp/base --new . scenes/cornell-spheres.toml,scenes/veach-mis.toml \\
        --rounds 5 --size 192 --spp 32

Each tree renders each scene once to warm PoCL's kernel cache (its first launch compiles), then
``rounds`` times, the order of the two alternating by round; printed per scene: the median
samples/s of each (the sidecar's ``samples_per_second``), their ratio and the median of the
per-round ratios.  Each render runs ``python -m pyopencl_rt.cli render`` in its tree with this
interpreter, so the tree's own package and kernels are used."""
from __future__ import annotations

import argparse
import json
import os
import statistics
import subprocess
import sys
import tempfile


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("scenes", help="comma-separated scene files (relative to --new, or absolute)")
    ap.add_argument("--base", required=True)
    ap.add_argument("--new", default=".")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--size", type=int, default=192)
    ap.add_argument("--spp", type=int, default=32)
    a = ap.parse_args()
    trees = {"base": os.path.abspath(a.base), "new": os.path.abspath(a.new)}
    out_dir = tempfile.mkdtemp(prefix="tree_ab_")
    env = dict(os.environ, POCL_CACHE_DIR=os.environ.get("POCL_CACHE_DIR", os.path.join(out_dir, "pocl")))

    def run(tag, scene):
        out = os.path.join(out_dir, f"{tag}.exr")
        subprocess.run([sys.executable, "-m", "pyopencl_rt.cli", "render", scene, "-o", out, "-q", "--width",
                        str(a.size), "--height", str(a.size), "--spp", str(a.spp), "--device", "cpu"],
                       cwd=trees[tag], env=env, check=True, capture_output=True)
        with open(out[:-4] + ".json") as f:
            return json.load(f)["samples_per_second"]

    for scene in a.scenes.split(","):
        path = scene if os.path.isabs(scene) else os.path.join(trees["new"], scene)
        for tag in trees:
            run(tag, path)
        rates = {t: [] for t in trees}
        for r in range(a.rounds):
            for tag in (list(trees) if r % 2 == 0 else list(trees)[::-1]):
                rates[tag].append(run(tag, path))
        base, new = statistics.median(rates["base"]), statistics.median(rates["new"])
        per_round = statistics.median(n / b for n, b in zip(rates["new"], rates["base"]))
        print(f"{os.path.basename(scene):28s} base {base / 1e6:.3f} Ms/s  new {new / 1e6:.3f} Ms/s  "
              f"new/base {new / base:.3f}  per round {per_round:.3f}", flush=True)


if __name__ == "__main__":
    main()
