"""The Mitsuba export of environment maps, image textures, point and directional lights, participating
media, and of the scenes of ``bench set`` (pyopencl_rt/bench/mitsuba_export.py): Mitsuba 3 (``scalar_rgb``, run at
test time in the interpreter that has it, as tests/bench/test_convergence.py does) renders the
exported scene, and its means per region equal ours.

Tolerance: per region and channel, |ours - Mitsuba| <= 5 standard errors of the difference (our
film's variance of the region mean, taken twice: Mitsuba's estimator has about the same variance)
+ 1% of our mean.  The 1% is for what differs by construction: the exported environment map is
our nearest texels resampled on a finer grid, which Mitsuba filters bilinearly (a blur of a small
fraction of our texel at its edges: the test's map is smooth, so that the blur is far below 1%),
and the renderers' random numbers.  A wrong orientation (the map turned by half a turn or
mirrored, a texture flipped in v) moves the regions by 30% and more here.  Skipped without
Mitsuba.
"""
import json
import subprocess
from pathlib import Path

import numpy as np
import pytest

import harness

from pyopencl_rt import load_scene
from pyopencl_rt.bench import mitsuba_host
from pyopencl_rt.bench.mitsuba_export import mitsuba_envmap, save_scene_npz, scene_arrays
from pyopencl_rt.imageio import write_exr
from pyopencl_rt.render.api import render_full
from pyopencl_rt.scene.model import Environment
from pyopencl_rt.render.settings import ImageSettings

SIZE = 32
BLOCK = 8  # regions of BLOCK x BLOCK pixels
HERE = Path(__file__).parent
TEXTURED_SCENE = HERE / "textured_scene.toml"  # beside quarters.png, which the test writes


def mitsuba_python():
    python, why = mitsuba_host.find_mitsuba_python(variant="scalar_rgb")
    if python is None:
        pytest.skip(f"Mitsuba not installed: {why}")
    return python


def render_both(scene, tmp_path, device, spp, size=SIZE):
    """(ours, Mitsuba's, our variance of the mean) at size x size.  Ours in our default sampler (its kernel is the one
    most tests build): the variance of its samples over spp is the independent samples' variance of
    the mean, which the scrambled Sobol mean's stays below on these smooth images (Owen 1997), so
    the regions' z-test errs on the safe side."""
    python = mitsuba_python()
    ours = render_full(scene, spp=spp, width=size, height=size, device=device, seed=5)
    settings = ImageSettings.resolve(scene, width=size, height=size)
    save_scene_npz(tmp_path / "scene.npz", scene_arrays(scene, settings, spp=spp))
    subprocess.run([python, str(mitsuba_host.HERE / "mitsuba_runner.py"), str(tmp_path / "scene.npz"), str(tmp_path),
                    "--checkpoints", str(spp), "--variant", "scalar_rgb"],
                   check=True, capture_output=True, env=mitsuba_host.mitsuba_env(), timeout=300)
    theirs = np.load(tmp_path / f"mitsuba_{spp}.npy").astype(np.float64)
    return ours.image.astype(np.float64), theirs, ours.film.variance_of_mean()


