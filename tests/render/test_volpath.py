"""The volumetric path tracer (cl/render/volpath.h in the megakernel, cl/megakernel/path.cl) in whole
renders against closed forms, on every device:

- transmittance: an emitter seen through a homogeneous absorbing slab behind index-matched (null)
  boundaries has radiance Le exp(-sigma_t d) per channel, grey and chromatic, with the spectral-MIS
  weights (volpathmis) and with the hero channel's alone (volpath);
- a furnace: an albedo-1 chromatic medium (the camera in it) inside an enclosure whose two-sided walls
  emit Le and reflect half (diffuse): the radiance is Le / (1 - 1/2) everywhere, medium or not;
- single scattering: a thin Henyey-Greenstein slab lit by a directional light, max_depth 2, against the
  integral of sigma_s E p(cos) exp(-sigma_t x (1 + 1 / cos alpha)) over the slab's depth;
- 8 (and 16) lanes render the bits of one lane on scenes/cornell-fog.toml (null boxes, a grid, a
  dielectric boundary, chromatic fog);
- the wavefront stages render the megakernel's bits (the one volumetric step, volpath_vertex, in both
  schedules; the same samples and tracking streams) on scenes/cornell-fog.toml (null boxes, a grid, a
  dielectric boundary, chromatic fog) and on the furnace (the camera inside a chromatic HG medium), and
  the closed forms above hold for them too;
- a scene without media compiles no media code (the preprocessed megakernel and wavefront stages), and
  binds dummies.

Estimates are pixel means over independent pixels: |z| < Z_MAX with the pixels' spread as the error."""
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.render import megakernel
from pyopencl_rt.render.settings import every_feature

import harness

Z_MAX = 4.5
SCENES = Path(__file__).resolve().parents[2] / "scenes"


def load(tmp_path, text, name="s.toml"):
    path = tmp_path / name
    path.write_text(text)
    return rt.load_scene(path)


def pixel_means(result):
    img = np.asarray(result.image, np.float64)[..., :3]
    return img.reshape(-1, 3)


def assert_mean(result, expected, rel=None):
    """The pixels' mean against expected (3 numbers), by a z-test over the pixels (and |rel| if given)."""
    px = pixel_means(result)
    mean, err = px.mean(0), px.std(0, ddof=1) / np.sqrt(len(px))
    z = (mean - expected) / np.maximum(err, 1e-12)
    assert np.all(np.abs(z) < Z_MAX), (mean, expected, z)
    if rel is not None:
        assert np.allclose(mean, expected, rtol=rel), (mean, expected)
    return mean


SLAB = """
[camera]
type = "orthographic"
eye = [0.0, 0.0, -5.0]
look_at = [0.0, 0.0, 0.0]
extent = 1.0

[film]
width = 16
height = 16

[render]
spp = {spp}
max_depth = 8
seed = 3

[materials.glow]
albedo = [0.0, 0.0, 0.0]
emission = [2.0, 1.0, 0.5]

[media.slab]
sigma_t = {sigma}
albedo = 0.0

[[shape]]  # the emitter, facing the camera
type = "quad"
material = "glow"
points = [[-2.0, -2.0, 3.0], [-2.0, 2.0, 3.0], [2.0, 2.0, 3.0], [2.0, -2.0, 3.0]]

[[shape]]  # the slab, z in [-{half}, {half}]
type = "box"
center = [0.0, 0.0, 0.0]
size = [4.0, 4.0, {d}]
index_matched = true
interior = "slab"
"""


@pytest.mark.parametrize("sigma, spectral_mis, mode", [((1.0, 1.0, 1.0), True, "auto"), ((0.5, 1.5, 3.0), True, "auto"),
                                                       ((0.5, 1.5, 3.0), False, "auto"),
                                                       ((0.5, 1.5, 3.0), True, "wavefront")])
def test_slab_transmittance(device, tmp_path, sigma, spectral_mis, mode):
    """Radiance through an absorbing slab of depth d: Le exp(-sigma_t d), channel by channel (by the
    device's schedule, and by the wavefront stages)."""
    d = 0.8
    scene = load(tmp_path, SLAB.format(spp=64, sigma=list(sigma), d=d, half=d / 2))
    scene.settings.spectral_mis = spectral_mis
    r = rt.render_full(scene, device=device, kernel_mode=mode)
    assert mode == "auto" or r.info["kernel_mode"] == mode
    assert "HAS_MEDIA" in r.info["features"]
    if not every_feature():  # else compiled in, and the kernels' spectral_mis chooses
        assert ("SPECTRAL_MIS" in r.info["features"]) == (spectral_mis and len(set(sigma)) > 1)
    expected = np.array([2.0, 1.0, 0.5]) * np.exp(-np.array(sigma) * d)
    assert_mean(r, expected, rel=0.05)


