"""Mitsuba 3 XML: references to objects declared later (resolved once the whole file is read, as
Mitsuba 3 resolves them) and blendbsdf with a bitmap weight, checked exactly and against Mitsuba's
own render of the same small file (scalar_rgb; the tile z-test of test_mitsuba_xml.py)."""
from __future__ import annotations

import re

import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError, load_scene

from harness import mitsuba_sensor
from scene_compare import triangle_records, triangles_equal
from test_mitsuba_xml import _z_against_mitsuba, load, mitsuba, write


def _mitsuba_image(mi, path, batches, spp):
    """Mitsuba's mean image of ``batches`` renders (seeds 0, 1, ...) and the variance of that mean."""
    scene = mi.load_file(str(path))
    images = np.stack([np.asarray(mi.render(scene, seed=i, spp=spp), np.float64) for i in range(batches)])
    return images.mean(0), images.var(0, ddof=1) / batches


def _renders_as_mitsuba(mi, path, w, h, our_spp):
    """The file loads without a warning and our render at ``our_spp`` agrees with Mitsuba's mean of 8
    renders at 64 spp: every 8x8 tile's z-score below 4.5, the image mean's below 4."""
    theirs, their_var = _mitsuba_image(mi, path, 8, 64)
    scene, warned = load(path)
    assert warned == []
    z, whole, _ = _z_against_mitsuba(scene, theirs, their_var, w, h, our_spp)
    assert np.abs(z).max() < 4.5, f"tile z-scores {np.round(z, 2)}"
    assert np.abs(whole).max() < 4.0, f"image-mean z {whole}"

# a shape that names, before they are declared, an area emitter, a bsdf (by "name") and, inside
# that bsdf, a texture (by "name"); a second bsdf only declared, then used by a later shape
FORWARD = """
{sensor}
<shape type="rectangle" id="panel">
  <transform name="to_world"><scale value="0.6"/><translate y="0.5"/></transform>
  <ref id="area-emitter"/>
  <ref name="bsdf" id="checks"/>
</shape>
<shape type="sphere"><float name="radius" value="0.35"/><point name="center" x="0" y="-0.2" z="0.3"/>
  <ref id="red"/></shape>
<emitter type="area" id="area-emitter"><rgb name="radiance" value="3, 2.5, 2"/></emitter>
<bsdf type="diffuse" id="checks"><ref name="reflectance" id="board"/></bsdf>
<texture type="checkerboard" id="board"><rgb name="color0" value="0.8, 0.2, 0.1"/>
  <rgb name="color1" value="0.1, 0.3, 0.7"/></texture>
<bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.7, 0.2, 0.2"/></bsdf>
<shape type="rectangle"><transform name="to_world"><scale value="3"/><translate z="-0.5"/></transform>
  <ref id="red"/></shape>
<emitter type="constant"><rgb name="radiance" value="0.4"/></emitter>
"""

# the same scene with every object declared before its use
BACKWARD = """
{sensor}
<texture type="checkerboard" id="board"><rgb name="color0" value="0.8, 0.2, 0.1"/>
  <rgb name="color1" value="0.1, 0.3, 0.7"/></texture>
<bsdf type="diffuse" id="checks"><ref name="reflectance" id="board"/></bsdf>
<bsdf type="diffuse" id="red"><rgb name="reflectance" value="0.7, 0.2, 0.2"/></bsdf>
<shape type="rectangle" id="panel">
  <transform name="to_world"><scale value="0.6"/><translate y="0.5"/></transform>
  <emitter type="area"><rgb name="radiance" value="3, 2.5, 2"/></emitter>
  <ref name="bsdf" id="checks"/>
</shape>
<shape type="sphere"><float name="radius" value="0.35"/><point name="center" x="0" y="-0.2" z="0.3"/>
  <ref id="red"/></shape>
<shape type="rectangle"><transform name="to_world"><scale value="3"/><translate z="-0.5"/></transform>
  <ref id="red"/></shape>
<emitter type="constant"><rgb name="radiance" value="0.4"/></emitter>
"""


