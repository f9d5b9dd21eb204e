"""Render Mitsuba 3's own Cornell box (``mi.cornell_box()``) at a few spp and print the timings as
one JSON line; run in an interpreter that has mitsuba (``pyopencl-rt bench mitsuba-cornell-box``
starts it).  Only mitsuba is needed, nothing of this package.

    python pyopencl_rt/bench/mitsuba_cornell_box.py [--variant llvm_ad_rgb] [--spp 16,64,256]

Each render is timed until its pixels are on the host.  The first includes the JIT compilation;
the later ones reuse the compiled kernels.  (``bench render --mitsuba`` times Mitsuba on the export
of our scene instead, through ``mitsuba_runner.py --serve``.)
"""
from __future__ import annotations

import argparse
import json
import time


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="llvm_ad_rgb")
    parser.add_argument("--spp", default="16,64,256", help="comma-separated samples per pixel, one render each")
    args = parser.parse_args(argv)

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    scene = mi.load_dict(mi.cornell_box())
    width, height = scene.sensors()[0].film().crop_size()

    def timed(spp):
        start = time.perf_counter()
        image = mi.render(scene, spp=spp)
        dr.eval(image)
        image.numpy()
        return {"spp": spp, "seconds": time.perf_counter() - start}

    renders = [timed(int(s)) for s in args.spp.split(",") if s.strip()]
    print(json.dumps({"renderer": "mitsuba", "version": mi.__version__, "drjit_version": dr.__version__,
                      "variant": args.variant, "scene": "mi.cornell_box()", "width": int(width),
                      "height": int(height), "renders": renders}), flush=True)


if __name__ == "__main__":
    main()
