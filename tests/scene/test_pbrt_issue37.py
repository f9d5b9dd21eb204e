"""pbrt-v4 loader (issue 37): gzip-compressed scene and PLY files, singular transforms, parameter
lists that go on after an included file ends, .spd spectrum files, coatedconductor's prefixed
parameters, the scale and mix textures, and the film's iso and exposure time; each against exact
parse results or closed forms."""
from __future__ import annotations

import gzip
import re
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError, load_scene

from harness import load_error, load_warned as load
from scene_compare import triangle_records, triangles_equal
from pyopencl_rt.scene.shapes.sphere import of as sphere_of

TRIANGLE = 'Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0]'


def write(tmp_path, text, name="s.pbrt") -> Path:
    path = tmp_path / name
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text)
    return path


def gz(path: Path) -> Path:
    """path.gz: path's bytes gzip-compressed (path removed)."""
    out = path.with_name(path.name + ".gz")
    out.write_bytes(gzip.compress(path.read_bytes()))
    path.unlink()
    return out


def _ply(path: Path) -> Path:
    """An ASCII PLY of two triangles with vertex normals (not the faces')."""
    path.write_text("ply\nformat ascii 1.0\nelement vertex 4\nproperty float x\nproperty float y\nproperty float z\n"
                    "property float nx\nproperty float ny\nproperty float nz\n"
                    "element face 2\nproperty list uchar int vertex_indices\nend_header\n"
                    "0 0 0 0.6 0 0.8\n2 0 0 0.6 0 0.8\n2 3 0 0 0.6 0.8\n0 3 0 0 0.6 0.8\n3 0 1 2\n3 0 2 3\n")
    return path


# -- (a) gzip ------------------------------------------------------------------------------------------

def test_gzipped_scene_include_and_ply_read_as_the_plain_files(tmp_path):
    body = ('Material "diffuse" "rgb reflectance" [0.2 0.4 0.6]\n'
            'Shape "plymesh" "string filename" "{ply}"\nInclude "{inc}"\n')
    write(tmp_path, 'Translate 0 0 -1\n' + TRIANGLE + '\n', name="plain/inc.pbrt")
    _ply(tmp_path / "plain" / "m.ply")
    plain, warned = load(write(tmp_path, "WorldBegin\n" + body.format(ply="m.ply", inc="inc.pbrt"),
                               name="plain/s.pbrt"))
    assert warned == [] and len(plain.faces) == 3
    write(tmp_path, 'Translate 0 0 -1\n' + TRIANGLE + '\n', name="zipped/inc.pbrt")
    gz(tmp_path / "zipped" / "inc.pbrt")
    gz(_ply(tmp_path / "zipped" / "m.ply"))
    main = gz(write(tmp_path, "WorldBegin\n" + body.format(ply="m.ply.gz", inc="inc.pbrt.gz"), name="zipped/s.pbrt"))
    assert main.name == "s.pbrt.gz"
    zipped, warned = load(main)
    assert warned == []
    assert triangles_equal(triangle_records(zipped), triangle_records(plain))
    assert np.allclose(np.sort(zipped.vertices, axis=0)[-1], [2, 3, 0])  # the PLY's, not only the include's


def test_a_corrupt_gzip_file_is_one_error_line(tmp_path):
    bad = tmp_path / "bad.pbrt.gz"
    bad.write_bytes(b"\x1f\x8b\x08\x00 this is not deflate data")
    with pytest.raises(SceneError) as info:
        load_scene(bad)
    assert "\n" not in str(info.value) and re.match(rf"{re.escape(str(bad))}: not a valid gzip file", str(info.value))
    (tmp_path / "m.ply.gz").write_bytes(b"plain bytes, not gzip")
    path = write(tmp_path, 'WorldBegin\nShape "plymesh" "string filename" "m.ply.gz"\n')
    with pytest.raises(SceneError, match=r's\.pbrt:2: Shape "plymesh": .*m\.ply\.gz: not a valid gzip file') as info:
        load_scene(path)
    assert "\n" not in str(info.value)


# -- (c) parameter lists across includes -------------------------------------------------------------------