FURNACE = """
[camera]
eye = [0.0, 0.0, 0.0]
look_at = [0.3, 0.2, 1.0]
fov = 90
medium = "fog"

[film]
width = 16
height = 16

[render]
spp = 48
max_depth = 1000
seed = 5

[materials.wall]
albedo = 0.5
emission = 1.0
two_sided = true

[media.fog]
sigma_t = [0.3, 0.8, 1.6]
albedo = 1.0
phase = "hg"
g = 0.4

[[shape]]  # the enclosure
type = "box"
center = [0.0, 0.0, 0.0]
size = 4.0
material = "wall"

[[shape]]  # the fog, a little inside it (the camera too)
type = "box"
center = [0.0, 0.0, 0.0]
size = 3.6
index_matched = true
interior = "fog"
"""


@pytest.mark.parametrize("mode", ["auto", "wavefront"])
def test_furnace(device, tmp_path, mode):
    """An albedo-1 medium in a white furnace neither adds nor takes light: Le / (1 - albedo) = 2; by
    the device's own schedule and by the wavefront stages."""
    r = rt.render_full(load(tmp_path, FURNACE), device=device, kernel_mode=mode, spp=48 if mode == "auto" else 16)
    assert "SPECTRAL_MIS" in r.info["features"]
    assert mode == "auto" or r.info["kernel_mode"] == "wavefront"
    assert_mean(r, np.full(3, 2.0), rel=0.05)


def ortho_header(**render) -> str:
    """A 16 x 16 orthographic view of the unit square around the origin from z = -5, and ``render``."""
    return harness.toml_tables(camera=dict(type="orthographic", eye=[0.0, 0.0, -5.0], look_at=[0.0, 0.0, 0.0],
                                           extent=1.0), film=dict(width=16, height=16), render=render)


SINGLE = ortho_header(spp=64, max_depth=2, seed=7) + """
[materials.black]
albedo = 0.0

[media.slab]
sigma_t = [1.0, 2.0, 4.0]
albedo = 0.8
phase = "hg"
g = 0.5

[[light]]
type = "directional"
direction = [{sx}, 0.0, {cz}]
irradiance = 3.0

[[shape]]  # the slab, z in [0, d]
type = "box"
center = [0.0, 0.0, {half}]
size = [100.0, 100.0, {d}]
index_matched = true
interior = "slab"
"""


def test_single_scattering(device, tmp_path):
    """Single scattering (max_depth 2: the camera segment and one scattering vertex's light sample) of
    a directional light by a chromatic HG slab, against the numerical integral over the depth."""
    d, alpha, g, albedo, E = 0.5, np.radians(30.0), 0.5, 0.8, 3.0
    sigma = np.array([1.0, 2.0, 4.0])
    scene = load(tmp_path, SINGLE.format(sx=np.sin(alpha), cz=np.cos(alpha), d=d, half=d / 2))
    r = rt.render_full(scene, device=device)
    cos = np.cos(alpha)  # dot(light's travel, camera ray): the phase function's argument
    phase = (1 - g * g) / (4 * np.pi * (1 + g * g + 2 * g * cos) ** 1.5)
    x = np.linspace(0.0, d, 20001)
    integrand = np.exp(-np.outer(sigma, x) * (1 + 1 / np.cos(alpha)))
    integral = np.sum((integrand[:, 1:] + integrand[:, :-1]) * 0.5 * np.diff(x), axis=1)
    expected = albedo * sigma * E * phase * integral
    assert_mean(r, expected, rel=0.05)


