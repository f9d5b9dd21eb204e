"""pbrt-v4's roughness as a float texture (conductor, dielectric, coateddiffuse): each texel's alpha as
pbrt-v4's RoughnessToAlpha makes it (sqrt where remaproughness, the default), multiplied into the
material's alpha by the kernels' textured parameters (Material.scalar_textures); and the texture
mappings pbrt-v4 does not have refused."""
from __future__ import annotations

import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError

from harness import load_warned as load

QUAD = 'Shape "trianglemesh" "point3 P" [-2 -1 0  2 -1 0  2 1 0  -2 1 0] "integer indices" [0 1 2  0 2 3] ' \
       '"point2 uv" [0 0  1 0  1 1  0 1]'
SCENE = """LookAt 0 0 -3  0 0 0  0 1 0
Camera "perspective" "float fov" 50
Film "rgb" "integer xresolution" 16 "integer yresolution" 16
Sampler "independent" "integer pixelsamples" 8
WorldBegin
LightSource "point" "point3 from" [0.3 0.5 -2] "rgb I" [3 3 3]
LightSource "infinite" "rgb L" [0.2 0.3 0.4]
Texture "rough" "float" "checkerboard" "float tex1" {r1} "float tex2" {r2} "float uscale" 4 "float vscale" 4
{material}
""" + QUAD


def scene_file(tmp_path, material, r1=0.0, r2=0.25, name="s.pbrt"):
    path = tmp_path / name
    path.write_text(SCENE.format(material=material, r1=r1, r2=r2))
    return path


def material(scene):
    return scene.materials[scene.face_materials[0]]


def values(texture):
    return sorted(set(np.round(texture.texels[..., 0].ravel().astype(float), 6)))


@pytest.mark.parametrize("remap,expect", [("", [0.0, 0.5]), ('"bool remaproughness" false', [0.0, 0.25])])
@pytest.mark.parametrize("mtype", ["conductor", "dielectric"])
def test_a_roughness_texture_becomes_the_alpha_texture(tmp_path, mtype, remap, expect):
    s, warned = load(scene_file(tmp_path, f'Material "{mtype}" "texture roughness" "rough" {remap}'))
    m = material(s)
    assert warned == []
    assert m.alpha == 1.0 and set(m.scalar_textures) == {"alpha"}
    assert values(m.scalar_textures["alpha"]) == expect
    assert not m.is_anisotropic


def test_u_and_v_textures_and_numbers(tmp_path):
    """uroughness a texture, vroughness a number: alpha 1 times the texture along u, sqrt(0.09) along v."""
    s, warned = load(scene_file(tmp_path, 'Material "conductor" "texture uroughness" "rough" "float vroughness" 0.09'))
    m = material(s)
    assert warned == [] and m.alpha == 1.0 and m.alpha_v == pytest.approx(0.3) and m.is_anisotropic
    assert values(m.scalar_textures["alpha"]) == [0.0, 0.5]


def test_coateddiffuse_takes_an_isotropic_texture_and_refuses_two(tmp_path):
    s, warned = load(scene_file(tmp_path, 'Material "coateddiffuse" "texture roughness" "rough"'))
    m = material(s)
    assert warned == [] and m.type == "roughplastic" and m.alpha == 1.0
    assert values(m.scalar_textures["alpha"]) == [0.0, 0.5]
    with pytest.raises(SceneError, match="a textured roughness that differs along u and v is not supported") as e:
        load(scene_file(tmp_path, 'Material "coateddiffuse" "texture uroughness" "rough" "float vroughness" 0.1',
                        name="b.pbrt"))
    assert "\n" not in str(e.value)


def test_a_coated_conductors_interface_roughness_texture_is_read(tmp_path):
    """coatedconductor's "texture interface.roughness": the coat's alpha texture (the kernels' coat
    reads the material's alpha); its conductor's roughness, a texture there, still warns (a number of
    the layer's table)."""
    s, warned = load(scene_file(tmp_path, 'Material "coatedconductor" "texture interface.roughness" "rough"'))
    m = material(s)
    assert warned == [] and m.type == "coatedconductor" and m.alpha == 1.0
    assert values(m.scalar_textures["alpha"]) == [0.0, 0.5]
    _, warned = load(scene_file(tmp_path, 'Material "coatedconductor" "texture conductor.roughness" "rough"',
                                name="c.pbrt"))
    assert any("conductor.roughness" in w for w in warned)