def test_a_parameter_list_goes_on_after_the_included_file_ends(tmp_path):
    """pbrt-v4's parser reads an included file's tokens in place of the Include: a directive begun in
    the included file takes parameters that follow the Include in the including file, and one begun
    before the Include takes the included file's first parameters."""
    write(tmp_path, 'Shape "trianglemesh"\n  "point3 P" [0 0 0  2 0 0  0 3 0  2 3 0]\n', name="geo/head.pbrt")
    write(tmp_path, '"point2 uv" [0 0  1 0  0 1]\n', name="geo/uv.pbrt")
    path = write(tmp_path, 'WorldBegin\nMaterial "diffuse"\nInclude "geo/head.pbrt"\n  "integer indices" [0 1 2  2 1 3]\n'
                           'Shape "trianglemesh" "point3 P" [0 0 5  1 0 5  0 1 5]\nInclude "geo/uv.pbrt"\n'
                           '"float alpha" 1\n')
    s, warned = load(path)
    assert warned == []
    v = s.vertices.astype(np.float64)[s.faces]
    assert v.shape == (3, 3, 3)
    assert np.allclose(v[0], [[0, 0, 0], [2, 0, 0], [0, 3, 0]]) and np.allclose(v[1], [[0, 3, 0], [2, 0, 0], [2, 3, 0]])
    assert np.allclose(v[2], [[0, 0, 5], [1, 0, 5], [0, 1, 5]])
    # the second shape's uvs came from the included file (v flipped to our convention)
    assert np.allclose(s.uvs[2], [[0, 1], [1, 1], [0, 0]])


def test_errors_in_streamed_includes_name_the_right_file_and_line(tmp_path):
    write(tmp_path, 'Shape "trianglemesh"\n\n  "point3 P" [0 0 0  1 0 0  0 1 x]\n', name="bad.pbrt")
    path = write(tmp_path, 'WorldBegin\nInclude "bad.pbrt"\n')
    with pytest.raises(SceneError, match=rf"^{re.escape(str(tmp_path / 'bad.pbrt'))}:3: \"point3 P\": expected "
                                         r"numbers, got 'x'$"):
        load_scene(path)
    path = write(tmp_path, 'WorldBegin\nInclude\n' + TRIANGLE)
    with pytest.raises(SceneError, match=r"s\.pbrt:2: Include needs a quoted string, got 'Shape'$"):
        load_scene(path)
    write(tmp_path, 'Include "b.pbrt"\n', name="a.pbrt")
    write(tmp_path, 'Include "a.pbrt"\n', name="b.pbrt")
    with pytest.raises(SceneError, match=r"b\.pbrt:1: Include 'a\.pbrt': the file includes itself$"):
        load_scene(write(tmp_path, 'WorldBegin\nInclude "a.pbrt"\n' + TRIANGLE))


# -- (b) singular transforms ------------------------------------------------------------------------------

# a unit cube as 12 triangles, with outward shading normals per vertex (not the faces')
_CUBE_P = "0 0 0  1 0 0  1 1 0  0 1 0  0 0 1  1 0 1  1 1 1  0 1 1"
_CUBE_I = "0 2 1  0 3 2  4 5 6  4 6 7  0 1 5  0 5 4  3 7 6  3 6 2  0 4 7  0 7 3  1 2 6  1 6 5"
CUBE = (f'Shape "trianglemesh" "point3 P" [{_CUBE_P}] "integer indices" [{_CUBE_I}] '
        '"normal N" [-1 -1 -1  1 -1 -1  1 1 -1  -1 1 -1  -1 -1 1  1 -1 1  1 1 1  -1 1 1]')
FLAT_Z = "ConcatTransform [2 0 0 0  0 3 0 0  0 0 0 0  0 0 5 1]"  # x 2, y 3, z to 0, then z = 5: rank 2
ZERO = "ConcatTransform [0 0 0 0  0 0 0 0  0 0 0 0  1 2 3 1]"  # everything to (1, 2, 3)


def test_singular_transforms_are_kept_as_pbrt_keeps_them(tmp_path):
    """pbrt-v4 keeps a singular Transform / ConcatTransform (its inverse NaN): triangles land where
    the matrix puts them (those left without area are never hit), while the quadrics (sphere, disk,
    cylinder), which it intersects through the inverse, and the instances, whose rays it moves by the
    inverse, are never hit."""
    s, warned = load(write(tmp_path, f"""WorldBegin
AttributeBegin
  {FLAT_Z}
  {CUBE}
  Shape "sphere" "float radius" 2
  Shape "disk"
  Shape "cylinder"
AttributeEnd
AttributeBegin
  Transform [0 0 0 0  0 0 0 0  0 0 0 0  0 0 0 1]
  Shape "sphere"
  {TRIANGLE}
AttributeEnd
ObjectBegin "tri"
  {TRIANGLE}
ObjectEnd
AttributeBegin
  {ZERO}
  ObjectInstance "tri"
AttributeEnd
AttributeBegin
  Translate 0 0 9
  ObjectInstance "tri"
AttributeEnd
"""))
    assert warned == []
    assert len(sphere_of(s.shapes)) == 0
    v = s.vertices.astype(np.float64)[s.faces]
    # the cube's bottom and top (4 triangles) flattened onto z = 5, x in [0, 2], y in [0, 3]; its
    # 8 side triangles have no area left; then the regular instance's triangle at z = 9
    assert v.shape == (5, 3, 3)
    flat, inst = v[:4], v[4]
    assert np.allclose(flat[..., 2], 5) and np.allclose(np.sort(np.unique(flat[..., 0])), [0, 2])
    assert np.allclose(np.sort(np.unique(flat[..., 1])), [0, 3])
    assert np.isclose(0.5 * np.linalg.norm(np.cross(flat[:, 1] - flat[:, 0], flat[:, 2] - flat[:, 0]), axis=1).sum(), 12)
    assert np.allclose(inst, [[0, 0, 9], [1, 0, 9], [0, 1, 9]])
    # no shading normals came through pbrt's NaN inverse: flat, finite
    assert s.normals is None or (np.isfinite(s.normals).all() and not np.abs(s.normals[:4]).any())


