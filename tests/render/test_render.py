"""The path tracer against closed forms and against itself, on every available device.

Statistics: a pixel's estimate is a mean over passes; the film keeps each pixel's sum of
squares, so its standard error is known.  Tolerances are stated next to each test.  Tests
that compare many numbers at once use a Bonferroni bound for a 1e-3 overall false-alarm rate.
"""
import numpy as np
import pytest

from pyopencl_rt import load_scene
from pyopencl_rt.render.api import render_full
from pyopencl_rt.scene.model import Camera, Material, RenderSettings, Scene
from pyopencl_rt.scene.shapes.sphere import records as sphere_records

CORNELL = "scenes/cornell-box.toml"
FLOAT_TOL = 2e-5  # relative: float32 arithmetic floor for near-zero-variance cases


def empty_mesh():
    return dict(vertices=np.zeros((0, 3), np.float32), faces=np.zeros((0, 3), np.int32),
                face_materials=np.zeros(0, np.int32))


def furnace_scene(shell_albedo, shell_emission, max_depth, integrator, inner_albedo=None):
    """Camera at the centre of an emissive, diffuse sphere of radius 10 (two-sided); optionally
    a diffuse sphere of radius 2 in front of the camera."""
    mats = [Material("shell", albedo=(shell_albedo,) * 3, emission=(shell_emission,) * 3, two_sided=True)]
    spheres = [[0, 0, 0, 10]]
    sphere_mats = [0]
    if inner_albedo is not None:
        mats.append(Material("ball", albedo=(inner_albedo,) * 3))
        spheres.append([0, 0, -5, 2])
        sphere_mats.append(1)
    return Scene(**empty_mesh(), materials=mats,
                 camera=Camera(eye=(0, 0, 0), look_at=(0, 0, -1), up=(0, 1, 0), fov=60),
                 shapes=sphere_records(np.array(spheres, np.float32)), shape_materials=np.array(sphere_mats, np.int32),
                 settings=RenderSettings(width=32, height=32, max_depth=max_depth, integrator=integrator))


def assert_mean(image, expect, label):
    """Mean of i.i.d. pixels within 3 standard errors (+ the float32 floor).  The standard error
    is that of the pixels' channel means: the channels of a pixel are one sample's three values
    (equal in a grey scene), not three independent samples."""
    pixels = np.asarray(image, np.float64).reshape(-1, image.shape[-1]).mean(axis=1)
    m = float(pixels.mean())
    se = float(pixels.std()) / np.sqrt(pixels.size)
    assert abs(m - expect) <= 3 * se + FLOAT_TOL * abs(expect), f"{label}: mean {m} vs {expect} (se {se:.2g})"


@pytest.mark.parametrize("integrator", ["path", "bsdf", "nee"])
def test_white_furnace(device, integrator):
    """A diffuse sphere of albedo 1 inside a uniform emitter of radiance 1 renders 1 in every
    pixel, for every bounce count (max_depth 2, 3, 5 and unlimited)."""
    for depth in (2, 3, 5, -1):
        r = render_full(furnace_scene(0.0, 1.0, depth, integrator, inner_albedo=1.0), spp=32, device=device, seed=3)
        assert r.info["nonfinite_samples"] == 0
        assert_mean(r.image, 1.0, f"{integrator} depth {depth}")


@pytest.mark.parametrize("integrator", ["path", "bsdf", "nee"])
def test_reflective_furnace_every_depth(device, integrator):
    """Inside an emitter of radiance Le that also reflects diffusely with albedo a, a path of at
    most D segments sees Le * (1 - a^D) / (1 - a): every bounce, Russian roulette and (for MIS)
    the weights of light sampling from inside a sphere are exercised."""
    a, le = 0.5, 0.5
    for depth in (1, 2, 3, 5, -1):
        expect = le * (1 - a**depth) / (1 - a) if depth > 0 else le / (1 - a)
        r = render_full(furnace_scene(a, le, depth, integrator), spp=64, device=device, seed=5)
        assert_mean(r.image, expect, f"{integrator} depth {depth}")