def region_means(image, block=BLOCK):
    h, w = image.shape[:2]
    return image.reshape(h // block, block, w // block, block, -1).mean(axis=(1, 3))


def assert_regions_agree(ours, theirs, variance, block=BLOCK):
    a, b = region_means(ours, block), region_means(theirs, block)
    se = np.sqrt(2 * region_means(variance, block) / (block * block))
    bad = np.abs(a - b) > 5 * se + 0.01 * a
    assert not bad.any(), (f"regions (row, column, channel) {np.argwhere(bad).tolist()}: ours {a[bad]}, "
                           f"Mitsuba {b[bad]}, standard error {se[bad]}")
    return a, b


def sky_map(path, height=32, width=64):
    """A map with no symmetry: red as cos(phi) and green as sin(phi) of the azimuth (phi = 2 pi u),
    blue brighter upwards, and a bright Gaussian spot at (u, v) = (0.3, 0.35); smooth, so that
    our nearest texel and Mitsuba's bilinear filtering of the export agree in any region."""
    v, u = np.meshgrid((np.arange(height) + 0.5) / height, (np.arange(width) + 0.5) / width, indexing="ij")
    phi = 2 * np.pi * u
    image = np.stack([0.6 + 0.5 * np.cos(phi), 0.6 + 0.5 * np.sin(phi), 0.3 + 0.6 * (1 - v)], -1)
    image += 15.0 * np.exp(-0.5 * (((u - 0.3) * width) ** 2 + ((v - 0.35) * height) ** 2) / 2.0 ** 2)[..., None]
    write_exr(path, image.astype(np.float32))
    return image


def test_envmap_export_is_our_map_in_mitsubas_layout():
    """Without Mitsuba: a map of centred rows is sampled at Mitsuba's nodes (column i at
    u = (i + 1/2) / W', row j at v = j / (H' - 1), u turned by half a turn), bilinearly as our
    kernel reads it; a map with rows on the poles (Mitsuba's own) goes as it is, with the to_world
    of its rotation."""
    ours = np.arange(4 * 8 * 3, dtype=np.float32).reshape(4, 8, 3)
    out, to_world = mitsuba_envmap(Environment(radiance=(2.0, 1.0, 1.0), image=ours), upsample=2)
    assert out.shape == (8, 16, 3) and np.array_equal(to_world, np.eye(3))
    s = np.array([2.0, 1.0, 1.0])
    # Mitsuba's u = 1/32 is our u = 0.53125: x = 3.75 between our columns 3 and 4; v = 0: row 0
    assert np.allclose(out[0, 0], (0.25 * ours[0, 3] + 0.75 * ours[0, 4]) * s, rtol=1e-5)
    # its u = 0.53125 is our 0.03125: x = -0.25, wrapping around between columns 7 and 0
    assert np.allclose(out[0, 8], (0.25 * ours[0, 7] + 0.75 * ours[0, 0]) * s, rtol=1e-5)
    # the bottom row is the south pole's (our row 3, clamped); u = 31/32 -> our 15/32: x = 3.25
    assert np.allclose(out[7, 15], (0.75 * ours[3, 3] + 0.25 * ours[3, 4]) * s, rtol=1e-5)
    # v = 3/7: y = 12/7 - 1/2 between our rows 1 and 2
    a = 12 / 7 - 1.5
    assert np.allclose(out[3, 8], ((1 - a) * (0.25 * ours[1, 7] + 0.75 * ours[1, 0])
                                   + a * (0.25 * ours[2, 7] + 0.75 * ours[2, 0])) * s, rtol=1e-5)
    c, sn = np.cos(0.4), np.sin(0.4)
    rot = np.array([[c, 0, sn], [0, 1, 0], [-sn, 0, c]])
    out, to_world = mitsuba_envmap(Environment(radiance=(2.0, 1.0, 1.0), image=ours, rows="poles", rotation=rot))
    assert np.array_equal(out, ours * s.astype(np.float32))
    # a world direction w: ours reads the map at rot @ w, Mitsuba at to_world^-1 @ w, turned
    assert np.allclose(np.diag([-1.0, 1.0, -1.0]) @ rot, np.linalg.inv(to_world))


def test_environment_map_renders_the_same(tmp_path, device):
    """The sky seen directly (looking along -z, then straight up) and a diffuse sphere lit by it."""
    sky_map(tmp_path / "sky.exr")
    for name, look_at, up in (("horizon", [0, 0, -1], [0, 1, 0]), ("zenith", [0, 1, 0], [0, 0, -1])):
        (tmp_path / f"{name}.toml").write_text(harness.toml_tables(
            camera=dict(eye=[0, 0, 0], look_at=look_at, up=up, fov=100), render=dict(max_depth=1)) + """
[environment]
file = "sky.exr"
scale = [1.0, 0.9, 1.1]
[[shape]]
type = "sphere"
center = [0, -50, 0]
radius = 0.01
""")
        ours, theirs, variance = render_both(load_scene(tmp_path / f"{name}.toml"), tmp_path, device, spp=16)
        assert_regions_agree(ours, theirs, variance)
    (tmp_path / "lit.toml").write_text(harness.toml_tables(
        camera=dict(eye=[0, 0, 3], look_at=[0, 0, 0], fov=45), render=dict(max_depth=4)) + """
[environment]
file = "sky.exr"
[[shape]]
type = "sphere"
center = [0, 0, 0]
radius = 1
""")
    ours, theirs, variance = render_both(load_scene(tmp_path / "lit.toml"), tmp_path, device, spp=128)
    a, _ = assert_regions_agree(ours, theirs, variance)
    assert a[1, 1].sum() > 0.1  # the sphere is lit


def test_image_textures_and_delta_lights_render_the_same(tmp_path, device):
    """A diffuse quad with an albedo texture under a constant sky, a point, a directional, a spot
    and a projector light, and an emissive quad with an emission texture, both quads with a texture
    of four different quarters (and a gradient within each), seen at an angle."""
    from PIL import Image

    y, x = np.indices((16, 16))
    quarters = np.array([[230, 40, 40], [40, 230, 40], [40, 40, 230], [230, 230, 230]])
    texture = quarters[(y // 8) * 2 + x // 8] * (0.5 + x[..., None] / 32)
    Image.fromarray(texture.astype(np.uint8)).save(tmp_path / "quarters.png")
    (tmp_path / "textured.toml").write_text(TEXTURED_SCENE.read_text())
    ours, theirs, variance = render_both(load_scene(tmp_path / "textured.toml"), tmp_path, device, spp=64)
    a, _ = assert_regions_agree(ours, theirs, variance)
    assert a.max() > 0.2


@pytest.mark.parametrize("name", ["textured-sky", "materials"])
def test_set_scenes_render_the_same(tmp_path, device, name):
    """The two scenes made for the set: whole-image means within 5 standard errors + 1% (regions
    would need far more samples with the glass's caustics)."""
    scene = load_scene(f"scenes/{name}.toml")
    ours, theirs, variance = render_both(scene, tmp_path, device, spp=128, size=24)
    assert_regions_agree(ours, theirs, variance, block=24)


def test_export_refuses_what_mitsuba_cannot_render_the_same():
    scene = load_scene("scenes/textured.toml")  # its glTF model's materials are the gltf type
    with pytest.raises(ValueError, match="gltf"):
        scene_arrays(scene)


def test_runner_records_the_counts_a_stratifying_sampler_renders(tmp_path):
    """Mitsuba's stratified sampler rounds 2 and 3 spp up to 4, 6 and 8 to 9: each point is the
    count rendered, and a checkpoint of less than twice the samples of the render before is skipped."""
    python = mitsuba_python()
    scene = load_scene("scenes/mitsuba-cbox.toml")
    save_scene_npz(tmp_path / "scene.npz", scene_arrays(scene, ImageSettings.resolve(scene, width=8, height=8)))
    subprocess.run([python, str(mitsuba_host.HERE / "mitsuba_runner.py"), str(tmp_path / "scene.npz"), str(tmp_path),
                    "--checkpoints", "1,2,3,4,6,8,12,16", "--variant", "scalar_rgb", "--sampler", "stratified"],
                   check=True, capture_output=True, env=mitsuba_host.mitsuba_env(), timeout=300)
    info = json.loads((tmp_path / "mitsuba.json").read_text())
    assert [point["spp"] for point in info["points"]] == [1, 4, 9]
    assert all(np.load(point["image"]).shape == (8, 8, 3) for point in info["points"])


# participating media (issue 25): a camera in a haze bounded by an index-matched sphere, a chromatic fog
# slab in an index-matched box, a glass sphere holding a dense forward-scattering medium, and a
# chromatic grid puff in an index-matched box, lit by a constant sky and a directional light
MEDIA_SCENE = HERE / "media_scene.toml"


def test_media_export_maps_every_part(tmp_path):
    """Without Mitsuba: the records of the media scene (integrator, media, grids, interfaces, the
    camera's medium); the integrator is volpath once spectral MIS is off or the media are grey;
    a trilinear grid fading to 0 outside its box is refused."""
    import dataclasses

    scene = load_scene(MEDIA_SCENE)
    arrays = scene_arrays(scene, ImageSettings.resolve(scene, width=8, height=8))
    s = json.loads(arrays["settings"])["media"]
    names = [m.name for m in scene.media]
    assert s["integrator"] == "volpathmis" and s["camera_medium"] == names.index("haze")
    by_name = dict(zip(names, s["media"]))
    assert by_name["marble"] == {"name": "marble", "sample_emitters": True, "phase": {"type": "hg", "g": 0.7},
                                 "albedo": [0.95] * 3, "type": "homogeneous", "sigma_t": [1.5] * 3, "scale": 1.0}
    smoke = by_name["smoke"]
    assert smoke["type"] == "heterogeneous" and smoke["scale"] == 1.0 and smoke["phase"] == {"type": "isotropic"}
    values = arrays[smoke["sigma_t"]["grid"]]  # density times the chromatic sigma_t, (z, y, x, 3)
    assert values.shape == (3, 3, 3, 3) and np.allclose(values[1, 1, 1], [3.2, 0.8, 0.2])
    assert np.allclose(smoke["sigma_t"]["to_world"],
                       [[1.2, 0, 0, -1.4], [0, 1.2, 0, -0.2], [0, 0, 1.2, 0.2], [0, 0, 0, 1]])
    itfs = [(i["interior"], i["exterior"], i["null"]) for i in s["interfaces"]]
    h, f, m, k = (names.index(n) for n in ("haze", "fog", "marble", "smoke"))
    assert itfs == [(h, -1, True), (f, h, True), (m, h, False), (k, h, True)]
    assert arrays["shape_interfaces"].tolist() == [0, 2] and set(arrays["face_interfaces"].tolist()) == {-1, 1, 3}
    scene.settings.spectral_mis = False
    assert json.loads(scene_arrays(scene)["settings"])["media"]["integrator"] == "volpath"
    scene.settings.spectral_mis = True
    grey = dataclasses.replace(scene, media=[dataclasses.replace(md, sigma_t=(1.0, 1.0, 1.0)) for md in scene.media])
    assert json.loads(scene_arrays(grey)["settings"])["media"]["integrator"] == "volpath"
    smoke_medium = scene.media[k]
    smoke_medium.density = dataclasses.replace(smoke_medium.density, outside="zero")
    with pytest.raises(ValueError, match="zero"):
        scene_arrays(scene)
    smoke_medium.density = dataclasses.replace(smoke_medium.density, filter="nearest")
    scene_arrays(scene)  # nearest texels inside the box: the same as clamping


def test_media_scene_renders_the_same(tmp_path, device):
    """Every part of the media export at once (the scene above, 16 x 16, 256 spp, ~3 s with the
    kernel built): means of the whole image, of 8 x 8 and of 4 x 4 regions within 5 standard errors
    + 1%.  What this catches (measured at 64 spp by altering the export, worst region at
    |difference| / tolerance; at 256 spp the tolerance is about half): interior and exterior
    swapped 8.7-19, the camera's medium dropped 2.3-4.1, the grid mirrored in x 1.5-3.0, the
    chromatic grid made grey 1.9-3.3, Henyey-Greenstein's g negated 1.2-1.6; as exported 0.5-0.7.
    (``volpath`` for ``volpathmis`` is 0.6: both are unbiased, only their noise differs.)  At 64
    spp a 4 x 4 region of Mitsuba's render carried a firefly (0.286 against 0.236, ours at 1024
    spp and three seeds, the same before and after this stop's sampling changes), which the
    tolerance, taken from our variance, did not allow for once our random numbers changed: 1.16;
    at 256 spp the worst region is at 0.51."""
    ours, theirs, variance = render_both(load_scene(MEDIA_SCENE), tmp_path, device, spp=256, size=16)
    a, _ = assert_regions_agree(ours, theirs, variance, block=16)
    assert a.min() > 0.1
    for block in (8, 4):
        assert_regions_agree(ours, theirs, variance, block=block)


def test_two_level_instances_export_as_their_moved_copies():
    """A scene drawn through the two-level BVH (a world quad; a two-triangle group of two
    materials in three instances: turned and moved, scaled unevenly, mirrored) is exported as
    what it renders: the world's faces and, per instance, each group triangle's corners moved by
    its to_world with the front on the side of M^-T n (corners reversed under the mirror), its
    material kept; the group's own-space faces are not exported."""
    from pyopencl_rt.scene.model import BlasGroup, Instance, Material, Scene

    v = np.array([[-3, -1, -3], [3, -1, -3], [3, -1, 3], [-3, -1, 3],  # world quad
                  [0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)  # the group's corners
    faces = np.array([[0, 2, 1], [0, 3, 2], [4, 5, 6], [4, 7, 5]], np.int32)
    scene = Scene(vertices=v, faces=faces, face_materials=np.array([0, 0, 1, 2], np.int32),
                  materials=[Material(albedo=(0.5, 0.5, 0.5)), Material(albedo=(0.8, 0.2, 0.2)),
                             Material(albedo=(0.2, 0.2, 0.8))])
    c, s = np.cos(0.7), np.sin(0.7)
    turned = np.array([[c, 0, s, 1.5], [0, 1, 0, 0.2], [-s, 0, c, -0.5], [0, 0, 0, 1]])
    uneven = np.diag([2.0, 0.5, 1.0, 1.0])
    mirror = np.diag([-1.0, 1.0, 1.0, 1.0]) @ turned
    scene.blas_groups = [BlasGroup("g", 2, 2)]
    scene.instances = [Instance("g", m, blas=0) for m in (turned, uneven, mirror)]
    scene.camera.eye, scene.camera.look_at = (0.0, 1.0, 8.0), (0.0, 0.0, 0.0)

    arrays = scene_arrays(scene, ImageSettings.resolve(scene, width=8, height=8), spp=1)
    tri = np.asarray(arrays["vertices"], np.float64)[arrays["faces"]]
    mats = arrays["face_materials"]
    assert len(tri) == 2 + 3 * 2
    assert np.allclose(tri[:2], v[faces[:2]]) and (mats[:2] == 0).all()
    exported = [(t, m) for t, m in zip(tri[2:], mats[2:])]
    for m in (turned, uneven, mirror):
        for f, mat in zip(faces[2:], (1, 2)):
            p = v[f].astype(np.float64)
            moved = p @ m[:3, :3].T + m[:3, 3]
            n = np.linalg.inv(m[:3, :3]).T @ np.cross(p[1] - p[0], p[2] - p[0])
            match = [(t, k) for t, k in exported
                     if np.allclose(np.sort(t, axis=0), np.sort(moved, axis=0), atol=1e-5)]
            assert len(match) == 1, (m, f)
            t, k = match[0]
            assert k == mat
            assert np.dot(np.cross(t[1] - t[0], t[2] - t[0]), n) > 0