def test_a_uniform_coat_roughness_texture_renders_the_numbers_image_bit_for_bit(tmp_path):
    """A coatedconductor whose interface roughness is a checkerboard of 0.25 and 0.25 against the number
    0.25: the same image at the same seed (the coat's alpha 0.5 both ways); of 0 and 0.25 another."""
    import pyopencl_rt as rt

    def render(text, **kw):
        s, _ = load(scene_file(tmp_path, text, name=f"{abs(hash((text, tuple(kw.items()))))}.pbrt", **kw))
        return rt.render_full(s, spp=8, width=16, height=16, device="cpu", seed=3).image

    coat = 'Material "coatedconductor" "float conductor.roughness" 0.1 '
    number = render(coat + '"float interface.roughness" 0.25')
    assert number.mean() > 0.01
    assert np.array_equal(render(coat + '"texture interface.roughness" "rough"', r1=0.25), number)
    assert not np.array_equal(render(coat + '"texture interface.roughness" "rough"'), number)


def test_a_uniform_texture_renders_the_numbers_image_bit_for_bit(tmp_path):
    """A checkerboard of 0.25 and 0.25 against "float roughness" 0.25 (alpha 0.5 both ways: 1 x 0.5
    and sqrt(0.25), exact): the same image at the same seed; a checkerboard of 0 and 0.25 another."""
    import pyopencl_rt as rt

    def render(text, **kw):
        s, _ = load(scene_file(tmp_path, text, name=f"{abs(hash((text, tuple(kw.items()))))}.pbrt", **kw))
        return rt.render_full(s, spp=8, width=16, height=16, device="cpu", seed=3).image

    number = render('Material "conductor" "float roughness" 0.25')
    assert number.mean() > 0.01
    assert np.array_equal(render('Material "conductor" "texture roughness" "rough"', r1=0.25), number)
    checks = render('Material "conductor" "texture roughness" "rough"')
    assert not np.array_equal(checks, number)


def test_an_unknown_texture_mapping_is_refused_in_one_line(tmp_path):
    """pbrt-v4 has uv, spherical, cylindrical and planar mappings (tests/scene/test_texture_mappings.py);
    another name is one line naming it (never read as uv)."""
    path = tmp_path / "m.pbrt"
    path.write_text('WorldBegin\nTexture "t" "spectrum" "checkerboard" "string mapping" "conical"\n'
                    'Material "diffuse" "texture reflectance" "t"\n' + QUAD)
    with pytest.raises(SceneError, match='m.pbrt:2: Texture "t": unknown mapping "conical"') as e:
        load(path)
    assert "\n" not in str(e.value)


def test_a_coated_conductors_reflectance_texture_makes_the_metal_of_each_texel(tmp_path):
    """coatedconductor's "texture reflectance": each texel's r becomes the metal under the coat, pbrt-v4's
    eta 1 and k = 2 sqrt(r) / sqrt(1 - r) (in the kernels; it was the texture's mean, with a warning):
    a uniform checkerboard of r renders the image of the number r at the same seed (k's float32
    rounding moves a random walk's Russian roulette now and then: over 95% of the pixels equal to
    1e-4, the means within 1%), a checkerboard of 0.9 and 0.1 another."""
    import pyopencl_rt as rt

    def render(text, name):
        path = tmp_path / name
        path.write_text(SCENE.format(material=text, r1=0.0, r2=0.0))
        s, warned = load(path)
        assert warned == [], warned
        return rt.render_full(s, spp=8, width=16, height=16, device="cpu", seed=3).image.astype(np.float64)

    coat = 'Material "coatedconductor" "float interface.roughness" 0.1 "float conductor.roughness" 0.2 '
    checks = 'Texture "r" "spectrum" "checkerboard" "rgb tex1" [{a}] "rgb tex2" [{b}] "float uscale" 4 "float vscale" 4\n'
    number = render(coat + '"rgb reflectance" [0.6 0.5 0.3]', "n.pbrt")
    uniform = render(checks.format(a="0.6 0.5 0.3", b="0.6 0.5 0.3") + coat + '"texture reflectance" "r"', "u.pbrt")
    varied = render(checks.format(a="0.9 0.9 0.9", b="0.1 0.1 0.1") + coat + '"texture reflectance" "r"', "v.pbrt")
    assert number.mean() > 0.01
    same = (np.abs(uniform - number) <= 1e-4 * number.max()).all(axis=-1)
    assert same.mean() > 0.95 and abs(uniform.mean() / number.mean() - 1) < 0.01, (same.mean(), uniform.mean(),
                                                                                     number.mean())
    assert np.abs(varied - number).mean() > 0.01