def test_plane_under_uniform_sky(device):
    """A diffuse plane of albedo rho under a sky of radiance L (a huge two-sided emissive sphere
    of albedo 0) has radiance rho * L wherever the camera sees it."""
    rho, sky = 0.3, 2.0
    v = np.array([[-50, 0, -50], [50, 0, -50], [50, 0, 50], [-50, 0, 50]], np.float32)
    f = np.array([[0, 2, 1], [0, 3, 2]], np.int32)
    sc = Scene(vertices=v, faces=f, face_materials=np.zeros(2, np.int32),
               materials=[Material("plane", albedo=(rho,) * 3), Material("sky", albedo=(0, 0, 0), emission=(sky,) * 3,
                                                                        two_sided=True)],
               camera=Camera(eye=(0, 1, 0), look_at=(0, 0, 0.001), up=(0, 0, 1), fov=30),
               shapes=sphere_records(np.array([[0, 0, 0, 1000]], np.float32)), shape_materials=np.array([1], np.int32),
               settings=RenderSettings(width=32, height=32, max_depth=3))
    for integrator in ("path", "bsdf", "nee"):
        r = render_full(sc, spp=32, device=device, seed=7, integrator=integrator)
        assert_mean(r.image, rho * sky, integrator)


def tile_means(image, var, k=8):
    h, w, c = image.shape
    m = image.astype(np.float64).reshape(h // k, k, w // k, k, c).mean(axis=(1, 3))
    v = var.reshape(h // k, k, w // k, k, c).sum(axis=(1, 3)) / (k * k) ** 2
    return m, v


@pytest.fixture(scope="module")
def cornell():
    return load_scene(CORNELL)


def test_integrators_agree_on_cornell_box(device, cornell):
    """path (MIS), bsdf and nee converge to the same image: tile-wise z-tests (8x8-pixel tiles,
    3 channels, 3 pairs = 144 tests; |z| < 4.5 is a 1e-3 overall false-alarm rate by
    Bonferroni) on independent renders (different seeds).  Error: MIS well below BSDF sampling
    alone, and not above light sampling alone (on this scene, with a small diffuse light,
    light sampling is already nearly optimal; see test_mis_beats_both_on_a_large_light)."""
    res = {}
    for i, integ in enumerate(("path", "bsdf", "nee")):
        r = render_full(cornell, spp=256, device=device, seed=100 + i, width=32, height=32, integrator=integ)
        assert r.info["nonfinite_samples"] == 0
        res[integ] = tile_means(r.image, r.film.variance_of_mean()) + (r.film.variance_of_mean().mean(),)
    for a, b in (("path", "bsdf"), ("path", "nee"), ("bsdf", "nee")):
        (ma, va, _), (mb, vb, _) = res[a], res[b]
        z = (ma - mb) / np.sqrt(va + vb)
        assert np.abs(z).max() < 4.5, f"{a} vs {b}: max |z| = {np.abs(z).max():.2f}"
    var_path, var_bsdf, var_nee = res["path"][2], res["bsdf"][2], res["nee"][2]
    assert var_path < 0.5 * var_bsdf
    assert var_path < 1.05 * var_nee


def test_mis_beats_both_on_a_large_light(device):
    """A diffuse floor under a large, close emitter: light sampling suffers from the 1/r^2 of
    points near the light, BSDF sampling from directions that miss it; MIS has the lowest
    variance (mean per-pixel variance of the estimate, same sample count)."""
    v = np.array([[-4, 0, -4], [4, 0, -4], [4, 0, 4], [-4, 0, 4],            # floor
                  [-2, 0.3, -2], [-2, 0.3, 2], [2, 0.3, 2], [2, 0.3, -2]], np.float32)  # light, facing down
    f = np.array([[0, 2, 1], [0, 3, 2], [4, 6, 5], [4, 7, 6]], np.int32)
    sc = Scene(vertices=v, faces=f, face_materials=np.array([0, 0, 1, 1], np.int32),
               materials=[Material("floor", albedo=(0.7,) * 3), Material("light", albedo=(0, 0, 0), emission=(3,) * 3)],
               camera=Camera(eye=(0, 4, 6), look_at=(0, 0, 0), up=(0, 1, 0), fov=50),
               settings=RenderSettings(width=32, height=32, max_depth=2))
    var = {}
    for integ in ("path", "bsdf", "nee"):
        r = render_full(sc, spp=128, device=device, seed=21, integrator=integ)
        var[integ] = r.film.variance_of_mean().mean()
    assert var["path"] < var["nee"] and var["path"] < var["bsdf"], var


def test_deterministic_for_a_seed(device, cornell):
    a = render_full(cornell, spp=4, device=device, seed=42, width=24, height=16).image
    b = render_full(cornell, spp=4, device=device, seed=42, width=24, height=16).image
    c = render_full(cornell, spp=4, device=device, seed=43, width=24, height=16).image
    assert np.array_equal(a, b)
    assert not np.array_equal(a, c)
    assert np.isfinite(a).all() and a.shape == (16, 24, 3)


def test_wave_size_does_not_change_the_image(device, cornell):
    """Random numbers are keyed by (pixel, pass, dimension) and passes are summed in order, so
    how many paths are in flight (and which slot a path used) cannot matter."""
    a = render_full(cornell, spp=3, device=device, seed=9, width=20, height=20, wave_size=256).image
    b = render_full(cornell, spp=3, device=device, seed=9, width=20, height=20, wave_size=4096).image
    assert np.array_equal(a, b)


def test_only_used_features_are_compiled(device, cornell, own_features):
    r = render_full(cornell, spp=1, device=device, width=8, height=8)
    assert "HAS_TRIANGLES" in r.info["features"] and "HAS_LIGHTS" in r.info["features"]
    assert "HAS_SHAPES" not in r.info["features"]
    dark = Scene(vertices=cornell.vertices, faces=cornell.faces, face_materials=np.zeros_like(cornell.face_materials),
                 materials=[Material("grey")], camera=cornell.camera)
    r = render_full(dark, spp=1, device=device, width=8, height=8)
    assert "HAS_LIGHTS" not in r.info["features"]
    assert (r.image == 0).all()  # nothing emits: exactly black
    balls = furnace_scene(0.0, 1.0, 3, "bsdf")
    r = render_full(balls, spp=1, device=device, width=8, height=8)
    assert "HAS_SHAPES" in r.info["features"] and "HAS_TRIANGLES" not in r.info["features"]
    assert not any(f.startswith("INTEGRATOR") for f in r.info["features"])  # a kernel argument


def test_max_depth_one_shows_only_emitters(device, cornell):
    img = render_full(cornell, spp=2, device=device, width=32, height=32, max_depth=1).image
    lit = (img > 0).any(axis=2)
    assert 0 < lit.sum() < 0.05 * lit.size  # the light alone: a few per cent of the frame
    assert np.allclose(img[lit].max(axis=0), [17.0, 12.0, 4.0], rtol=1e-6)


def test_prepared_wavefront_sets_the_image(device, cornell):
    """A Wavefront built once (as `bench render` and the convergence bench do) fixes the
    resolution, seed and settings; it used to be given the scene's 512x512 film (a crash)."""
    from pyopencl_rt.render.wavefront import Wavefront

    wf = Wavefront(cornell, device, width=20, height=12, seed=5)
    a = render_full(cornell, spp=2, wavefront=wf).image
    b = render_full(cornell, spp=2, device=device, width=20, height=12, seed=5).image
    assert a.shape == (12, 20, 3)
    assert np.array_equal(a, b)
