"""Render Mitsuba 3's own Cornell box (``mi.cornell_box()``) at a few spp and print the timings as
one JSON line; run in an interpreter that has mitsuba (``pyopencl-rt bench mitsuba-cornell-box``
starts it).  Only mitsuba is needed, nothing of this package.

    python pyopencl_rt/bench/mitsuba_cornell_box.py [--variant llvm_ad_rgb] [--spp 16,64,256]
    python pyopencl_rt/bench/mitsuba_cornell_box.py --serve [--variant llvm_ad_rgb] [--spp 64]

Each render is timed until its pixels are on the host.  The first includes the JIT compilation;
the later ones reuse the compiled kernels.  With ``--serve`` the renders of ``--spp`` (the warm-up)
come first, then one more render for every spp read from stdin, one line each, its timing printed
as one JSON line as soon as it is done: ``bench render --mitsuba`` renders the box between its own
renders that way, so that load on a shared machine falls on both alike, with ``--rfilter`` the
pixel filter of our scene (so that both renderers filter alike).
"""
from __future__ import annotations

import argparse
import json
import sys
import time


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--variant", default="llvm_ad_rgb")
    parser.add_argument("--spp", default="16,64,256", help="comma-separated samples per pixel, one render each")
    parser.add_argument("--serve", action="store_true", help="then render the spp of each stdin line")
    parser.add_argument("--rfilter", default=None,
                        help="the film's rfilter as a JSON dict (default: cornell_box()'s, a gaussian)")
    args = parser.parse_args(argv)

    import drjit as dr
    import mitsuba as mi

    mi.set_variant(args.variant)
    spec = mi.cornell_box()
    if args.rfilter:
        spec["sensor"]["film"]["rfilter"] = json.loads(args.rfilter)
    scene = mi.load_dict(spec)
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
                      "height": int(height), "rfilter": spec["sensor"]["film"]["rfilter"], "renders": renders}),
          flush=True)
    if args.serve:
        for line in sys.stdin:
            if line.strip():
                print(json.dumps(timed(int(line))), flush=True)


if __name__ == "__main__":
    main()
