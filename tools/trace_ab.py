"""Rays/s of pyopencl_rt.trace() (or occluded()) for several source trees, interleaved, beside
Embree on one thread: the A/B measurement behind the ray-casting steps (docs/BENCHMARKS.md).

    python tools/trace_ab.py . /tmp/base --size 1M --set diffuse --rounds 9
    python tools/trace_ab.py . /tmp/base --shuffle --any-hit      # rays in random order, occluded()

The bumpy torus of ``bench rays`` and its ray sets (primary, or the diffuse bounce of each primary
hit; ``--shuffle`` puts them in random order, so that no packet holds neighbours) are made once, by
this tree, and handed to one worker process per tree, which builds the BVH
with its own code and traces the rays with its own kernels (one untimed warm-up first). Each round
then runs every tree once in turn, and Embree (embreex, one thread, in this process), so that load
on a shared machine falls on all of them alike. Printed per backend: the median over the rounds of
Mrays per CPU second (the process's CPU time, PoCL's threads included: the work per thread, which
load disturbs less than the wall time), the median of the per-round ratios to the first tree, and
whether each tree's hits equal the first tree's bit for bit.  Set ``PYOPENCL_RT_LANES=0`` to time
one ray per work-item instead of packets (the workers inherit the environment).
"""
from __future__ import annotations

import argparse
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

WORKER = r'''
import hashlib, sys, time
import numpy as np
sys.path.insert(0, sys.argv[1])
from pyopencl_rt.accel.bvh import build_bvh
from pyopencl_rt.trace import _opencl, _rays
data = np.load(sys.argv[2])
bvh = build_bvh(data["vertices"], data["faces"])
o, d, tmin, tmax = _rays(data["origins"], data["directions"], 0.0, np.inf)
_opencl(bvh, o[:1024], d[:1024], tmin[:1024], tmax[:1024], sys.argv[3], any_hit=sys.argv[4] == "1")
print("ready", flush=True)
any_hit = sys.argv[4] == "1"
for line in sys.stdin:
    wall, cpu = time.perf_counter(), time.process_time()
    res = _opencl(bvh, o, d, tmin, tmax, sys.argv[3], any_hit=any_hit)
    cpu, wall = time.process_time() - cpu, time.perf_counter() - wall
    arrays = [res] if any_hit else [res[k] for k in ("t", "prim_id", "u", "v")]
    digest = hashlib.sha1(b"".join(np.ascontiguousarray(a).tobytes() for a in arrays)).hexdigest()
    print(cpu, wall, digest, flush=True)
'''


def main(argv=None):
    from pyopencl_rt.accel.bvh import build_bvh
    from pyopencl_rt.accel.embree import embree_scene
    from pyopencl_rt.bench.workloads import bumpy_torus, diffuse_rays, parse_sizes, primary_rays
    from pyopencl_rt.trace import trace

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("trees", nargs="+", type=Path, help="source trees (checkouts or worktrees)")
    parser.add_argument("--size", default="1M", help="torus triangles (as bench rays' --sizes)")
    parser.add_argument("--set", choices=("primary", "diffuse"), default="diffuse")
    parser.add_argument("--rays", type=int, default=1_000_000, help="primary rays (diffuse: one per hit)")
    parser.add_argument("--shuffle", action="store_true", help="the rays in random order (no neighbours in a packet)")
    parser.add_argument("--any-hit", action="store_true", help="occluded() instead of trace()")
    parser.add_argument("--rounds", type=int, default=9)
    parser.add_argument("--device", default="cpu")
    args = parser.parse_args(argv)

    vertices, faces = bumpy_torus(parse_sizes(args.size)[0])
    bvh = build_bvh(vertices, faces)
    origins, directions = primary_rays(bvh.bounds.astype(np.float64), args.rays)
    if args.set == "diffuse":
        hits = trace(bvh, origins, directions, backend="embree")
        origins, directions = diffuse_rays(hits, origins, directions, np.random.default_rng(7))
    if args.shuffle:
        order = np.random.default_rng(5).permutation(len(origins))
        origins, directions = origins[order], directions[order]
    scene = embree_scene(bvh)
    n = len(origins)
    with tempfile.TemporaryDirectory() as tmp:
        data = Path(tmp) / "rays.npz"
        np.savez(data, vertices=vertices, faces=faces, origins=origins, directions=directions)
        workers = [subprocess.Popen([sys.executable, "-c", WORKER, str(tree.resolve()), str(data), args.device,
                                     "1" if args.any_hit else "0"],
                                    stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
                   for tree in args.trees]
        for w in workers:
            if w.stdout.readline().strip() != "ready":
                raise SystemExit("a worker failed to start")
        names = [str(t) for t in args.trees] + ["embree x1"]
        cpu = {name: [] for name in names}
        digests = {}
        for _ in range(args.rounds):
            for tree, w in zip(args.trees, workers):
                w.stdin.write("run\n")
                w.stdin.flush()
                seconds, _wall, digest = w.stdout.readline().split()
                cpu[str(tree)].append(float(seconds))
                digests[str(tree)] = digest
            start = time.process_time()
            if args.any_hit:
                scene.run(origins, directions, query="OCCLUDED")
            else:
                scene.run(origins, directions, output=1)
            cpu["embree x1"].append(time.process_time() - start)
        for w in workers:
            w.stdin.close()
            w.wait()
    first = names[0]
    print(f"{n} {args.set} rays{' (shuffled)' if args.shuffle else ''}, {'any' if args.any_hit else 'closest'} hit, "
          f"on {len(faces)} triangles, {args.rounds} rounds")
    for name in names:
        ratios = [a / b for a, b in zip(cpu[first], cpu[name])]
        same = "" if name == "embree x1" else ("  hits equal" if digests[name] == digests[first] else "  HITS DIFFER")
        print(f"{name:<30} {n / statistics.median(cpu[name]) / 1e6:8.3f} Mrays/cpu-s   "
              f"x{statistics.median(ratios):.3f} of the first{same}")


if __name__ == "__main__":
    main()
