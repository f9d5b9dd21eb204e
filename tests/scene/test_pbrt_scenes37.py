"""pbrt-v4 loader behaviour that the public scenes (issue 37) need: named materials defined after
the shapes that use them."""
from __future__ import annotations

import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError

from harness import load_warned as load

TRIANGLE = 'Shape "trianglemesh" "point3 P" [0 0 0  1 0 0  0 1 0]'


def world(tmp_path, body):
    path = tmp_path / "s.pbrt"
    path.write_text(f"WorldBegin\n{body}\n")
    return load(path)


def test_a_named_material_defined_after_its_shapes(tmp_path):
    """pbrt-v4 creates named materials after the whole file is read (contemporary-bathroom names
    "light" before Include "materials.pbrt"): the shape gets the material, with the transform
    and area light in effect where it stood."""
    s, w = world(tmp_path, f"""
AttributeBegin
  NamedMaterial "later"
  Translate 5 0 0
  AreaLightSource "diffuse" "rgb L" [2 3 4]
  {TRIANGLE}
AttributeEnd
Material "diffuse" "rgb reflectance" [0.1 0.1 0.1]
Translate 0 7 0
{TRIANGLE}
MakeNamedMaterial "later" "string type" "conductor" "rgb reflectance" [0.9 0.8 0.7]""")
    assert w == [] and len(s.faces) == 2
    mats = [s.materials[i] for i in s.face_materials]
    xs = s.vertices.astype(np.float64).reshape(-1, 3, 3)[:, 0]
    named = int(np.argmin(np.abs(xs[:, 0] - 5)))  # the waiting shape, at x = 5
    other = 1 - named
    assert np.allclose(xs[named], [5, 0, 0]) and np.allclose(xs[other], [0, 7, 0])
    assert mats[named].type == "conductor" and mats[named].f0 == (0.9, 0.8, 0.7)
    assert mats[named].is_emissive and tuple(mats[named].emission) != (0, 0, 0)
    assert mats[other].type == "diffuse" and not mats[other].is_emissive


def test_a_named_material_never_defined_is_still_an_error(tmp_path):
    with pytest.raises(SceneError, match=r":2: NamedMaterial: no material named 'nothing'"):
        world(tmp_path, f'NamedMaterial "nothing"\n{TRIANGLE}\nMakeNamedMaterial "other" "string type" "diffuse"')


def test_a_missing_normal_map_is_a_missing_file(tmp_path):
    """One error line that says the file is not there (the bench's "missing" verdict and its
    probe rely on it), as for the other files a scene names."""
    from pyopencl_rt.scene.loaders.pbrt import MissingFile

    with pytest.raises(MissingFile, match=r":2: Material \"diffuse\": normal map: file 'bump.png' not found "
                                          r"\(looked for .*bump.png\)$"):
        world(tmp_path, f'Material "diffuse" "string normalmap" "bump.png"\n{TRIANGLE}')


@pytest.mark.parametrize("cls", ["ptex", "wrinkled", "marble"])
def test_an_unsupported_texture_class_is_one_error_line(tmp_path, cls):
    with pytest.raises(SceneError, match=rf':2: Texture "t" "{cls}": texture class "{cls}" is not supported$'):
        world(tmp_path, f'Texture "t" "spectrum" "{cls}"\nMaterial "diffuse" "texture reflectance" "t"\n{TRIANGLE}')


def test_the_bench_probe_skips_missing_files_and_keeps_going(tmp_path, monkeypatch):
    """The bench's probe (SKIP_MISSING_FILES, never a render's): an Include, an image texture and
    a plymesh that are not there are skipped with a warning each, a texture becomes a grey stand-in
    so the materials naming it resolve, and a named material never defined (it was in a missing
    file) leaves its shape out; what the rest of the file asks for is still read."""
    import warnings

    from pyopencl_rt.scene.loaders import load_scene, pbrt

    monkeypatch.setattr(pbrt, "SKIP_MISSING_FILES", True)
    path = tmp_path / "s.pbrt"
    path.write_text(f"""WorldBegin
Include "materials.pbrt"
Texture "t" "spectrum" "imagemap" "string filename" "gone.png"
Material "diffuse" "texture reflectance" "t"
Shape "plymesh" "string filename" "gone.ply"
{TRIANGLE}
NamedMaterial "from-the-missing-file"
{TRIANGLE}
""")
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(path)
    skipped = [str(w.message) for w in caught if str(w.message).startswith(pbrt.MISSING_SKIPPED)]
    assert len(skipped) == 4 and all(n in " ".join(skipped) for n in ("materials.pbrt", "gone.png", "gone.ply",
                                                                           "from-the-missing-file"))
    assert len(scene.faces) == 1 and scene.materials[scene.face_materials[0]].albedo == (0.5, 0.5, 0.5)
    monkeypatch.setattr(pbrt, "SKIP_MISSING_FILES", False)
    with pytest.raises(pbrt.MissingFile, match="materials.pbrt"):  # a render never skips
        load_scene(path)


@pytest.mark.parametrize("mtype", ["nanovdb", "cloud", "rgbgrid"])
def test_an_unsupported_medium_type_is_one_error_line(tmp_path, mtype):
    """Never vacuum in its place (disney-cloud rendered an empty sky so)."""
    with pytest.raises(SceneError, match=rf':2: MakeNamedMedium "m": medium type "{mtype}" is not supported$'):
        world(tmp_path, f'MakeNamedMedium "m" "string type" "{mtype}"\n{TRIANGLE}')


def test_imagemap_invert_after_scale(tmp_path):
    """pbrt-v4's ImageTexture: v = scale x lookup, then max(0, 1 - v) when inverted (kroken's
    roughness maps).  Linear 8-bit texels 0, 128, 255 at scale 0.5 become 1, 1 - 64/255, 0.5."""
    from PIL import Image

    Image.fromarray(np.array([[[0, 0, 0], [128, 128, 128], [255, 255, 255]]], np.uint8)).save(tmp_path / "t.png")
    s, w = world(tmp_path, f"""Texture "t" "spectrum" "imagemap" "string filename" "t.png" "string encoding" "linear"
    "float scale" 0.5 "bool invert" true
Material "diffuse" "texture reflectance" "t"
{TRIANGLE}""")
    assert w == []
    texels = s.materials[s.face_materials[0]].base_texture.texels[0, :, :3]
    assert np.allclose(texels, np.array([1.0, 1.0 - 0.5 * 128 / 255, 0.5])[:, None], atol=1e-6)


def test_the_probe_skips_the_parameters_after_a_missing_include(tmp_path, monkeypatch):
    """smoke-plume's Include "geometry/density_big_0084.pbrt" ends in a MakeNamedMedium whose
    parameter list goes on after the Include: skipping the file skips them too."""
    import warnings

    from pyopencl_rt.scene.loaders import load_scene, pbrt

    monkeypatch.setattr(pbrt, "SKIP_MISSING_FILES", True)
    path = tmp_path / "s.pbrt"
    path.write_text(f'WorldBegin\nInclude "gone.pbrt"\n  "spectrum sigma_a" [300 20 830 20] "bool x" true\n'
                    f'MediumInterface "smoke" ""\nMaterial "interface"\n{TRIANGLE}\n')
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        scene = load_scene(path)
    assert len(scene.faces) == 1  # its medium, defined in the missing file, is skipped too
    assert sum(str(w.message).startswith(pbrt.MISSING_SKIPPED) for w in caught) == 2