def test_a_scene_with_singular_transforms_renders_without_nan(tmp_path):
    """A flattened emissive cube (its top and bottom: a 2 x 3 quad facing both ways at z = 5, the
    cube's outward normals lost), a zero-scaled sphere and a zero-scaled instance in front of the
    camera: every pixel is finite, and the quad lights a diffuse floor."""
    import pyopencl_rt as rt

    path = write(tmp_path, f"""LookAt 1 1.5 -4  1 1.5 5  0 1 0
Camera "perspective" "float fov" 60
Film "rgb" "integer xresolution" 16 "integer yresolution" 16
Sampler "independent" "integer pixelsamples" 16
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [4 4 4] "bool twosided" true
  {FLAT_Z}
  {CUBE}
AttributeEnd
AttributeBegin
  {ZERO}
  Shape "sphere"
  {CUBE}
AttributeEnd
ObjectBegin "cube"
  {CUBE}
ObjectEnd
AttributeBegin
  {ZERO}
  ObjectInstance "cube"
AttributeEnd
Shape "trianglemesh" "point3 P" [-10 -10 7  10 -10 7  10 10 7  -10 10 7] "integer indices" [0 1 2  0 2 3]
""")
    scene, warned = load(path)
    assert warned == []
    r = rt.render_full(scene, spp=16, width=16, height=16, device="cpu", seed=1)
    assert np.isfinite(r.image).all() and np.isfinite(r.film.variance_of_mean()).all()
    # the camera looks at the quad's centre (1, 1.5, 5): the light, 4 where it is seen
    assert np.allclose(r.image[7:9, 7:9], 4, rtol=1e-3)


@pytest.mark.parametrize("text,message", [
    (f"{ZERO}\nCamera \"perspective\"\nWorldBegin\n{TRIANGLE}", r":2: Camera: the transform is singular"),
    (f"WorldBegin\n{ZERO}\nLightSource \"distant\"\n{TRIANGLE}",
     r":3: LightSource \"distant\": the transform is singular"),
    (f"WorldBegin\n{ZERO}\nMakeNamedMedium \"m\" \"string type\" \"uniformgrid\" \"float density\" [1]\n{TRIANGLE}",
     r":3: MakeNamedMedium \"m\": the transform is singular"),
])
def test_what_needs_the_inverse_of_a_singular_transform_is_one_error_line(tmp_path, text, message):
    path = write(tmp_path, text)
    msg = load_error(path)
    assert msg.startswith(f"{path}:") and re.search(message, msg), msg


# -- (d) .spd spectrum files --------------------------------------------------------------------------------

def test_spd_conductor_spectra_are_gold(tmp_path):
    """pbrt-v4's "spectrum eta" "spds/Au.eta.spd": Mitsuba's own gold tables (its data/ior/Au.*.spd),
    read as wavelength-value pairs and made RGB as the loaders make named conductors (no illuminant,
    clamped at 0): exactly Mitsuba's "Au" (its scalar_rgb's eta and k, float32), red-yellow (eta
    rising from red to blue, k falling)."""
    import shutil

    from harness import mitsuba

    mi = mitsuba()
    data = Path(mi.__file__).parent / "data" / "ior"
    (tmp_path / "spds").mkdir()
    for part in ("eta", "k"):
        shutil.copy(data / f"Au.{part}.spd", tmp_path / "spds" / f"Au.{part}.spd")
    s, warned = load(write(tmp_path, 'WorldBegin\nMaterial "conductor" "spectrum eta" "spds/Au.eta.spd" '
                                     '"spectrum k" "spds/Au.k.spd"\n' + TRIANGLE))
    assert warned == []
    mat = s.materials[s.face_materials[0]]
    params = mi.traverse(mi.load_dict({"type": "conductor", "material": "Au"}))
    assert np.allclose(mat.eta, [float(x) for x in params["eta.value"]], rtol=1e-5)
    assert np.allclose(mat.k, [float(x) for x in params["k.value"]], rtol=1e-5)
    assert mat.eta[0] < mat.eta[1] < mat.eta[2] and mat.k[0] > mat.k[1] > mat.k[2]
    # coatedconductor's conductor.eta / conductor.k read the same files the same way
    s2, _ = load(write(tmp_path, 'WorldBegin\nMaterial "coatedconductor" "spectrum conductor.eta" "spds/Au.eta.spd" '
                                 '"spectrum conductor.k" "spds/Au.k.spd"\n' + TRIANGLE, name="c.pbrt"))
    inner = s2.materials[s2.face_materials[0]].record()  # under the coating: divided by interface.eta, 1.5
    assert np.allclose(inner["eta"] * 1.5, mat.eta, rtol=1e-6) and np.allclose(inner["k"] * 1.5, mat.k, rtol=1e-6)


