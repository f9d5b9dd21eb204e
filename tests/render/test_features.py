"""One program for every scene ($PYOPENCL_RT_KERNEL_FEATURES=all, render/settings.py): the
features a scene does not use only add code that its data never selects, so the image is the
scene's own kernel's bit for bit.  This is what lets the test suite run with every feature
compiled in (tests/conftest.py) while users get kernels with only what their scene uses."""
from pathlib import Path

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.device import abi
from pyopencl_rt.render import megakernel
from pyopencl_rt.render.settings import EVERY_FEATURE, FEATURES_ENV
from pyopencl_rt.errors import UsageError

import harness

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def both(scene, device, monkeypatch, **options):
    """The render with the scene's own features and with every feature, in that order."""
    out = []
    for mode in ("scene", "all"):
        monkeypatch.setenv(FEATURES_ENV, mode)
        out.append(rt.render_full(scene, device=device, **options))
    return out


def assert_same(own, every):
    """The same film bit for bit and the same ray counts; ``every``'s kernel had every feature
    and ``own``'s only what the scene uses (at least one fewer)."""
    features = set(every.info["features"])
    assert set(EVERY_FEATURE) <= features
    assert not set(EVERY_FEATURE) <= set(own.info["features"])
    assert not any(f.startswith("HAS_MATERIAL_") or f == "MATERIALS_SELECTED" for f in features)
    assert own.info["lanes"] == every.info["lanes"]
    assert np.array_equal(own.film.sum, every.film.sum)
    assert np.array_equal(own.film.sum_sq, every.film.sum_sq)
    assert (own.stats.rays_extend, own.stats.rays_shadow) == (every.stats.rays_extend, every.stats.rays_shadow)


@pytest.mark.parametrize("name", ["mitsuba-cbox", "textured-sky", "cornell-fog", "many-lights", "clamped", "spheres"])
def test_every_feature_renders_the_same_bits(device, monkeypatch, name):
    """A box of diffuse triangles and an area light (almost nothing compiled in of its own), a
    textured scene under an environment map with spheres, a box with fog (the volumetric
    integrator), thousands of lamps picked by the light BVH, the box again with the run-time
    choices that a scene's kernel compiles in (the stratified sampler, pbrt's maxcomponentvalue),
    and spheres without a triangle (the empty BVH traversed): at the lane width users get
    (megakernel)."""
    import dataclasses

    monkeypatch.setenv(megakernel.LANES_ENV, harness.forced_lanes(device))
    options = {}
    if name == "clamped":
        scene = rt.load_scene(SCENES / "mitsuba-cbox.toml")
        scene.settings = dataclasses.replace(scene.settings, max_component_value=0.5)
        options["sampler"] = "stratified"
    elif name == "spheres":
        from scenes_small import small_scene

        scene = dataclasses.replace(small_scene(), vertices=np.zeros((0, 3), np.float32),
                                    faces=np.zeros((0, 3), np.int32), face_materials=np.zeros(0, np.int32))
    else:
        scene = rt.load_scene(SCENES / f"{name}.toml")
    own, every = both(scene, device, monkeypatch, kernel_mode="megakernel", spp=2, seed=4, width=32, height=24,
                      max_depth=6, **options)
    assert_same(own, every)
    if name == "clamped":  # the clamp and the sampler were the scene kernel's defines
        assert {"MAX_COMPONENT_VALUE=0.5f", f"SAMPLER={abi.SAMPLERS['stratified']}"} <= set(own.info["features"])
    assert every.info["light_tree"] is (name == "many-lights") is ("LIGHT_TREE" in own.info["features"])
    if name == "spheres":
        assert "HAS_TRIANGLES" not in own.info["features"] and own.image.mean() > 0.1


def test_every_feature_renders_the_same_bits_one_path_per_item(device, monkeypatch):
    """Vertex normals, normal and bump maps and vertex colours beside flat faces: the width-1
    megakernel (as GPUs run it) and the wavefront stages."""
    from scenes_small import shading_scene

    monkeypatch.setenv(megakernel.LANES_ENV, "0")
    scene = shading_scene()
    for mode in ("megakernel", "wavefront"):
        assert_same(*both(scene, device, monkeypatch, kernel_mode=mode, spp=2, seed=2, width=24, height=16))


def test_the_setting_is_checked(device, monkeypatch):
    monkeypatch.setenv(FEATURES_ENV, "some")
    with pytest.raises(UsageError, match=FEATURES_ENV):
        rt.render_full(rt.load_scene(SCENES / "mitsuba-cbox.toml"), device=device, spp=1, width=4, height=4)
