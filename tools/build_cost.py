"""CPU seconds of a cold kernel build: what one distinct feature set costs a first render (and the
test suite, which builds some 160 of them on a fresh machine, docs/BENCHMARKS.md "Kernel builds").

    python tools/build_cost.py scenes/cornell-fog.toml --lanes 8
    python tools/build_cost.py mixed --lanes 0 --define LANE_GROUP=8

Each run takes a fresh, empty PoCL and pyopencl cache (so nothing is reused from an earlier
build) and renders the scene once, 16 x 8 pixels at 1 spp, with the megakernel: PoCL compiles
part of a program when it is built and the rest (the work-group function for the launch's group
size) at its first launch, so the render's process CPU time is the whole cost.  ``mixed`` is
tests/render/mixed_scene.toml (every material, shape and light type).  ``--define NAME=VALUE``
adds a kernel define (LANE_GROUP: the launch takes its group size from it).  Run it several times
and alternate variants: the machine's load changes the wall time, not much the CPU time.
"""
from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", help="a scene file, or 'mixed'")
    parser.add_argument("--lanes", default="8", help="$PYOPENCL_RT_LANES: 0 (one path per work-item), 8 or 16")
    parser.add_argument("--define", action="append", default=[], help="NAME=VALUE, an extra kernel define")
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args(argv)
    cache = tempfile.mkdtemp(prefix="build_cost_")
    os.environ["XDG_CACHE_HOME"] = cache  # PoCL's kernel cache and pyopencl's binary cache
    os.environ["POCL_CACHE_DIR"] = os.path.join(cache, "pocl")
    sys.path.insert(0, str(ROOT))
    import pyopencl_rt as rt
    from pyopencl_rt.render import megakernel, wavefront

    os.environ[megakernel.LANES_ENV] = args.lanes
    extra = {}
    for item in args.define:
        name, _, value = item.partition("=")
        extra[name] = int(value) if value.lstrip("-").isdigit() else (value or True)
    if extra:
        features = wavefront.kernel_features
        wavefront.kernel_features = lambda *a, **k: {**features(*a, **k), **extra}
    if args.scene == "mixed":
        sys.path.insert(0, str(ROOT / "tests" / "render"))
        sys.path.insert(0, str(ROOT / "tests"))
        import test_path_lanes

        scene = test_path_lanes.mixed_scene(Path(tempfile.mkdtemp(prefix="build_cost_scene_")))
    else:
        scene = rt.load_scene(args.scene)
    cpu, wall = time.process_time(), time.perf_counter()
    result = rt.render_full(scene, device=args.device, kernel_mode="megakernel", spp=1, width=16, height=8, seed=1)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    print(json.dumps({"scene": args.scene, "lanes": result.info.get("lanes"), "defines": extra,
                      "cold_build_cpu_s": round(cpu, 2), "wall_s": round(wall, 2)}))


if __name__ == "__main__":
    main()
