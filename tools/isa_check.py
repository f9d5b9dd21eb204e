"""One instruction set's check of the SIMD width rule (docs/DEVICES.md, "SIMD width on CPUs"), meant
to run under Debian's qemu-user with an empty PoCL cache, as `make isa-check` does:

    POCL_CACHE_DIR=$(mktemp -d) qemu-x86_64 -cpu Haswell .venv/bin/python tools/isa_check.py --expect-width 8

Under `-cpu Haswell` PoCL compiles for AVX2 and links its AVX2 library, under `-cpu Nehalem` SSE4.2
and its SSE4.1 library.  Checked, each a line of output and together the exit status:
  probe      what the probe reports (the compile's macros, the library's register width) and the
             width the rule gives (--expect-width: what it must be on this CPU model)
  crossings  the kernels a render and trace() build (one path, the lanes and trace packets at 8 and
             16) pass no 32- or 64-byte vector to a PoCL built-in
  render     the Cornell box renders at the default width and at each forced width with the film
             of one path per work-item, bit for bit, finite
  trace      trace()/occluded() packets at 8 and 16 equal one ray per work-item on a small torus
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import warnings
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--device", default="cpu")
    parser.add_argument("--expect-width", type=int, choices=(0, 8, 16), help="the width the rule must give")
    args = parser.parse_args(argv)
    warnings.simplefilter("ignore")  # the compiler's warnings: counted below, not printed

    import pyopencl_rt as rt
    from pyopencl_rt.accel.device_bvh import LANES_ENV
    from pyopencl_rt.device import isa
    from pyopencl_rt.device.devices import select_device
    from pyopencl_rt.device.kernels import runtime
    from pyopencl_rt.render import megakernel
    from pyopencl_rt.render.wavefront import Wavefront

    failures = []

    def check(name, ok, text):
        print(f"{'ok  ' if ok else 'FAIL'} {name}: {text}", flush=True)
        if not ok:
            failures.append(name)

    device = select_device(args.device)
    machine = isa.probe(device)
    width, reason = isa.simd_width(machine)
    check("probe", args.expect_width is None or width == args.expect_width,
          f"{json.dumps(machine.as_dict())} -> {reason}")

    scene = rt.load_scene(ROOT / "scenes" / "cornell-box.toml")
    os.environ[LANES_ENV] = "0"
    base = Wavefront(scene, device, width=8, height=8, kernel_mode="megakernel").features
    builds = {"one path": (megakernel.SOURCES, base), "trace": (("accel/trace.cl",), {"BVH_WIDE8": True})}
    for lanes in (8, 16):
        builds[f"lanes {lanes}"] = (megakernel.SOURCES, {**base, **megakernel.lane_features(lanes)})
        builds[f"trace packets {lanes}"] = (("accel/trace.cl",), {"BVH_WIDE8": True, "PACKET_WIDTH": lanes})
    rt_dev = runtime(device)
    for name, (names, defines) in builds.items():
        found = isa.program_crossings(rt_dev.program(names, defines), device)
        check(f"crossings {name}", not found, f"{len(found)} built-in calls with a wide vector {sorted(set(found))[:4]}")

    films = {}
    for lanes in ("0", "", "8", "16"):
        os.environ[LANES_ENV] = lanes
        result = rt.render_full(scene, device=device, kernel_mode="megakernel", spp=2, width=24, height=16, seed=7)
        films[lanes] = (result.film.sum, result.info["lanes"])
    for lanes in ("", "8", "16"):
        same = np.array_equal(films[lanes][0], films["0"][0]) and np.isfinite(films[lanes][0]).all()
        check(f"render {lanes or 'default'}", same, f"{films[lanes][1]} lanes, film equal to one path: {same}")

    from pyopencl_rt import build_bvh, occluded, trace
    from pyopencl_rt.bench.workloads import bumpy_torus

    bvh = build_bvh(*bumpy_torus(1600))
    rng = np.random.default_rng(3)
    origins = np.repeat(rng.normal(scale=0.2, size=(64, 3)), 16, axis=0).astype(np.float32)
    directions = rng.normal(size=(len(origins), 3)).astype(np.float32)
    os.environ[LANES_ENV] = "0"
    ref = trace(bvh, origins, directions, device=device, layout="wide8")
    ref_any = occluded(bvh, origins, directions, device=device, layout="wide8")
    for lanes in ("8", "16"):
        os.environ[LANES_ENV] = lanes
        got = trace(bvh, origins, directions, device=device, layout="wide8")
        got_any = occluded(bvh, origins, directions, device=device, layout="wide8")
        same = np.array_equal(got["t"], ref["t"]) and np.array_equal(got_any, ref_any)
        check(f"trace packets {lanes}", same, f"{(ref['prim_id'] >= 0).mean():.2f} of the rays hit; t and any hit equal")
    print(f"{len(failures)} failed: {', '.join(failures)}" if failures else "all passed")
    return 1 if failures else 0


if __name__ == "__main__":
    sys.exit(main())
