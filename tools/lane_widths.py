"""Which lane width is fastest on this host, per OpenCL implementation: the measurement behind
the width rule (pyopencl_rt/device/isa.py: PoCL's simd_width, INTEL_CPU_WIDTH).

    python tools/lane_widths.py --json docs/bench/lane-widths-<host>.json

For every x86 CPU device present (PoCL, Intel's CPU runtime, ...), every width its LaneRule
builds alike (one path per work-item, 8, 16) is a variant of tools/kernel_ab.py; all variants of
all implementations render each scene of the set in turn, round after round, in one process (a
shared machine's load falls on all alike).  Printed: per scene the samples/s of each variant, then
per implementation the median over scenes of each width's ratio to one path per work-item, the
fastest width, and what the rule gives now; the images of each scene are compared (the widths
and implementations compute the same samples: a difference above rounding is a bug).
"""
from __future__ import annotations

import argparse
import json
import platform
import subprocess
import sys
import tempfile
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tools"))

SCENES = ("scenes/mitsuba-cbox.toml", "scenes/mitsuba-cbox-spheres.toml", "scenes/textured-sky.toml")


def cpu_model() -> str:
    try:
        for line in open("/proc/cpuinfo"):
            if line.startswith("model name"):
                return line.split(":", 1)[1].strip()
    except OSError:
        pass
    return platform.processor() or "unknown CPU"


def main(argv=None):
    import kernel_ab

    from pyopencl_rt.device import devices, isa

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scenes", nargs="*", default=list(SCENES))
    parser.add_argument("--width", type=int, default=256, help="image width and height")
    parser.add_argument("--spp", type=int, default=16, help="per timed render")
    parser.add_argument("--rounds", type=int, default=5)
    parser.add_argument("--json", help="write the results here")
    args = parser.parse_args(argv)

    variants = []  # (implementation, spec, lanes)
    rules = {}
    for entry in devices.all_devices():
        device = entry[2]
        if not isa.x86_cpu(device):
            continue
        spec = devices.describe(entry).index
        rule = isa.lane_rule(device)
        rules[spec] = rule
        for lanes in (0, *rule.widths):
            variants.append((rule.implementation, spec, lanes))
    if not variants:
        sys.exit("no x86 CPU OpenCL device found")
    results = {"cpu": cpu_model(), "scenes": {}, "rules": {s: {"implementation": r.implementation, "target": r.describe,
                                                              "default": r.default, "reason": r.reason}
                                                          for s, r in rules.items()}}
    for scene in args.scenes:
        with tempfile.TemporaryDirectory() as tmp:
            out = Path(tmp) / "ab.json"
            kernel_ab.main([scene, "--width", str(args.width), "--spp", str(args.spp), "--rounds", str(args.rounds),
                            "--json", str(out), "--device", variants[0][1]]
                           + [a for impl, spec, lanes in variants for a in
                              ("--variant", json.dumps({"kernel_mode": "megakernel", "device": spec,
                                                        "env": {"PYOPENCL_RT_LANES": str(lanes)}}))])
            rows = json.loads(out.read_text())["results"]
        results["scenes"][scene] = [{"implementation": impl, "device": spec, "lanes": lanes,
                                     "msamples_per_s": row["msamples_per_s"], "median": row["median"],
                                     "max_rel_image_diff_vs_first": row["max_rel_image_diff_vs_first"]}
                                    for (impl, spec, lanes), row in zip(variants, rows)]
    print(f"\n{results['cpu']}")
    summary = {}
    for spec, rule in rules.items():
        per_width = {}
        for lanes in (0, *rule.widths):
            ratios = []
            for rows in results["scenes"].values():
                own = [r for r in rows if r["device"] == spec]
                base = np.array(next(r for r in own if r["lanes"] == 0)["msamples_per_s"])
                mine = np.array(next(r for r in own if r["lanes"] == lanes)["msamples_per_s"])
                ratios.append(float(np.median(mine / base)))
            per_width[lanes] = float(np.median(ratios))
        best = max(per_width, key=per_width.get)
        summary[spec] = {"implementation": rule.implementation, "target": rule.describe,
                         "ratio_to_one_path": per_width, "fastest": best, "rule": rule.default}
        print(f"{spec} {rule.implementation:6s} {rule.describe}")
        print("   " + "  ".join(f"{w or 1}: x{r:.3f}" for w, r in per_width.items())
              + f"   fastest {best or 'one path'}; the rule gives {rule.default or 'one path'}")
    results["summary"] = summary
    if args.json:
        Path(args.json).write_text(json.dumps(results, indent=1) + "\n")


if __name__ == "__main__":
    main()
