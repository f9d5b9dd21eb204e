"""The megakernel schedule (cl/megakernel/path.cl, pyopencl_rt/render/megakernel.py): the same
samples as the wavefront, so the same image bit for bit, the same rays traced, and the same
handling of passes, time limits and interruptions.  Runs on every device (forced where the
device's default schedule is the wavefront)."""
from pathlib import Path

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.errors import UserError
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.megakernel import kernel_mode
from pyopencl_rt.render.wavefront import Wavefront

SCENES = Path(__file__).resolve().parents[2] / "scenes"


def both(scene, device, **options):
    """The same render with each schedule."""
    common = dict(spp=3, device=device, seed=11, width=40, height=28, **options)
    return (rt.render_full(scene, kernel_mode="wavefront", **common),
            rt.render_full(scene, kernel_mode="megakernel", **common))


@pytest.mark.parametrize("name", ["cornell-box", "cornell-jensen", "veach-mis", "textured"])
def test_same_image_and_rays_as_the_wavefront(device, name):
    """Every material, spheres, textures and MIS: the film sums are equal bit for bit, and so are
    the numbers of closest-hit and shadow rays (the same paths were traced)."""
    scene = rt.load_scene(SCENES / f"{name}.toml")
    wavefront, megakernel = both(scene, device)
    assert wavefront.info["kernel_mode"] == "wavefront" and megakernel.info["kernel_mode"] == "megakernel"
    assert np.array_equal(wavefront.film.sum, megakernel.film.sum)
    assert np.array_equal(wavefront.film.sum_sq, megakernel.film.sum_sq)
    assert megakernel.stats.rays_extend == wavefront.stats.rays_extend > 0
    assert megakernel.stats.rays_shadow == wavefront.stats.rays_shadow > 0


def test_other_lights_integrators_and_depths(device):
    """Point, directional, spot, projector and environment lights, the single-technique
    integrators, a max depth."""
    scene = rt.load_scene(SCENES / "cornell-box.toml")
    from pyopencl_rt.scene.model import DirectionalLight, Environment, PointLight, ProjectorLight, SpotLight, look_at_frame

    scene.lights = [PointLight(position=(278.0, 400.0, 200.0), intensity=(2e4, 2e4, 2e4)),
                    DirectionalLight(direction=(0.2, -1.0, 0.3), irradiance=(0.5, 0.5, 0.5)),
                    SpotLight(position=(278.0, 540.0, 278.0), intensity=(3e4, 2e4, 1e4), cutoff_angle=40,
                              to_world=look_at_frame((278, 540, 278), (300, 0, 250), (0, 0, 1))),
                    ProjectorLight(position=(100.0, 300.0, 100.0), irradiance=(1e4, 2e4, 3e4), fov=30,
                                   to_world=look_at_frame((100, 300, 100), (400, 100, 500), (0, 1, 0)))]
    scene.environment = Environment(radiance=(0.2, 0.3, 0.4))
    for options in ({}, {"integrator": "nee"}, {"integrator": "bsdf", "max_depth": 3}, {"max_depth": -1}):
        wavefront, megakernel = both(scene, device, **options)
        assert np.array_equal(wavefront.film.sum, megakernel.film.sum), options


def test_passes_larger_than_the_wave_and_resumed_passes(device):
    """A pass of more pixels than the wave size takes several launches; passes started at an
    offset (a resume, another device's share) are the same passes."""
    scene = rt.load_scene(SCENES / "cornell-box.toml")
    reference = Wavefront(scene, device, width=40, height=28, seed=5, kernel_mode="wavefront")
    small = Wavefront(scene, device, width=40, height=28, seed=5, kernel_mode="megakernel", wave_size=300)
    a, b = Film(40, 28), Film(40, 28)
    reference.run(a, passes=5)
    small.run(b, passes=2)
    small.run(b, passes=3, first_pass=2)
    assert b.passes == 5 and np.array_equal(a.sum, b.sum)


def test_cancel_keeps_whole_passes(device):
    scene = rt.load_scene(SCENES / "cornell-box.toml")
    wf = Wavefront(scene, device, width=24, height=16, seed=2, kernel_mode="megakernel", wave_size=24 * 16)
    calls = []

    def cancel():
        calls.append(1)
        return len(calls) > 3

    film = Film(24, 16)
    stats = wf.run(film, passes=50, cancel=cancel)
    assert stats.interrupted and film.passes == stats.passes == 3
    reference = Film(24, 16)
    Wavefront(scene, device, width=24, height=16, seed=2, kernel_mode="wavefront").run(reference, passes=3)
    assert np.array_equal(film.sum, reference.sum)


def test_schedule_choice(device):
    import pyopencl as cl

    cpu = bool(device.type & cl.device_type.CPU)
    assert kernel_mode(device, "opencl", None) == ("megakernel" if cpu else "wavefront")
    assert kernel_mode(device, "embree", None) == "wavefront"  # Embree traces the wavefront's queues
    assert kernel_mode(device, "opencl", ["albedo"]) == "wavefront"  # AOVs live in wavefront buffers
    with pytest.raises(UserError, match="megakernel"):
        kernel_mode(device, "embree", None, "megakernel")
    with pytest.raises(UserError, match="unknown kernel mode"):
        kernel_mode(device, "opencl", None, "fast")
    # participating media choose no schedule (both have the medium step), but take no film AOVs
    for requested in (None, "wavefront", "megakernel"):
        assert kernel_mode(device, "opencl", None, requested, media=True) == kernel_mode(device, "opencl", None,
                                                                                          requested)
    with pytest.raises(UserError, match="AOVs .* participating media"):
        kernel_mode(device, "opencl", ["albedo"], media=True)