def test_spd_reflectance_and_emission(tmp_path):
    """A reflectance .spd under D65, clamped to [0, 1] (a flat 0.5 is 0.5 grey; a spectrum that is 0.8
    above 600 nm and 0 below is red: Mitsuba's reflectance of the same file), the same numbers inline
    give the same colour, and an emission .spd is its colour at luminance 1 times scale (pbrt-v4
    divides a light's scale by the spectrum's photometric value): CIE D65 itself is sRGB's white."""
    from harness import mitsuba
    from pyopencl_rt.scene.loaders.mitsuba_spectrum import CIE_D65, CIE_WAVELENGTHS

    mi = mitsuba()
    (tmp_path / "flat.spd").write_text("# a flat spectrum\n360 0.5\n830 0.5\n")
    (tmp_path / "red.spd").write_text("380 0  599 0\n600 0.8  830 0.8\n")  # pbrt: pairs on any line
    (tmp_path / "red-mitsuba.spd").write_text("380 0\n599 0\n600 0.8\n830 0.8\n")  # Mitsuba: one a line
    (tmp_path / "d65.spd").write_text("\n".join(f"{w} {v}" for w, v in zip(CIE_WAVELENGTHS, CIE_D65 * 3.7)))
    s, warned = load(write(tmp_path, f"""WorldBegin
Material "diffuse" "spectrum reflectance" "flat.spd"
{TRIANGLE}
Material "diffuse" "spectrum reflectance" "red.spd"
Translate 0 0 1
{TRIANGLE}
Material "diffuse" "spectrum reflectance" [380 0  599 0  600 0.8  830 0.8]
Translate 0 0 1
{TRIANGLE}
AttributeBegin
AreaLightSource "diffuse" "spectrum L" "d65.spd" "float scale" 2
Translate 0 0 1
{TRIANGLE}
AttributeEnd
"""))
    assert warned == []
    albedo = [s.materials[i].albedo for i in s.face_materials]
    def theirs(fname):
        value = mi.traverse(mi.load_dict({"type": "diffuse", "reflectance": {
            "type": "spectrum", "filename": str(tmp_path / fname)}}))["reflectance.value"]
        return [float(x) for x in value]

    # (Mitsuba's sum over 1000 wavelengths gives a flat 0.5 as 0.4994)
    assert np.allclose(albedo[0], 0.5, atol=1e-3) and np.allclose(albedo[0], theirs("flat.spd"), atol=1e-5)
    assert np.allclose(albedo[1], theirs("red-mitsuba.spd"), atol=1e-5) and albedo[1][0] > 0.5 > albedo[1][2]
    assert albedo[2] == albedo[1]
    assert np.allclose(s.materials[s.face_materials[3]].emission, 2.0, atol=2e-3)


@pytest.mark.parametrize("text,message", [
    ('Material "conductor" "spectrum eta" "spds/none.spd"', r"\"spectrum eta\": spectrum file 'spds/none\.spd' not found"),
    ('Material "diffuse" "spectrum reflectance" "odd.spd"', r"\"spectrum reflectance\": 'odd\.spd': needs wavelength-value "
                                                             r"pairs, at least two \(got 3 numbers\)"),
    ('Material "diffuse" "spectrum reflectance" "word.spd"', r"'word\.spd' line 2: 'x' is not a number"),
    ('Material "diffuse" "spectrum reflectance" [500 1 400 1]', r"the wavelengths must increase"),
])
def test_bad_spectrum_files_are_one_error_line(tmp_path, text, message):
    (tmp_path / "odd.spd").write_text("400 1\n500\n")
    (tmp_path / "word.spd").write_text("400 1\n500 x\n")
    path = write(tmp_path, f"WorldBegin\n{text}\n{TRIANGLE}")
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"{path}:2: ") and re.search(message, msg), msg


# -- (e) coatedconductor ------------------------------------------------------------------------------------

def _material(tmp_path, text, name="m.pbrt"):
    s, warned = load(write(tmp_path, f"WorldBegin\n{text}\n{TRIANGLE}", name=name))
    return s.materials[s.face_materials[0]], warned