def _sensor(size=32, spp=64):
    return mitsuba_sensor("0, 0, 3", 45, size, size, max_depth=3, spp=spp)


def test_forward_references_load_as_if_declared_first(tmp_path):
    fwd, warned = load(write(tmp_path, FORWARD.format(sensor=_sensor()), name="fwd.xml"))
    back, warned_back = load(write(tmp_path, BACKWARD.format(sensor=_sensor()), name="back.xml"))
    assert warned == [] and warned_back == []
    assert triangles_equal(triangle_records(fwd), triangle_records(back))
    panel = fwd.materials[fwd.face_materials[0]]
    assert panel.emission == (3.0, 2.5, 2.0) and panel.base_texture is not None  # the emitter and the texture
    assert np.array_equal(panel.base_texture.texels, back.materials[back.face_materials[0]].base_texture.texels)
    # one emitter, on the panel: the top-level area emitter is not a light of its own
    assert sum(m.is_emissive for m in fwd.materials) == 1
    assert [fwd.materials[i].albedo for i in fwd.shape_materials] == [(0.7, 0.2, 0.2)]
    # "red", referenced twice before and after its declaration: one material
    wall = fwd.face_materials[-1]
    assert fwd.shape_materials[0] == wall


def test_forward_references_render_as_mitsuba_does(tmp_path):
    mi = mitsuba()
    w = h = 32
    path = write(tmp_path, FORWARD.format(sensor=_sensor(w, 64)))
    _renders_as_mitsuba(mi, path, w, h, 256)


def test_forward_references_into_a_later_include(tmp_path):
    """A <ref> to an object that an <include> further down declares (Mitsuba reads the includes
    before it resolves references), by name and by class."""
    (tmp_path / "parts").mkdir()
    write(tmp_path, '<bsdf type="diffuse" id="grey"><ref name="reflectance" id="checks"/></bsdf>\n'
                    '<texture type="checkerboard" id="checks"><rgb name="color0" value="0.1, 0.2, 0.3"/></texture>\n'
                    '<emitter type="area" id="glow"><rgb name="radiance" value="5"/></emitter>',
          name="parts/later.xml")
    path = write(tmp_path, '<shape type="rectangle"><ref id="grey"/><ref id="glow"/></shape>\n'
                           '<shape type="rectangle"><transform name="to_world"><translate x="3"/></transform>'
                           '<ref name="bsdf" id="grey"/></shape>\n'
                           '<include filename="parts/later.xml"/>')
    scene, warned = load(path)
    assert warned == [] and len(scene.faces) == 4
    first, second = scene.materials[scene.face_materials[0]], scene.materials[scene.face_materials[-1]]
    assert first.emission == (5.0, 5.0, 5.0) and second.emission == (0.0, 0.0, 0.0)
    assert first.base_texture is not None and second.base_texture is not None
    assert np.allclose(second.base_texture.texels[0, 0, :3], [0.1, 0.2, 0.3])


@pytest.mark.parametrize("body,message", [
    # an id nothing declares, in the file or in its includes: one line, at the <ref>
    ('<shape type="sphere"><ref id="later"/></shape>\n<bsdf type="diffuse" id="sooner"/>',
     r's\.xml:2: <ref id="later">: no object with id="later" defined in the file or its includes$'),
    ('<ref id="ghost"/>', r's\.xml:2: <ref id="ghost">: no object with id="ghost" defined'),
    # Mitsuba 3 resolves an alias at once: its object must come first
    ('<alias id="b" as="c"/>\n<bsdf type="diffuse" id="b"/>',
     r's\.xml:2: <alias id="b">: no object with id="b" defined before it'),
    # a texture named twice, once by a forward reference
    ('<shape type="sphere"><bsdf type="diffuse"><ref name="reflectance" id="t"/>'
     '<rgb name="reflectance" value="0.5"/></bsdf></shape>\n<texture type="checkerboard" id="t"/>',
     r'property "reflectance" given twice'),
])
def test_dangling_references_are_one_clear_error(tmp_path, body, message):
    path = write(tmp_path, body + '<shape type="sphere"/>')
    with pytest.raises(SceneError) as info:
        load_scene(path)
    text = str(info.value)
    assert "\n" not in text and "Traceback" not in text
    assert re.search(message, text), text


