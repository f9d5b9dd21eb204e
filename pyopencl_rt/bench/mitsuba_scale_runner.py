"""Load and render one Mitsuba 3 XML file, as ``pyopencl-rt bench scale`` runs Mitsuba beside us.

    python pyopencl_rt/bench/mitsuba_scale_runner.py SCENE.xml OUT.exr [--variant llvm_ad_rgb]

Prints one JSON line: the seconds of the import (and set_variant), of load_file, of the render
(until its pixels are on the host) and of writing the image.  Only mitsuba is needed: the
process's wall time and peak RSS are measured by the parent (:mod:`.scale`), as for ours.
"""
from __future__ import annotations

import argparse
import json
import time


def main(argv=None) -> int:
    ap = argparse.ArgumentParser()
    ap.add_argument("scene")
    ap.add_argument("output")
    ap.add_argument("--variant", default="llvm_ad_rgb")
    a = ap.parse_args(argv)
    t0 = time.perf_counter()
    import mitsuba as mi

    mi.set_variant(a.variant)
    t1 = time.perf_counter()
    scene = mi.load_file(a.scene)
    t2 = time.perf_counter()
    image = mi.render(scene)
    pixels = image.numpy()  # evaluated: the render is done
    t3 = time.perf_counter()
    mi.util.write_bitmap(a.output, image)
    t4 = time.perf_counter()
    print(json.dumps({"import_seconds": t1 - t0, "load_seconds": t2 - t1, "render_seconds": t3 - t2,
                      "write_seconds": t4 - t3, "shape": list(pixels.shape), "mitsuba": mi.__version__}))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