def test_coatedconductor_reads_pbrt_v4s_prefixed_parameters(tmp_path):
    """pbrt-v4's coatedconductor parameters (materials.cpp: conductor.eta, conductor.k or reflectance,
    conductor.roughness / uroughness / vroughness, interface.eta, interface.roughness, thickness,
    maxdepth, nsamples) as our coatedconductor's record: the metal as pbrt puts it under the coating
    (eta and k divided by interface.eta; reflectance r as eta 1, k = 2 sqrt(r) / sqrt(1 - r)), each
    layer's GGX alpha = sqrt(roughness) (pbrt's RoughnessToAlpha), no warning."""
    m, warned = _material(tmp_path, 'Material "coatedconductor" "rgb conductor.eta" [0.2 0.4 1.0] '
                                    '"rgb conductor.k" [3 2.5 2] "float conductor.roughness" 0.04 '
                                    '"float interface.roughness" 0.09 "float thickness" 0.02')
    rec = m.record()
    assert m.type == "coatedconductor" and warned == []
    assert np.allclose(rec["eta"], np.array([0.2, 0.4, 1.0]) / 1.5) and np.allclose(rec["k"], np.array([3, 2.5, 2]) / 1.5)
    assert np.isclose(rec["alpha"], 0.3) and m.alpha_v is None and np.isclose(rec["ior"], 1.5)
    assert np.allclose(rec["table"][:5], [0.2, 0.2, 0.02, 10, 1])
    # anisotropic conductor, smooth coating of 1.33, no remapping
    m, _ = _material(tmp_path, 'Material "coatedconductor" "rgb conductor.eta" [1 1 1] "rgb conductor.k" [2 2 2] '
                               '"float conductor.uroughness" 0.1 "float conductor.vroughness" 0.5 '
                               '"float interface.eta" 1.33 "bool remaproughness" false')
    rec = m.record()
    assert np.allclose(rec["eta"], 1 / 1.33) and np.allclose(rec["k"], 2 / 1.33) and rec["alpha"] == 0.0
    assert np.allclose(rec["table"][:2], [0.1, 0.5]) and m.is_anisotropic
    # reflectance, as pbrt-v4 turns it into eta and k
    m, _ = _material(tmp_path, 'Material "coatedconductor" "rgb reflectance" [0.9 0.5 0.2]')
    r = np.array([0.9, 0.5, 0.2])
    rec = m.record()
    assert np.allclose(rec["eta"], 1 / 1.5) and np.allclose(rec["k"], 2 * np.sqrt(r) / np.sqrt(1 - r) / 1.5)
    # neither: pbrt's copper
    from pyopencl_rt.scene.loaders.mitsuba_metals import CONDUCTORS

    rec = _material(tmp_path, 'Material "coatedconductor"')[0].record()
    assert np.allclose(rec["eta"], np.array(CONDUCTORS["Cu"][0]) / 1.5)
    assert np.allclose(rec["k"], np.array(CONDUCTORS["Cu"][1]) / 1.5)


def test_coatedconductor_with_reflectance_and_eta_is_one_error_line(tmp_path):
    path = write(tmp_path, 'WorldBegin\nMaterial "coatedconductor" "rgb reflectance" [0.5 0.5 0.5] '
                           '"rgb conductor.eta" [1 1 1]\n' + TRIANGLE)
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and re.search(r's\.pbrt:2: Material "coatedconductor": give "reflectance" or '
                                         r'"conductor\.eta" / "conductor\.k", not both', msg), msg


# -- (f) the scale and mix textures ---------------------------------------------------------------------------

def _png(path, rgb8):
    from PIL import Image

    Image.fromarray(np.asarray(rgb8, np.uint8), "RGB").save(path)


