"""``pyopencl-rt bench materials``: the cost of texture lookups and of rough and layered materials.

Each pair renders two variants of one scene, timed alternately (see :mod:`.timing`), and reports
the median samples/s of both and their ratio a / b:

* ``textures``: scenes/textured.toml as is (a), and with every texture removed, the factors kept
  (b), so that kernel is compiled without HAS_TEXTURES;
* ``rough``: scenes/cornell-jensen.toml with its mirror and glass spheres at GGX alpha 0.1 (a)
  against the scene as is, both spheres smooth (delta lobes) (b);
* ``gltf``: the Cornell box with every diffuse material turned into a glTF plastic (metallic 0,
  alpha 0.1) of the same base colour (a) against plain Lambert (b).
"""
from __future__ import annotations

import copy
import dataclasses
import statistics
from pathlib import Path

from .timing import interleaved_render_rates, machine_info, write_results


def with_materials(scene, change):
    """A shallow copy of ``scene`` whose materials are copies passed through ``change``."""
    changed = copy.copy(scene)
    changed.materials = [change(dataclasses.replace(m)) for m in scene.materials]
    copies = {id(old): new for old, new in zip(scene.materials, changed.materials)}
    for m in changed.materials:  # a mix blends the copies
        m.blend = tuple(copies.get(id(b), b) for b in m.blend)
    return changed


def untextured(material):
    material.base_texture = material.mr_texture = material.emission_texture = None
    return material


def roughened(material):
    if material.type in ("conductor", "dielectric"):
        material.alpha = 0.1
    return material


def gltf_plastic(material):
    if material.type == "diffuse" and not material.is_emissive:
        material.type, material.metallic, material.alpha = "gltf", 0.0, 0.1
    return material


# name -> (JSON key, table label, scene file, variant a, variant b); None keeps the scene as is
PAIRS = {
    "textures": ("textured_vs_untextured", "textured vs untextured", "textured.toml", None, untextured),
    "rough": ("rough_vs_smooth", "rough vs smooth (jensen)", "cornell-jensen.toml", roughened, None),
    "gltf": ("gltf_vs_diffuse", "glTF plastic vs diffuse", "cornell-box.toml", gltf_plastic, None),
}


def compare_pair(label, scene_a, scene_b, device, width, height, spp, repeat, echo=print) -> dict:
    from ..render.wavefront import Wavefront

    variants = {side: (scene, Wavefront(scene, device, width=width, height=height))
                for side, scene in (("a", scene_a), ("b", scene_b))}
    rates, _info = interleaved_render_rates(variants, spp, repeat)
    median_a, median_b = statistics.median(rates["a"]), statistics.median(rates["b"])
    echo(f"{label:<28} {median_a / 1e6:8.3f} {median_b / 1e6:8.3f}   {median_a / median_b:6.3f}")
    return {"a_samples_per_second": median_a, "b_samples_per_second": median_b, "a_over_b": median_a / median_b,
            "a_all": rates["a"], "b_all": rates["b"],
            "features_a": sorted(map(str, variants["a"][1].features)),
            "features_b": sorted(map(str, variants["b"][1].features))}


def run_materials_bench(devices=None, scenes_dir="scenes", pairs=tuple(PAIRS), width=256, height=256, spp=8,
                        repeat=3, json_path=None, echo=print) -> dict:
    from ..device import devices as device_registry
    from ..errors import UserError
    from ..scene.loaders import load_scene

    from ..render.settings import FEATURES_ENV, every_feature

    if every_feature():  # both variants would run one and the same program
        raise UserError(f"bench materials times the kernels of each variant's own features: unset ${FEATURES_ENV}")
    chosen = device_registry.resolve(devices)
    if len(chosen) != 1:
        raise UserError(f"bench materials times one device, and --device selected {len(chosen)}: pick one")
    device = chosen[0]
    results = {"device": device_registry.device_label(device), "width": width, "height": height, "spp": spp,
               "repeat": repeat, "machine": machine_info()}
    echo(f"{'pair (a vs b)':<28} {'a Ms/s':>8} {'b Ms/s':>8}   a/b")
    for name in pairs:
        key, label, scene_file, change_a, change_b = PAIRS[name]
        scene = load_scene(Path(scenes_dir) / scene_file)
        scene_a = with_materials(scene, change_a) if change_a else scene
        scene_b = with_materials(scene, change_b) if change_b else scene
        results[key] = compare_pair(label, scene_a, scene_b, device, width, height, spp, repeat, echo)
    if json_path:
        write_results(json_path, results, echo)
    return results