# -- blendbsdf with a bitmap weight ---------------------------------------------------------------------

def _weight_images(tmp_path):
    """RGB JPEGs (4:4:4 at quality 100, and Pillow's default 4:2:0 chroma subsampling at 75), a grey
    JPEG and an RGB PNG of random texels whose luminance differs from their channels' mean."""
    from PIL import Image

    rng = np.random.default_rng(7)
    rgb = rng.integers(0, 256, (8, 8, 3)).astype(np.uint8)
    Image.fromarray(rgb, "RGB").save(tmp_path / "w.jpg", quality=100, subsampling=0)
    Image.fromarray(rgb[..., 1], "L").save(tmp_path / "g.jpg", quality=100)
    Image.fromarray(rgb, "RGB").save(tmp_path / "w.png")
    Image.fromarray(rgb, "RGB").save(tmp_path / "w420.jpg", quality=75)
    return ["w.jpg", "w420.jpg", "g.jpg", "w.png"]


def _blend(weight, second='<bsdf type="roughconductor"><string name="material" value="Au"/>'
                          '<float name="alpha" value="0.2"/></bsdf>'):
    return (f'<bsdf type="blendbsdf">{weight}<bsdf type="roughplastic">'
            f'<rgb name="diffuse_reflectance" value="0.7, 0.3, 0.1"/></bsdf>{second}</bsdf>')


@pytest.mark.parametrize("raw", [False, True], ids=["srgb", "raw"])
def test_blend_bitmap_weight_is_mitsubas_eval_1(tmp_path, raw):
    """The weight Mitsuba's blendbsdf reads from a bitmap (src/bsdfs/blendbsdf.cpp: eval_1 clamped to
    [0, 1]; src/textures/bitmap.cpp: an 8-bit image decoded from sRGB to linear unless raw, then the
    luminance of the bilinear lookup) and ours (the material's weight times its scalar texture, looked
    up as the kernel looks it up) at random uvs: equal to float32 rounding (Mitsuba stores the decoded
    8-bit texels as half floats: 1e-3).  Reading the texels as stored (no sRGB decode) or their mean
    instead of their luminance is off by up to 0.25."""
    from pyopencl_rt.scene.textures import lookup

    mi = mitsuba()
    rng = np.random.default_rng(3)
    uv = rng.random((64, 2)) * 1.5 - 0.25  # repeat wrap both sides
    flag = f'<boolean name="raw" value="{str(raw).lower()}"/>'
    for fname in _weight_images(tmp_path):
        weight = f'<texture type="bitmap" name="weight"><string name="filename" value="{fname}"/>{flag}</texture>'
        path = write(tmp_path, f'<shape type="rectangle">{_blend(weight)}</shape>', name=f"{fname}.xml")
        scene, warned = load(path)
        assert warned == []
        mat = next(m for m in scene.materials if m.type == "mix")
        tex = mat.scalar_textures["mix_weight"]
        ours = mat.mix_weight * lookup(tex.texels, uv, tex.wrap, tex.filter, tex.to_uv)[:, 0]
        bitmap = mi.load_dict({"type": "bitmap", "filename": str(tmp_path / fname), "raw": raw})
        theirs = []
        for u, v in uv:
            si = mi.SurfaceInteraction3f()
            si.uv = mi.Point2f(float(u), float(v))
            theirs.append(min(max(float(bitmap.eval_1(si)), 0.0), 1.0))
        assert np.allclose(ours, theirs, atol=1e-3), (fname, np.abs(ours - np.array(theirs)).max())


