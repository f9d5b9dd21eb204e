"""Samples/s of the lane megakernel against one path per work-item on Mitsuba's Cornell box with a
diffuse icosphere of many triangles added (docs/BENCHMARKS.md, "Paths in SIMD lanes"), and whether
their images are equal.

    python tools/lanes_scene_size.py 6    # icosphere subdivisions: 6 -> 82k triangles, 8 -> 1.3M
"""
from __future__ import annotations

import dataclasses
import os
import sys
from pathlib import Path

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))


def main(argv=None):
    import trimesh

    from pyopencl_rt.device.devices import select_device
    from pyopencl_rt.render.film import Film
    from pyopencl_rt.render.megakernel import LANES_ENV
    from pyopencl_rt.render.wavefront import Wavefront
    from pyopencl_rt.scene.loaders import load_scene

    argv = sys.argv[1:] if argv is None else argv
    subdivisions = int(argv[0]) if argv else 6
    scene = load_scene(ROOT / "scenes" / "mitsuba-cbox.toml")
    sphere = trimesh.creation.icosphere(subdivisions=subdivisions, radius=0.3)
    vertices = (np.asarray(sphere.vertices) + [0.3, -0.6, 0.3]).astype(np.float32)
    faces = np.asarray(sphere.faces, np.int32) + len(scene.vertices)
    scene = dataclasses.replace(
        scene, vertices=np.concatenate([scene.vertices, vertices]), faces=np.concatenate([scene.faces, faces]),
        face_materials=np.concatenate([scene.face_materials, np.full(len(faces), scene.face_materials[0], np.int32)]))
    print("triangles", len(scene.faces))
    device = select_device("cpu")
    engines = {}
    for width in ("0", "16"):
        os.environ[LANES_ENV] = width
        engines[width] = Wavefront(scene, device, width=128, height=128)
        engines[width].run(Film(128, 128), passes=1)  # warm-up
    images = {}
    for _ in range(3):  # rounds, the two in turn
        for width, wf in engines.items():
            film = Film(128, 128)
            stats = wf.run(film, passes=8)
            images[width] = film.image()
            print(f"lanes {wf.lane_width:2d}: {stats.samples / stats.seconds / 1e6:.3f} Msamples/s")
    print("images identical:", bool(np.array_equal(images["0"], images["16"])))


if __name__ == "__main__":
    main()
