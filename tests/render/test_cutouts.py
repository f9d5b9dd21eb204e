"""Texture lookups (to_uv, wrap modes, filters) and alpha cut-outs (Mitsuba's mask BSDF) rendered
as Mitsuba 3 renders them: one small XML scene rendered by Mitsuba (scalar_rgb) at test time and by
us, compared tile by tile (cl/scene/textures.h, cl/render/path.h)."""
from __future__ import annotations

import warnings

import numpy as np

import pyopencl_rt as rt
from pyopencl_rt.scene.loaders import load_scene

import harness
from harness import mitsuba_rect

W, H, TILE = 48, 32, 8


def _write_png(path, a, mode):
    from PIL import Image

    Image.fromarray(np.asarray(a, np.uint8), mode).save(path)


def _scene(tmp_path, max_depth=3, variant=False) -> str:
    """Six panels in front of a grey wall under a constant sky and a point light: a bitmap with
    to_uv and mirror / clamp wrapping, bilinear and nearest; a checkerboard scaled 4 x 2 by to_uv; a
    bitmap rotated and scaled by to_uv, nearest;
    a masked one-sided diffuse seen from behind, and a masked twosided diffuse seen from behind,
    whose opacity is a bitmap of holes and grey (0.5) texels.  ``variant``: each of these features
    changed (mirror and clamp -> repeat, nearest -> bilinear, the checkerboard's and bitmaps'
    to_uv dropped, no masks), to show that the comparison sees each."""
    rng = np.random.default_rng(7)
    _write_png(tmp_path / "colors.png", rng.integers(0, 256, (5, 6, 3)), "RGB")
    holes = np.where((np.indices((8, 8)).sum(0) % 3) == 0, 0, 255)
    holes[2:4, 2:6] = 128
    _write_png(tmp_path / "holes.png", holes, "L")

    def bitmap(wrap, filt, to_uv='<scale x="2.5" y="2"/><translate x="-0.7" y="-0.5"/>'):
        if variant:
            wrap, filt = "repeat", "bilinear"
        return ('<bsdf type="diffuse"><texture type="bitmap" name="reflectance"><string name="filename" '
                f'value="colors.png"/><string name="wrap_mode" value="{wrap}"/><string name="filter_type" '
                f'value="{filt}"/><transform name="to_uv">{to_uv}</transform></texture></bsdf>')

    checker_uv = "" if variant else '<scale x="4" y="2"/>'
    checker = ('<bsdf type="diffuse"><texture type="checkerboard" name="reflectance"><rgb name="color0" value="0.8, '
               '0.2, 0.1"/><rgb name="color1" value="0.1, 0.3, 0.9"/>'
               f'<transform name="to_uv">{checker_uv}</transform></texture></bsdf>')
    leaf = '<bsdf type="diffuse"><rgb name="reflectance" value="0.1, 0.8, 0.1"/></bsdf>'

    def mask(nested):
        if variant:
            return nested
        return ('<bsdf type="mask"><texture type="bitmap" name="opacity"><string name="filename" value="holes.png"/>'
                f'<string name="filter_type" value="nearest"/></texture>{nested}</bsdf>')

    panels = [
        mitsuba_rect(-2.0, 1.0, bitmap("mirror", "bilinear")),
        mitsuba_rect(0.0, 1.0, bitmap("clamp", "nearest")),
        mitsuba_rect(2.0, 1.0, checker),
        mitsuba_rect(-2.0, -1.0, mask(leaf), angle=160),  # one-sided, seen from behind
        mitsuba_rect(0.0, -1.0, mask(f'<bsdf type="twosided">{leaf}</bsdf>'), angle=160),
        mitsuba_rect(2.0, -1.0, bitmap("repeat", "nearest",
                                       "" if variant else '<rotate z="1" angle="30"/><scale value="1.5"/>')),
    ]
    body = harness.mitsuba_stage(harness.mitsuba_sensor("0.3, 0.4, 6", 55, W, H, max_depth=max_depth, spp=64),
                                 "".join(panels), '<bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>')
    return harness.write_mitsuba_scene(tmp_path / f"cutouts{'_variant' if variant else ''}{max_depth}.xml", body)