def test_scale_and_mix_textures(tmp_path):
    """pbrt-v4's "scale" (tex x scale, defaults 1) and "mix" ((1 - amount) tex1 + amount tex2, defaults
    0, 1, 0.5; amount a float texture: an image's first channel): of constants, the constant; with
    images, the image baked texel by texel (linear in each image input, so the bilinear lookup of the
    bake is the combination of the lookups), keeping the image's uv mapping."""
    from pyopencl_rt.scene.textures import lookup

    rng = np.random.default_rng(5)
    a8, b8, w8 = (rng.integers(0, 256, (4, 6, 3)) for _ in range(3))
    for name, img in (("a.png", a8), ("b.png", b8), ("w.png", w8)):
        _png(tmp_path / name, img)
    a, b, w = (x / 255.0 for x in (a8, b8, w8))  # "encoding" "linear": the texels as stored
    lin = '"string encoding" "linear"'
    s, warned = load(write(tmp_path, f"""WorldBegin
Texture "A" "spectrum" "imagemap" "string filename" "a.png" {lin} "float uscale" 2
Texture "B" "spectrum" "imagemap" "string filename" "b.png" {lin} "float uscale" 2
Texture "W" "float" "imagemap" "string filename" "w.png" {lin} "float uscale" 2
Texture "half" "spectrum" "scale" "texture tex" "A" "float scale" 0.5
Texture "sA" "spectrum" "scale" "rgb tex" [0.2 0.4 0.6] "texture scale" "W"
Texture "consts" "spectrum" "mix" "rgb tex1" [0.2 0.4 0.6] "rgb tex2" [1 0 0.5] "float amount" 0.25
Texture "AB" "spectrum" "mix" "texture tex1" "A" "texture tex2" "B" "float amount" 0.3
Texture "byW" "spectrum" "mix" "rgb tex1" [0.1 0.2 0.3] "rgb tex2" [0.9 0.8 0.7] "texture amount" "W"
Texture "dflt" "spectrum" "mix"
Texture "one" "float" "scale"
""" + "\n".join(f'Material "diffuse" "texture reflectance" "{t}"\nTranslate 0 0 1\n{TRIANGLE}'
                for t in ("half", "sA", "consts", "AB", "byW", "dflt", "one"))))
    assert warned == []
    mats = [s.materials[i] for i in s.face_materials]
    uv = rng.random((40, 2)) * 1.4 - 0.2

    def look(texture):
        return lookup(texture.texels, uv, texture.wrap, texture.filter, texture.to_uv)[:, :3]

    def ref(img):  # the image as pbrt's imagemap "A" looks it up (uscale 2)
        t = np.ones(img.shape[:2] + (4,))
        t[..., :3] = img
        return lookup(t, uv, "repeat", "bilinear", mats[0].base_texture.to_uv)[:, :3]

    assert mats[0].base_texture.to_uv[0] == 2.0  # the image's mapping kept
    assert np.allclose(look(mats[0].base_texture), 0.5 * ref(a), atol=1e-6)
    grey_w = np.repeat(w[..., :1], 3, axis=-1)  # a float texture: the image's first channel
    assert np.allclose(look(mats[1].base_texture), ref(grey_w) * [0.2, 0.4, 0.6], atol=1e-6)
    assert mats[2].base_texture is None and np.allclose(mats[2].albedo, [0.4, 0.3, 0.575])
    assert np.allclose(look(mats[3].base_texture), 0.7 * ref(a) + 0.3 * ref(b), atol=1e-6)
    wl = ref(grey_w)
    assert np.allclose(look(mats[4].base_texture), (1 - wl) * [0.1, 0.2, 0.3] + wl * [0.9, 0.8, 0.7], atol=1e-6)
    assert mats[5].base_texture is None and mats[5].albedo == (0.5, 0.5, 0.5)
    assert mats[6].base_texture is None and mats[6].albedo == (1.0, 1.0, 1.0)


def test_a_mix_of_images_that_do_not_line_up_warns(tmp_path):
    _png(tmp_path / "a.png", np.full((4, 4, 3), 200))
    _png(tmp_path / "b.png", np.full((2, 2, 3), 100))
    path = write(tmp_path, """WorldBegin
Texture "A" "spectrum" "imagemap" "string filename" "a.png" "string encoding" "linear"
Texture "B" "spectrum" "imagemap" "string filename" "b.png" "string encoding" "linear"
Texture "AB" "spectrum" "mix" "texture tex1" "A" "texture tex2" "B"
Material "diffuse" "texture reflectance" "AB"
""" + TRIANGLE)
    s, warned = load(path)
    assert warned == [f"{path}:4: Texture \"AB\": its image inputs differ in size or mapping; '{tmp_path / 'b.png'}' "
                      "is read at its mean"]
    tex = s.materials[s.face_materials[0]].base_texture
    assert tex.texels.shape[:2] == (4, 4) and np.allclose(tex.texels[..., :3], 0.5 * 200 / 255 + 0.5 * 100 / 255)


# -- (g) the film's iso and exposure time --------------------------------------------------------------------

LIT = """LookAt 0 0 -3  0 0 0  0 1 0
Camera "perspective" "float fov" 50 {camera}
Film "rgb" "integer xresolution" 16 "integer yresolution" 16 {film}
Sampler "independent" "integer pixelsamples" 8
WorldBegin
LightSource "point" "point3 from" [0 2 -2] "rgb I" [3 3 3]
LightSource "distant" "point3 from" [0 0 -1] "point3 to" [0 0 0] "rgb L" [0.5 0.5 0.5]
LightSource "infinite" "rgb L" [0.2 0.3 0.4]
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [2 1 0.5]
  Translate -1 0 1
  Shape "sphere" "float radius" 0.3
AttributeEnd
Shape "trianglemesh" "point3 P" [-2 -1 0  2 -1 0  2 1 0  -2 1 0] "integer indices" [0 1 2  0 2 3]
"""


