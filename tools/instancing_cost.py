"""Instancing costs (docs/BENCHMARKS.md, "Instancing"), N instances of a 128-triangle group (a
subdivided octahedron) on a grid:

    python tools/instancing_cost.py [N ...]        host build time and device memory, flattened
                                                   against two-level (default 1000 100000)
    python tools/instancing_cost.py --xml N PATH   write that scene as a Mitsuba 3 file (a floor,
                                                   a point light, a sky, a sensor over the grid)
                                                   for tools/kernel_ab.py's samples/s, each way
    python tools/instancing_cost.py --run PATH     load PATH, build, render 32 x 32 at 1 spp: the
                                                   time of each and the process's peak memory
"""
from __future__ import annotations

import resource
import sys
import time
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))
sys.path.insert(0, str(ROOT / "tests"))
from render.test_instancing_two_level import subdivided_octahedron  # noqa: E402

from pyopencl_rt.scene.instances import flattened, scene_bvh  # noqa: E402
from pyopencl_rt.scene.model import BlasGroup, Instance, Material, Scene  # noqa: E402


def grid(n: int) -> np.ndarray:
    """(n, 4, 4): instance k at 3 (i, 0, -j) on a square grid, turned about y by 0.7 k."""
    side = int(np.ceil(np.sqrt(n)))
    ij = np.stack(np.divmod(np.arange(n), side), axis=1).astype(np.float64)
    m = np.tile(np.eye(4), (n, 1, 1))
    a = np.arange(n) * 0.7
    m[:, 0, 0], m[:, 0, 2], m[:, 2, 0], m[:, 2, 2] = np.cos(a), np.sin(a), -np.sin(a), np.cos(a)
    m[:, 0, 3], m[:, 2, 3] = 3 * ij[:, 0], -3 * ij[:, 1]
    return m


def grid_scene(n: int) -> Scene:
    v, f = subdivided_octahedron(2)
    s = Scene(vertices=v.astype(np.float32), faces=f.astype(np.int32), face_materials=np.zeros(len(f), np.int32),
              materials=[Material()])
    s.blas_groups = [BlasGroup("o", 0, len(f))]
    s.instances = [Instance("o", mk, blas=0) for mk in grid(n)]
    return s


def write_xml(n: int, path: Path) -> None:
    """The grid as a Mitsuba 3 scene: the group an OBJ beside it with the sphere's normals."""
    v, f = subdivided_octahedron(2)
    obj = path.with_suffix(".obj")
    obj.write_text("".join(f"v {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in v)
                   + "".join(f"vn {x:.9g} {y:.9g} {z:.9g}\n" for x, y, z in v)
                   + "".join(f"f {a + 1}//{a + 1} {b + 1}//{b + 1} {c + 1}//{c + 1}\n" for a, b, c in f))
    side = int(np.ceil(np.sqrt(n)))
    extent = 3.0 * side
    centre = (extent / 2 - 1.5, 0.0, -(extent / 2 - 1.5))
    eye = (centre[0], 0.55 * extent + 4, centre[2] + 0.75 * extent + 6)
    rows = [f'<shape type="instance"><ref id="o"/><transform name="to_world"><matrix value="'
            + " ".join(f"{x:.9g}" for x in m.ravel()) + '"/></transform></shape>\n' for m in grid(n)]
    path.write_text(
        '<scene version="3.0.0">\n'
        '<integrator type="path"><integer name="max_depth" value="4"/></integrator>\n'
        '<sensor type="perspective"><float name="fov" value="50"/><transform name="to_world">'
        f'<lookat origin="{eye[0]}, {eye[1]}, {eye[2]}" target="{centre[0]}, 0, {centre[2]}" up="0, 1, 0"/>'
        '</transform><film type="hdrfilm"><integer name="width" value="64"/><integer name="height" value="64"/>'
        '</film></sensor>\n'
        f'<emitter type="point"><point name="position" x="{centre[0]}" y="{extent}" z="{centre[2]}"/>'
        f'<rgb name="intensity" value="{extent * extent}"/></emitter>\n'
        '<emitter type="constant"><rgb name="radiance" value="0.2"/></emitter>\n'
        f'<shape type="shapegroup" id="o"><shape type="obj"><string name="filename" value="{obj.name}"/>'
        '<bsdf type="diffuse"><rgb name="reflectance" value="0.7, 0.5, 0.3"/></bsdf></shape></shape>\n'
        + "".join(rows)
        + f'<shape type="rectangle"><transform name="to_world"><rotate x="1" angle="-90"/><scale value="{extent}"/>'
        f'<translate x="{centre[0]}" y="-1" z="{centre[2]}"/></transform>'
        '<bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf></shape>\n</scene>\n')


def run(path: str) -> None:
    import pyopencl_rt as rt
    from pyopencl_rt.scene.loaders import load_scene

    t0 = time.perf_counter()
    scene = load_scene(path)
    t1 = time.perf_counter()
    bvh = scene_bvh(scene)
    t2 = time.perf_counter()
    r = rt.render_full(scene, spp=1, width=32, height=32, device="cpu", seed=1)
    t3 = time.perf_counter()
    peak = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 2**20
    print(f"{path}: {len(scene.instances)} instances ({sum(i.blas >= 0 for i in scene.instances)} two-level), "
          f"{len(scene.faces)} faces; load {t1 - t0:.1f} s, BVHs {t2 - t1:.1f} s ({bvh.build_seconds:.1f} s in "
          f"TwoLevelBVH), render 32 x 32 x 1 spp {t3 - t2:.1f} s (its own BVH build, {r.info['bvh_seconds']:.1f} s, "
          f"and kernel build included); image mean {r.image.mean():.3f}; peak RSS {peak:.2f} GiB", flush=True)


def main(counts):
    from pyopencl_rt.accel.device_bvh import node_buffer

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
        nodes = node_buffer(bvh, "wide8")
        t_flat = time.perf_counter() - t0
        mem_flat = bvh.triangles.nbytes + nodes.nbytes
        print(f"{n} instances x {len(s.faces)} triangles: two-level {t_two:.2f} s, {mem_two / 2**20:.1f} MiB; "
              f"flattened {t_flat:.2f} s, {mem_flat / 2**20:.1f} MiB (triangles + wide8 nodes)")


if __name__ == "__main__":
    if sys.argv[1:2] == ["--xml"]:
        write_xml(int(sys.argv[2]), Path(sys.argv[3]))
    elif sys.argv[1:2] == ["--run"]:
        run(sys.argv[2])
    else:
        main([int(a) for a in sys.argv[1:]] or [1000, 100000])
