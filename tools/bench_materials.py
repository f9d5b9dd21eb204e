"""The cost of a texture lookup and of rough against smooth materials (issue 4).

Each pair renders the same scene twice, interleaved, repeat times, and reports the median
samples/s of both and their ratio:

* textures: scenes/textured.toml as is, and with every texture removed (the factors kept), so
  the kernel is compiled without HAS_TEXTURES;
* rough vs smooth: scenes/cornell-jensen.toml with its mirror and glass spheres smooth (delta
  lobes) and with both at GGX alpha 0.1 (roughness 0.32);
* glTF vs diffuse: the Cornell box with every diffuse material turned into a glTF plastic
  (metallic 0, alpha 0.1) of the same base colour.

    python tools/bench_materials.py [--width 256 --height 256 --spp 8 --repeat 3 --json FILE]
"""
from __future__ import annotations

import argparse
import copy
import dataclasses
import json
import statistics
import sys
from pathlib import Path

sys.path.insert(0, str(Path(__file__).resolve().parent.parent))

from pyopencl_rt import load_scene
from pyopencl_rt.device.devices import select_device
from pyopencl_rt.render.api import render_full
from pyopencl_rt.render.wavefront import Wavefront


def variant(scene, change):
    s = copy.copy(scene)
    s.materials = [change(dataclasses.replace(m)) for m in scene.materials]
    return s


def untextured(m):
    m.base_texture = m.mr_texture = m.emission_texture = None
    return m


def roughened(m):
    if m.type in ("conductor", "dielectric"):
        m.alpha = 0.1
    return m


def plastic(m):
    if m.type == "diffuse" and not m.is_emissive:
        m.type, m.metallic, m.alpha = "gltf", 0.0, 0.1
    return m


def compare(name, a, b, args, device):
    wfs = [Wavefront(s, device, width=args.width, height=args.height) for s in (a, b)]
    for wf, s in zip(wfs, (a, b)):
        render_full(s, spp=1, wavefront=wf)  # warm-up: kernel build and first launches
    rates = ([], [])
    for _ in range(args.repeat):
        for k, (wf, s) in enumerate(zip(wfs, (a, b))):
            rates[k].append(render_full(s, spp=args.spp, wavefront=wf).info["samples_per_second"])
    ma, mb = statistics.median(rates[0]), statistics.median(rates[1])
    print(f"{name:<28} {ma / 1e6:8.3f} {mb / 1e6:8.3f}   {ma / mb:6.3f}")
    return {"a_samples_per_second": ma, "b_samples_per_second": mb, "a_over_b": ma / mb,
            "a_all": rates[0], "b_all": rates[1], "features_a": sorted(map(str, wfs[0].features)),
            "features_b": sorted(map(str, wfs[1].features))}


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--width", type=int, default=256)
    ap.add_argument("--height", type=int, default=256)
    ap.add_argument("--spp", type=int, default=8)
    ap.add_argument("--repeat", type=int, default=3)
    ap.add_argument("--device", default="cpu")
    ap.add_argument("--json")
    args = ap.parse_args()
    device = select_device(args.device)
    root = Path(__file__).resolve().parent.parent / "scenes"
    textured, jensen, cornell = (load_scene(root / n) for n in ("textured.toml", "cornell-jensen.toml",
                                                                "cornell-box.toml"))
    print(f"{'pair (a vs b)':<28} {'a Ms/s':>8} {'b Ms/s':>8}   a/b")
    out = {"width": args.width, "height": args.height, "spp": args.spp, "repeat": args.repeat,
           "textured_vs_untextured": compare("textured vs untextured", textured, variant(textured, untextured),
                                             args, device),
           "rough_vs_smooth": compare("rough vs smooth (jensen)", variant(jensen, roughened), jensen, args, device),
           "gltf_vs_diffuse": compare("glTF plastic vs diffuse", variant(cornell, plastic), cornell, args, device)}
    if args.json:
        Path(args.json).write_text(json.dumps(out, indent=2))
        print(f"wrote {args.json}")


if __name__ == "__main__":
    main()