def test_spot_light_in_a_medium(device, tmp_path):
    """Volumetric next-event estimation from a spot light: the slab above lit by a spot whose beam
    covers every scattering point the camera sees renders what a point light of its intensity
    renders (the same samples: Le differs only by rounding); aimed away, nothing."""
    text = SINGLE.format(sx=0.0, cz=1.0, d=0.5, half=0.25).split("[[light]]")
    point = text[0] + '[[light]]\ntype = "point"\nposition = [0.2, 0.1, -1.0]\nintensity = 2.0\n' + \
        text[1].split("\n", 4)[4]
    spot = point.replace('type = "point"', 'type = "spot"\nlook_at = [0.2, 0.1, 0.0]\ncutoff_angle = 85\n'
                                           'beam_width = 80')
    results = [rt.render_full(load(tmp_path, t, f"{i}.toml"), device=device, spp=4) for i, t in enumerate((point, spot))]
    assert results[0].image.mean() > 0.005
    assert np.allclose(results[1].film.sum, results[0].film.sum, rtol=1e-5, atol=0)
    away = spot.replace("look_at = [0.2, 0.1, 0.0]", "look_at = [0.2, 0.1, -2.0]")
    assert rt.render_full(load(tmp_path, away, "away.toml"), device=device, spp=4).film.sum.max() == 0


@pytest.mark.parametrize("width_set", harness.width_sets())
def test_lanes_render_the_same_bits(device, monkeypatch, width_set):
    """The lane widths (harness.width_sets: the users' in make test, all in make stress) against
    one path per work-item on the media scene of scenes/ (test_path_lanes.py's rule)."""
    widths = harness.widths_of(device, width_set)  # skips where lanes never run
    scene = rt.load_scene(SCENES / "cornell-fog.toml")
    results = harness.lane_renders(scene, device, monkeypatch, widths, spp=2, seed=4, width=24, height=24)
    assert "HAS_MEDIA" in results["0"].info["features"] and results["0"].film.sum.max() > 0
    harness.assert_same_lanes(results)


@pytest.mark.parametrize("name", ["cornell-fog", "furnace"])
def test_wavefront_renders_the_megakernel_bits(device, tmp_path, monkeypatch, name):
    """The wavefront stages (the medium step in shade, the transmittance in shadow, the path's medium,
    hero channel, ratios and tracking stream kept per slot) against the megakernel at the lane width
    the device gets: the same film bit for bit, and the same rays traced.  cornell-fog: chromatic fog
    and a grid in null boxes, a medium inside a glass sphere; the furnace: the camera inside a
    chromatic Henyey-Greenstein medium, long paths."""
    monkeypatch.delenv(megakernel.LANES_ENV, raising=False)
    scene = rt.load_scene(SCENES / "cornell-fog.toml") if name == "cornell-fog" else load(tmp_path, FURNACE)
    options = dict(device=device, spp=2, seed=4, width=16, height=16, max_depth=8 if name == "furnace" else 6)
    wavefront = rt.render_full(scene, kernel_mode="wavefront", **options)
    mega = rt.render_full(scene, kernel_mode="megakernel", **options)
    assert {"HAS_MEDIA", "SPECTRAL_MIS"} <= set(wavefront.info["features"])
    assert wavefront.info["kernel_mode"] == "wavefront" and mega.info["kernel_mode"] == "megakernel"
    assert wavefront.film.sum.max() > 0
    assert np.array_equal(wavefront.film.sum, mega.film.sum)
    assert np.array_equal(wavefront.film.sum_sq, mega.film.sum_sq)
    assert (wavefront.stats.rays_extend, wavefront.stats.rays_shadow) == (mega.stats.rays_extend, mega.stats.rays_shadow)


def test_embree_refuses_media(device, tmp_path):
    """Embree's shadow stage is an any-hit test: a scene with media (which needs the transmittance) is
    refused in one line, before anything is built."""
    from pyopencl_rt.errors import UserError
    from pyopencl_rt.render.wavefront import Wavefront

    with pytest.raises(UserError, match="embree: scenes with participating media"):
        Wavefront(load(tmp_path, FURNACE), device, width=8, height=8, intersector="embree")


def preprocessed(features, sources=megakernel.SOURCES) -> str:
    from pyopencl_rt.device.kernels import assemble, define_options

    src = assemble(*sources)
    features = {k: v for k, v in features.items() if k not in megakernel.lane_features(8)}  # one lane: plain C
    out = subprocess.run([shutil.which("cpp"), "-P", *define_options(features)], input=src, capture_output=True,
                         text=True, check=True)
    return out.stdout


