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
    assert [fwd.materials[i].albedo for i in fwd.sphere_materials] == [(0.7, 0.2, 0.2)]
    # "red", referenced twice before and after its declaration: one material
    wall = fwd.face_materials[-1]
    assert fwd.sphere_materials[0] == wall


def test_forward_references_render_as_mitsuba_does(tmp_path):
    mi = mitsuba()
    w = h = 32
    path = write(tmp_path, FORWARD.format(sensor=_sensor(w, 64)))
    theirs, their_var = _mitsuba_image(mi, path, 8, 64)
    scene, warned = load(path)
    assert warned == []
    z, whole, _ = _z_against_mitsuba(scene, theirs, their_var, w, h, 256)
    assert np.abs(z).max() < 4.5, f"tile z-scores {np.round(z, 2)}"
    assert np.abs(whole).max() < 4.0, f"image-mean z {whole}"


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