def test_blend_bitmap_weight_renders_as_mitsuba_does(tmp_path):
    """roughplastic blended with a rough gold by a JPEG weight, on a panel under a point light and a
    constant sky: our render and Mitsuba's within the noise, tile by tile (32 x 32, 8 x 8 tiles)."""
    mi = mitsuba()
    from harness import mitsuba_stage

    _weight_images(tmp_path)
    weight = '<texture type="bitmap" name="weight"><string name="filename" value="w.jpg"/></texture>'
    panel = f'<shape type="rectangle"><transform name="to_world"><scale value="1.2"/></transform>{_blend(weight)}</shape>'
    w = h = 32
    body = mitsuba_stage(mitsuba_sensor("0, 0, 3", 45, w, h, max_depth=3, spp=64), panel, '<bsdf type="diffuse"/>')
    path = write(tmp_path, body)
    _renders_as_mitsuba(mi, path, w, h, 512)


@pytest.mark.parametrize("raw", [False, True], ids=["srgb", "raw"])
def test_blend_of_a_mirror_by_a_bitmap_weight_is_the_blends_expectation(tmp_path, raw):
    """A white furnace: a panel seen head-on under a constant sky of 1, one bounce, blending a diffuse
    of 0.5 and a smooth gold mirror by a uniform grey JPEG of 8-bit value 150.  Every pixel is then
    (1 - w) 0.5 + w F, F gold's reflectance at normal incidence (taken from Mitsuba's conductor) and
    w = 150 / 255 decoded from sRGB (0.305), or 150 / 255 itself with raw (0.588).

    Mitsuba 3.9.1's own render of this file is darker (red 0.56 for 0.62 at w = 0.25): its blendbsdf
    weighs a delta sample against the other BSDF's density (docs/SCENE_FORMAT.md, blendbsdf), so a
    blend with a smooth conductor or dielectric is compared with the closed form, not with Mitsuba."""
    import pyopencl_rt as rt
    from PIL import Image

    mi = mitsuba()
    Image.fromarray(np.full((4, 4), 150, np.uint8), "L").save(tmp_path / "grey.jpg", quality=100)
    flag = f'<boolean name="raw" value="{str(raw).lower()}"/>'
    weight = f'<texture type="bitmap" name="weight"><string name="filename" value="grey.jpg"/>{flag}</texture>'
    blend = (f'<bsdf type="blendbsdf">{weight}<bsdf type="diffuse"><rgb name="reflectance" value="0.5"/></bsdf>'
             '<bsdf type="conductor"><string name="material" value="Au"/></bsdf></bsdf>')
    path = write(tmp_path, f"""
<integrator type="path"><integer name="max_depth" value="2"/></integrator>
<sensor type="perspective"><float name="fov" value="10"/>
  <transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0" up="0, 1, 0"/></transform>
  <film type="hdrfilm"><integer name="width" value="8"/><integer name="height" value="8"/><rfilter type="box"/></film>
</sensor>
<emitter type="constant"><rgb name="radiance" value="1"/></emitter>
<shape type="rectangle"><transform name="to_world"><scale value="2"/></transform>{blend}</shape>""")
    gold = mi.load_dict({"type": "conductor", "material": "Au"})
    si = mi.SurfaceInteraction3f()
    si.n = mi.Normal3f(0, 0, 1)
    si.sh_frame = mi.Frame3f(si.n)
    si.wi = mi.Vector3f(0, 0, 1)
    _, f0 = gold.sample(mi.BSDFContext(), si, 0.5, mi.Point2f(0.5, 0.5))
    g = 150 / 255
    w = g if raw else ((g + 0.055) / 1.055) ** 2.4
    exact = (1 - w) * 0.5 + w * np.array(f0, np.float64)
    scene, warned = load(path)
    assert warned == []
    r = rt.render_full(scene, spp=1024, width=8, height=8, device="cpu", seed=3)
    # the panel's pixels see 5 degrees off its normal at most: F within 1e-4 of normal incidence
    mean = r.image.astype(np.float64).mean((0, 1))
    sigma = np.sqrt(r.film.variance_of_mean().sum((0, 1))) / 64
    assert np.all(np.abs(mean - exact) < 4 * sigma + 1e-4), (mean, exact, sigma)