@pytest.mark.skipif(shutil.which("cpp") is None, reason="needs the C preprocessor")
def test_no_media_no_media_code(device, tmp_path):
    """A scene without media compiles none of the volumetric code (no HAS_MEDIA, and the preprocessed
    megakernel and wavefront stages have no medium step, no media fields in the path state, and never
    touch the per-slot media buffers, bound to dummies); with media they do."""
    from pyopencl_rt.render import wavefront
    from pyopencl_rt.render.wavefront import Wavefront

    plain = Wavefront(rt.load_scene(SCENES / "cornell-box.toml"), device, width=8, height=8, kernel_mode="wavefront",
                      wave_size=256)
    assert "HAS_MEDIA" not in plain.features and "SPECTRAL_MIS" not in plain.features
    assert plain.buffer("vol_rng").size == plain.buffer("vol_r").size == 16  # dummies
    code = ("path_medium(", "volpath_vertex", "shadow_transmittance", "medium_sample_free_flight", "puint rng;",
            "vol_rng[", "sh_medium[")
    for sources, kernel in ((megakernel.SOURCES, "mk_path"), (wavefront.SOURCES, "wf_shade")):
        src = preprocessed(plain.features, sources)
        assert kernel in src
        for name in code:
            assert name not in src, (kernel, name)
    fog = Wavefront(rt.load_scene(SCENES / "cornell-fog.toml"), device, width=8, height=8, kernel_mode="wavefront",
                    wave_size=256)
    assert {"HAS_MEDIA", "SPECTRAL_MIS"} <= set(fog.features)
    assert fog.buffer("vol_rng").size == 4 * 256 and fog.buffer("vol_r").size == 12 * 256
    for sources in (megakernel.SOURCES, wavefront.SOURCES):
        src = preprocessed(fog.features, sources)
        for name in ("path_medium(", "volpath_vertex", "shadow_transmittance", "medium_sample_free_flight"):
            assert name in src, name
    assert "vol_rng[" in preprocessed(fog.features, wavefront.SOURCES)


THIN = ortho_header(spp=64, max_depth=4, seed=9) + """
[materials.glow]
albedo = [0.0, 0.0, 0.0]
emission = [2.0, 1.0, 0.5]

[[shape]]  # the emitter, facing the camera
type = "quad"
material = "glow"
points = [[-2.0, -2.0, 3.0], [-2.0, 2.0, 3.0], [2.0, 2.0, 3.0], [2.0, -2.0, 3.0]]
"""


@pytest.mark.parametrize("media", [False, True])
def test_thin_dielectric_sheet(device, tmp_path, media):
    """Mitsuba's thindielectric (a dielectric with MATERIAL_FLAG_THIN): at normal incidence an emitter
    behind the sheet is seen through it, undeflected, with 1 - R, R = F + (1 - F)^2 F / (1 - F^2): by the
    surface integrator's BSDF sampling, and (media: an empty index-matched box makes it the volumetric
    one) as the null crossing with probability 1 - R of cl/render/volpath.h."""
    from pyopencl_rt.scene.model import Material

    box = '\n[[shape]]\ntype = "box"\ncenter = [0.0, 0.0, 1.5]\nsize = 1.0\nindex_matched = true\n'
    scene = load(tmp_path, THIN + (box if media else ""))
    assert scene.has_media() == media
    scene.uvs = scene.normals = None
    glow = scene.materials[0]
    sheet = Material(name="sheet", type="dielectric", ior=1.5, thin=True)
    scene.materials = [glow, sheet]
    # a sheet at z = 0, both triangles facing the camera
    v = np.array([[-2, -2, 0], [-2, 2, 0], [2, 2, 0], [2, -2, 0]], np.float32)
    n = len(scene.vertices)
    scene.vertices = np.concatenate([scene.vertices, v]).astype(np.float32)
    scene.faces = np.concatenate([scene.faces, np.array([[n, n + 1, n + 2], [n, n + 2, n + 3]])]).astype(np.int32)
    scene.face_materials = np.concatenate([scene.face_materials, [1, 1]]).astype(np.int32)
    if scene.face_interfaces is not None:
        scene.face_interfaces = np.concatenate([scene.face_interfaces, [-1, -1]]).astype(np.int32)
    r = rt.render_full(scene, device=device)
    assert ("HAS_MEDIA" in r.info["features"]) == media
    F = 0.04  # ((1.5 - 1) / (1.5 + 1))^2
    R = F + (1 - F) ** 2 * F / (1 - F * F)
    assert_mean(r, np.array([2.0, 1.0, 0.5]) * (1 - R))
    if r.stats.rays_extend:  # straight through: the image is Le (1 - R) on average, never deflected
        assert pixel_means(r).max() <= 2.0 + 1e-6