def test_texture_lookups_and_masks_match_mitsuba(tmp_path):
    """48 x 32, six panels: bitmaps with to_uv under each wrap mode and filter, a checkerboard and a
    bitmap scaled (and rotated) by to_uv, and two masked diffuse panels seen from behind
    (one-sided: black but for its holes; twosided: green), by Mitsuba (4 batches of 64 spp: their
    spread its variance) and by us (512 spp): every 8 x 8 tile within 4.5 sigma, at max_depth 3
    and at max_depth 2 (where a path through a hole ends at the wall it reaches: the null bounce
    counts, as in Mitsuba); measured: 1.9 and 1.5.  Mitsuba's render of the variant scene (each
    feature changed) is more than 10 sigma from ours in every tile (measured: 19 and more at
    max_depth 3): the comparison sees each panel's feature."""
    mi = harness.mitsuba()

    for depth in (3, 2):
        path = _scene(tmp_path, max_depth=depth)
        theirs, their_var = harness.mitsuba_batches(mi, path, batches=4)
        with warnings.catch_warnings():
            warnings.simplefilter("error")  # every element is read without a word
            scene = load_scene(path)
        r = rt.render_full(scene, spp=512, device="cpu", seed=3)
        ours, var = r.image.astype(np.float64), r.film.variance_of_mean()
        z = harness.tile_z(ours, var, theirs, their_var, TILE)
        assert z.max() < 4.5, (depth, np.round(z.max(-1), 1))
        if depth == 3:
            other, other_var = harness.mitsuba_batches(mi, _scene(tmp_path, max_depth=depth, variant=True), batches=4)
            z_other = harness.tile_z(ours, var, other, other_var, TILE).max(-1)
            assert z_other.min() > 10, np.round(z_other, 1)


def test_lookups_and_masks_in_lanes(device, monkeypatch, tmp_path):
    """The scene above (every wrap mode and filter, to_uv, masks one- and two-sided): the same film
    bit for bit and the same rays at one lane and at the device's lane width (cl/render/path.h)."""
    widths = ("0", harness.forced_lanes(device))
    scene = load_scene(_scene(tmp_path, max_depth=4))
    results = harness.lane_renders(scene, device, monkeypatch, widths, spp=4, seed=2, width=W, height=H)
    harness.assert_same_lanes(results)


def _cutout_scene(pbrt_like=True):
    """A floor (albedo 0.5) under a directional light straight down (irradiance 1), seen from above
    by an orthographic camera through a black quad at height 0.5 that is an alpha cut-out in the
    intersection: alpha 0, 0.5 and 1 in thirds along x (a 3 x 1 texture, nearest)."""
    from pyopencl_rt.scene.model import Camera, DirectionalLight, Material, RenderSettings, Scene
    from pyopencl_rt.scene.textures import texture_from_array

    quad = np.array([[-1, 0, -1], [-1, 0, 1], [1, 0, 1], [1, 0, -1]], np.float32)
    v = np.concatenate([quad, quad + [0, 0.5, 0]])
    f = np.array([[0, 1, 2], [0, 2, 3], [4, 5, 6], [4, 6, 7]], np.int32)
    uv = ((v[f][..., [0, 2]] + 1) / 2).astype(np.float32)
    alpha = texture_from_array(np.array([[0.0, 0.5, 1.0]], np.float32)).with_lookup(filter="nearest")
    cut = Material("cut", albedo=(0, 0, 0), cutout=True, opacity=1.0, scalar_textures={"opacity": alpha})
    return Scene(vertices=v, faces=f, face_materials=np.array([0, 0, 1, 1], np.int32),
                 materials=[Material("floor", albedo=(0.5,) * 3), cut], uvs=uv,
                 camera=Camera(eye=(0, 2, 0), look_at=(0, 0, 0), up=(0, 0, -1), projection="orthographic", extent=2),
                 lights=[DirectionalLight(direction=(0, -1, 0), irradiance=(1, 1, 1))],
                 settings=RenderSettings(width=30, height=30, max_depth=2))


def test_intersection_cutouts_closed_form(device):
    """pbrt-v4's alpha (Material.cutout, cl/scene/scene.h): where alpha is 0 the camera sees the lit
    floor, 0.5 / pi; where it is 0.5 a camera ray passes with probability 1/2 and so does the
    floor's shadow ray (each its own hash): 0.5 / (4 pi); where it is 1 the black quad, 0.  And
    the same bits at every lane width."""
    scene = _cutout_scene()
    assert scene.material_defines().get("HAS_CUTOUTS")
    r = rt.render_full(scene, spp=256, device=device, seed=4)
    img = r.image.astype(np.float64).mean(-1)
    thirds = [img[2:28, 1:9].mean(), img[2:28, 11:19].mean(), img[2:28, 21:29].mean()]
    assert abs(thirds[0] / (0.5 / np.pi) - 1) < 0.01, thirds
    assert abs(thirds[1] / (0.5 / (4 * np.pi)) - 1) < 0.03, thirds
    assert thirds[2] == 0.0, thirds


def test_intersection_cutouts_in_lanes(device, monkeypatch):
    widths = ("0", harness.forced_lanes(device))
    results = harness.lane_renders(_cutout_scene(), device, monkeypatch, widths, spp=8, seed=2)
    harness.assert_same_lanes(results)