def _lights(scene):
    from pyopencl_rt.scene.lights import DirectionalLight, PointLight

    emissive = [m.emission for m in scene.materials if m.is_emissive]
    point = next(lt.intensity for lt in scene.lights if isinstance(lt, PointLight))
    distant = next(lt.irradiance for lt in scene.lights if isinstance(lt, DirectionalLight))
    return np.array([*emissive, point, distant, scene.environment.radiance], np.float64)


@pytest.mark.parametrize("camera,film,ratio", [
    ("", "", 1.0),
    ("", '"float iso" 400', 4.0),  # pbrt-v4: exposure time x ISO / 100
    ('"float shutteropen" 0.25 "float shutterclose" 0.75', '"float iso" 50', 0.25),  # the shutter's 0.5
    ('"float shutterclose" 3', '"float iso" 200', 6.0),
])
def test_iso_and_exposure_time_scale_what_the_film_records(tmp_path, camera, film, ratio):
    base, warned0 = load(write(tmp_path, LIT.format(camera="", film=""), name="base.pbrt"))
    s, warned = load(write(tmp_path, LIT.format(camera=camera, film=film)))
    assert warned == [] and warned0 == []
    assert np.allclose(_lights(s), ratio * _lights(base), rtol=1e-12)


def test_iso_scales_the_rendered_image_exactly(tmp_path):
    """The same seed at ISO 100 and 250: every pixel 2.5 times (the renderer is linear in emission)."""
    import pyopencl_rt as rt

    a, _ = load(write(tmp_path, LIT.format(camera="", film=""), name="a.pbrt"))
    b, _ = load(write(tmp_path, LIT.format(camera="", film='"float iso" 250'), name="b.pbrt"))
    ra = rt.render_full(a, spp=8, width=16, height=16, device="cpu", seed=4)
    rb = rt.render_full(b, spp=8, width=16, height=16, device="cpu", seed=4)
    assert ra.image.mean() > 0.05
    assert np.allclose(rb.image, 2.5 * ra.image, rtol=1e-4, atol=1e-6)


@pytest.mark.parametrize("camera,film,message", [
    ('"float shutteropen" 1 "float shutterclose" 1', "", r":2: Camera: shutteropen 1 and shutterclose 1: the shutter "
                                                        r"does not open"),
    ("", '"float iso" 0', r':3: Film "float iso" must be > 0, got 0'),
    ("", '"float exposuretime" 0.5', r':3: Film "float exposuretime": not a parameter of pbrt-v4\'s film, which '
                                     r"refuses it \(the exposure time is the Camera's shutterclose - shutteropen\)$"),
])
def test_impossible_exposures_are_one_error_line(tmp_path, camera, film, message):
    path = write(tmp_path, LIT.format(camera=camera, film=film))
    with pytest.raises(SceneError) as info:
        load_scene(path)
    msg = str(info.value)
    assert "\n" not in msg and msg.startswith(f"{path}:") and re.search(message, msg), msg


def test_named_metal_spectra_are_mitsubas_conductors_and_brass_is_refused(tmp_path):
    """pbrt-v4's metal-X-eta / metal-X-k are Mitsuba's conductors of the same name (their spectra
    made RGB as Mitsuba's RGB variants make them); a named spectrum we have no data for is one error
    line, never another metal."""
    from pyopencl_rt.scene.loaders.mitsuba_metals import CONDUCTORS

    for metal in ("Au", "Ag", "Cu", "Al", "MgO", "TiO2"):
        m, warned = _material(tmp_path, f'Material "conductor" "spectrum eta" "metal-{metal}-eta" '
                                        f'"spectrum k" "metal-{metal}-k"')
        assert warned == [] and (m.eta, m.k) == (CONDUCTORS[metal][0], CONDUCTORS[metal][1]), metal
    path = write(tmp_path, 'WorldBegin\nMaterial "conductor" "spectrum eta" "metal-CuZn-eta"\n' + TRIANGLE)
    with pytest.raises(SceneError, match=r':2: Material "conductor": spectrum "metal-CuZn-eta" is not supported'):
        load_scene(path)


# -- (g) displacement: bump mapping by a float texture ------------------------------------------------------

