"""Build time and memory of N instances of a small group, flattened against two-level
(docs/BENCHMARKS.md, "Instancing"): python tools/instancing_cost.py [N ...] (default 1000 100000)."""
from __future__ import annotations

import sys
import time

import numpy as np

sys.path.insert(0, "tests")
from render.test_instancing_two_level import subdivided_octahedron  # noqa: E402

from pyopencl_rt.scene.instances import flattened, scene_bvh  # noqa: E402
from pyopencl_rt.scene.model import BlasGroup, Instance, Material, Scene  # noqa: E402


def grid_scene(n: int) -> Scene:
    v, f = subdivided_octahedron(2)
    side = int(np.ceil(np.sqrt(n)))
    ij = np.stack(np.divmod(np.arange(n), side), axis=1).astype(np.float64)
    m = np.tile(np.eye(4), (n, 1, 1))
    m[:, 0, 3], m[:, 2, 3] = 3 * ij[:, 0], -3 * ij[:, 1]
    s = Scene(vertices=v.astype(np.float32), faces=f.astype(np.int32), face_materials=np.zeros(len(f), np.int32),
              materials=[Material()])
    s.blas_groups = [BlasGroup("o", 0, len(f))]
    s.instances = [Instance("o", mk, blas=0) for mk in m]
    return s


def main(counts):
    for n in counts:
        s = grid_scene(n)
        t0 = time.perf_counter()
        two = scene_bvh(s)
        bufs = two.buffers("wide8")
        t_two = time.perf_counter() - t0
        mem_two = two.triangles.nbytes + sum(b.nbytes for b in bufs.values())
        t0 = time.perf_counter()
        flat = flattened(s)
        bvh = scene_bvh(flat)
        from pyopencl_rt.accel.device_bvh import node_buffer
        nodes = node_buffer(bvh, "wide8")
        t_flat = time.perf_counter() - t0
        mem_flat = bvh.triangles.nbytes + nodes.nbytes
        print(f"{n} instances x {len(s.faces)} triangles: two-level {t_two:.2f} s, {mem_two / 2**20:.1f} MiB; "
              f"flattened {t_flat:.2f} s, {mem_flat / 2**20:.1f} MiB (triangles + wide8 nodes)")


if __name__ == "__main__":
    main([int(a) for a in sys.argv[1:]] or [1000, 100000])
