"""Rays/s of pyopencl_rt.trace() beside Embree (embreex, one thread) on the height field of
``bench set``'s million-triangle scene (pyopencl_rt/bench/scale_scene.py), where the set's scene
is slower than Mitsuba (docs/BENCHMARKS.md, "Current: the grown set"): camera rays from the scene's
viewpoint, and uniform bounce rays over the hemisphere of each camera ray's hit.

    python tools/heightfield_rays.py [--triangles 1.01e6] [--rays 1000000] [--rounds 3]

Ours: the wall time of trace() on the prebuilt BVH (PoCL's threads); Embree: one thread's CPU
time, so per thread ours is the figure over PoCL's thread count.  Medians of the rounds.
"""
from __future__ import annotations

import argparse
import importlib
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))


def main(argv=None) -> int:
    import embreex.rtcore_scene as rtcs
    from embreex.mesh_construction import TriangleMesh

    from pyopencl_rt.bench.scale_scene import grid_size, heightfield

    trace = importlib.import_module("pyopencl_rt.trace")
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--triangles", type=float, default=1.01e6)
    ap.add_argument("--rays", type=int, default=1_000_000)
    ap.add_argument("--rounds", type=int, default=3)
    a = ap.parse_args(argv)
    vertices, faces = heightfield(grid_size(a.triangles))
    bvh = trace.as_bvh((vertices, faces))
    print(f"{len(faces)} triangles, SAH cost {bvh.stats['sah_cost']:.2f}, depth {bvh.stats['depth']}")
    rng = np.random.default_rng(1)
    eye = np.array([0.0, -2.6, 2.2])  # the scene's camera (scale_scene.XML), fov 40
    look = -eye / np.linalg.norm(eye)
    right = np.cross(look, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    up = np.cross(right, look)
    half = np.tan(np.radians(20.0))
    d = look + rng.uniform(-half, half, (a.rays, 1)) * right + rng.uniform(-half, half, (a.rays, 1)) * up
    d = (d / np.linalg.norm(d, axis=1, keepdims=True)).astype(np.float32)
    o = np.tile(eye, (a.rays, 1)).astype(np.float32)
    hit = trace.trace(bvh, o, d)
    ok = hit["prim_id"] >= 0
    p = o[ok] + hit["t"][ok, None] * d[ok]
    n = hit["normal"][ok]
    n = np.where((n * d[ok]).sum(1, keepdims=True) > 0, -n, n)
    w = rng.normal(size=(int(ok.sum()), 3))
    w /= np.linalg.norm(w, axis=1, keepdims=True)
    w = np.where((w * n).sum(1, keepdims=True) < 0, -w, w)
    sets = {"primary": (o, d), "bounce": ((p + 1e-4 * n).astype(np.float32), w.astype(np.float32))}
    scene = rtcs.EmbreeScene()
    TriangleMesh(scene, vertices[faces].astype(np.float32))
    for name, (origins, directions) in sets.items():
        trace.trace(bvh, origins[:1000], directions[:1000])  # the kernel built
        ours, theirs = [], []
        for _ in range(a.rounds):
            t0 = time.perf_counter()
            trace.trace(bvh, origins, directions)
            ours.append(time.perf_counter() - t0)
            t0 = time.process_time()
            scene.run(origins, directions, output=1)
            theirs.append(time.process_time() - t0)
        m = len(origins) / 1e6
        print(f"{name}: {len(origins)} rays, ours {m / np.median(ours):.2f} Mrays/s (wall), "
              f"Embree {m / np.median(theirs):.2f} Mrays/s (one thread's CPU)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