def test_displacement_texture_is_a_bump_map_of_the_channel_average(tmp_path):
    """pbrt-v4's "texture displacement" (BumpMap) becomes our bump map of the texture (no warning): its
    texels the average of the image's channels (pbrt's float image textures), times the texture's
    scale, looked up with its uv mapping; a constant displacement tilts nothing; a normal map wins."""
    from PIL import Image

    Image.fromarray(np.array([[[255, 0, 0], [0, 255, 0]], [[0, 0, 255], [255, 255, 255]]], np.uint8)).save(
        tmp_path / "h.png")
    tex = 'Texture "h" "float" "imagemap" "string filename" "h.png" "string encoding" "linear" "float scale" 0.5 ' \
          '"float uscale" 2\n'
    s, warned = load(write(tmp_path, f'WorldBegin\n{tex}Material "diffuse" "texture displacement" "h"\n{TRIANGLE}'))
    mat = s.materials[s.face_materials[0]]
    assert warned == [] and mat.bump_map and mat.normal_scale == 1.0
    texels = mat.normal_texture.texels[..., :3]
    assert np.allclose(texels, np.array([[1, 1], [1, 3]])[..., None] / 3 * 0.5, atol=1e-6)
    assert mat.normal_texture.to_uv[0] == 2.0  # pbrt's uscale
    s, warned = load(write(tmp_path, 'WorldBegin\nTexture "c" "float" "constant" "float value" 0.3\n'
                                     f'Material "diffuse" "texture displacement" "c"\n{TRIANGLE}'))
    assert warned == [] and s.materials[s.face_materials[0]].normal_texture is None
    Image.new("RGB", (2, 2), (128, 128, 255)).save(tmp_path / "n.png")
    s, _ = load(write(tmp_path, f'WorldBegin\n{tex}Material "diffuse" "texture displacement" "h" '
                                f'"string normalmap" "n.png"\n{TRIANGLE}'))
    assert not s.materials[s.face_materials[0]].bump_map


@pytest.mark.parametrize("whole", [True, False])
def test_a_bump_map_seen_from_behind_is_pbrts(tmp_path, whole):
    """pbrt-v4 displaces along the surface's own normal (the triangles' winding) and its two-sided BSDF
    sees the tilted frame from behind, so a bumped panel seen from behind shows the height field
    inverted: the panel wound the other way under the height h renders as the first under -h.  Mitsuba's
    rule (the map mirrored through the tangent plane for a viewer behind it, our other convention)
    shows the same bumps from both sides: the mutation (map_conventions emptied) fails it."""
    from PIL import Image

    from pyopencl_rt.render.api import render_full

    y, x = np.mgrid[0:32, 0:32] / 32
    Image.fromarray(np.round((0.5 + 0.25 * np.sin(2 * np.pi * x) + 0.25 * np.cos(2 * np.pi * y)) * 255)
                    .astype(np.uint8), "L").save(tmp_path / "h.png")
    images = []
    for indices, scale in (("0 1 2 0 2 3", 0.4), ("0 2 1 0 3 2", -0.4)):
        s, _ = load(write(tmp_path, 'LookAt 0 0 -3  0 0 0  0 1 0\nCamera "perspective" "float fov" 40\n'
                                    'Film "rgb" "integer xresolution" 32 "integer yresolution" 24\nWorldBegin\n'
                                    'LightSource "distant" "point3 from" [0 1 -1] "point3 to" [0 0 0] "rgb L" [3 3 3]\n'
                                    f'Texture "h" "float" "imagemap" "string filename" "h.png" "float scale" {scale}\n'
                                    'Material "conductor" "float roughness" 0.1 "texture displacement" "h"\n'
                                    f'Shape "trianglemesh" "integer indices" [{indices}] '
                                    '"point3 P" [-1 -1 0  1 -1 0  1 1 0  -1 1 0] "point2 uv" [0 0  1 0  1 1  0 1]\n'))
        if not whole:
            s.materials[0].map_conventions = ()
        images.append(render_full(s, seed=3).image.astype(np.float64))
    diff = np.abs(images[0] - images[1]).mean() / images[0].mean()
    assert (diff < 1e-3) if whole else (diff > 0.05), diff


def test_pbrt_normal_map_reads_green_inverted_and_turns_whole(tmp_path):
    """pbrt-v4's "string normalmap": linear RGB whose y runs opposite to our frame's T (green read as
    1 - G), turned whole from behind, as its renders show (BENCHMARKS, feature scene normalmap: 99.98%;
    78.75% with green as read)."""
    from PIL import Image

    Image.fromarray(np.array([[[255, 64, 200]]], np.uint8)).save(tmp_path / "n.png")
    s, warned = load(write(tmp_path, f'WorldBegin\nMaterial "diffuse" "string normalmap" "n.png"\n{TRIANGLE}'))
    mat = s.materials[s.face_materials[0]]
    assert warned == [] and not mat.bump_map and mat.map_conventions == ("whole",)
    assert np.allclose(mat.normal_texture.texels[0, 0, :3], [1.0, 1 - 64 / 255, 200 / 255], atol=1e-6)
