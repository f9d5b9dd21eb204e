"""Mitsuba 3's plastic, roughplastic, principled and principledthin (cl/materials/plastic.h, ...), and
roughconductor / roughdielectric (Beckmann and GGX, isotropic and anisotropic: conductor.h,
dielectric.h) against Mitsuba 3 itself (scalar_rgb; skipped without the mitsuba package): the same XML BSDF
read by our loader and by Mitsuba, evaluated at random direction pairs of the local frame (f cos
and pdf, relative 1e-4), and a small scene rendered by both (image means within the noise)."""
import numpy as np
import pytest

from pyopencl_rt import render_full

import harness
from test_materials import bsdf_eval
from test_mitsuba_xml import _mitsuba_image, load, mitsuba, write

REL = 1e-4  # relative agreement of f cos and pdf (float32 against Mitsuba's float32: ~1e-5 seen)
FLOOR = 1e-3  # values below this compare absolutely (to REL * FLOOR = 1e-7: the float32 cancellation
# of the refraction's half vector leaves tiny values a few tenths of a percent apart)

BSDFS = {
    "plastic": '<bsdf type="plastic"/>',
    "plastic_bk7_nonlinear": '<bsdf type="plastic"><rgb name="diffuse_reflectance" value="0.1, 0.6, 0.3"/>'
                             '<string name="int_ior" value="bk7"/><boolean name="nonlinear" value="true"/>'
                             '<rgb name="specular_reflectance" value="0.6, 0.7, 0.8"/></bsdf>',
    "roughplastic": '<bsdf type="roughplastic"/>',  # Beckmann, alpha 0.1
    "roughplastic_ggx_nonlinear": '<bsdf type="roughplastic"><string name="distribution" value="ggx"/>'
                                  '<float name="alpha" value="0.4"/><string name="ext_ior" value="water"/>'
                                  '<float name="int_ior" value="1.9"/><boolean name="nonlinear" value="true"/>'
                                  '<rgb name="diffuse_reflectance" value="0.02, 0.2, 0.1"/></bsdf>',
    "roughplastic_beckmann_rough": '<bsdf type="roughplastic"><float name="alpha" value="0.8"/>'
                                   '<float name="int_ior" value="2.0"/></bsdf>',
    "principled": '<bsdf type="principled"><rgb name="base_color" value="0.2, 0.8, 0.1"/>'
                  '<float name="roughness" value="0.3"/><float name="metallic" value="0.3"/>'
                  '<float name="anisotropic" value="0.6"/><float name="spec_tint" value="0.4"/>'
                  '<float name="sheen" value="0.7"/><float name="sheen_tint" value="0.5"/>'
                  '<float name="clearcoat" value="0.8"/><float name="clearcoat_gloss" value="0.3"/>'
                  '<float name="flatness" value="0.4"/><float name="specular" value="0.7"/></bsdf>',
    "principled_metal": '<bsdf type="principled"><rgb name="base_color" value="0.9, 0.6, 0.2"/>'
                        '<float name="metallic" value="1"/><float name="roughness" value="0.15"/></bsdf>',
    "principled_glass": '<bsdf type="principled"><rgb name="base_color" value="0.3, 0.6, 0.8"/>'
                        '<float name="spec_trans" value="0.7"/><float name="roughness" value="0.25"/>'
                        '<float name="eta" value="1.33"/><float name="clearcoat" value="0.4"/>'
                        '<float name="main_specular_sampling_rate" value="2"/></bsdf>',
    "principledthin": '<bsdf type="principledthin"><rgb name="base_color" value="0.7, 0.1, 0.1"/>'
                      '<float name="spec_trans" value="0.4"/><float name="diff_trans" value="1.2"/>'
                      '<float name="sheen" value="0.5"/><float name="anisotropic" value="0.3"/>'
                      '<float name="spec_tint" value="0.6"/><float name="eta" value="1.33"/>'
                      '<float name="flatness" value="0.2"/></bsdf>',
    # roughconductor, roughdielectric: Beckmann (Mitsuba's default) and GGX, isotropic and anisotropic
    "conductor_beckmann_Au": '<bsdf type="roughconductor"><string name="material" value="Au"/>'
                             '<float name="alpha" value="0.2"/></bsdf>',
    "conductor_ggx_aniso": '<bsdf type="roughconductor"><string name="distribution" value="ggx"/>'
                           '<float name="alpha_u" value="0.35"/><float name="alpha_v" value="0.05"/>'
                           '<rgb name="eta" value="0.2, 0.9, 1.1"/><rgb name="k" value="3, 2.5, 2"/></bsdf>',
    "conductor_beckmann_aniso_aC": '<bsdf type="roughconductor"><string name="material" value="a-C"/>'
                                   '<float name="alpha_u" value="0.15"/><float name="alpha_v" value="0.6"/></bsdf>',
    "dielectric_beckmann": '<bsdf type="roughdielectric"><float name="alpha" value="0.6"/>'
                           '<string name="int_ior" value="bk7"/></bsdf>',
    "dielectric_ggx_aniso": '<bsdf type="roughdielectric"><string name="distribution" value="ggx"/>'
                            '<float name="alpha_u" value="0.45"/><float name="alpha_v" value="0.12"/>'
                            '<float name="int_ior" value="1.7"/><string name="ext_ior" value="water"/></bsdf>',
    "dielectric_beckmann_aniso": '<bsdf type="roughdielectric"><float name="alpha_u" value="0.25"/>'
                                 '<float name="alpha_v" value="0.8"/><float name="int_ior" value="1.33"/></bsdf>',
}
TRANSMITS = {"principled_glass", "principledthin", "dielectric_beckmann", "dielectric_ggx_aniso",
             "dielectric_beckmann_aniso"}
BOTH_SIDES = {"principled_glass", "dielectric_beckmann", "dielectric_ggx_aniso", "dielectric_beckmann_aniso"}


def _mi_eval(mi, bsdf, wo, wi):
    """Mitsuba's eval (f cos) and pdf in its local frame: si.wi = wo (toward the viewer)."""
    ctx = mi.BSDFContext()
    f, p = np.zeros((len(wo), 3)), np.zeros(len(wo))
    for k in range(len(wo)):
        si = mi.SurfaceInteraction3f()
        si.n = mi.Normal3f(0, 0, 1)
        si.sh_frame = mi.Frame3f(si.n)
        si.wi = mi.Vector3f(*wo[k])
        v = bsdf.eval(ctx, si, mi.Vector3f(*wi[k]))
        f[k] = [v[0], v[1], v[2]]
        p[k] = bsdf.pdf(ctx, si, mi.Vector3f(*wi[k]))
    return f, p


def _dirs(rng, n, below=0.0):
    z = rng.uniform(0.01, 1, n)
    phi = rng.uniform(0, 2 * np.pi, n)
    r = np.sqrt(1 - z * z)
    d = np.stack([r * np.cos(phi), r * np.sin(phi), np.where(rng.random(n) < below, -z, z)], 1)
    return d.astype(np.float32).astype(np.float64)


def _ours(tmp_path, xml):
    scene, warned = load(write(tmp_path, f'<shape type="rectangle">{xml}</shape>'))
    assert warned == [], warned
    return scene.materials[scene.face_materials[0]]


def _assert_close(ours, theirs, what):
    err = np.abs(ours - theirs) / np.maximum(np.abs(theirs), FLOOR)
    worst = np.unravel_index(np.argmax(err), err.shape)
    assert err.max() < REL, f"{what}: max relative error {err.max():.3g} at {worst}: {ours[worst]} vs {theirs[worst]}"
    return err.max()


@pytest.mark.parametrize("name", list(BSDFS))
def test_eval_and_pdf_agree_with_mitsuba(tmp_path, runtime, name):
    """400 random (wo, wi) pairs, wo above the surface (and, for the transmitting ones, 40% of wi
    below it; principled_glass and the rough dielectrics also seen from inside, Mitsuba's wi.z < 0):
    f cos and the pdf of our BSDF equal Mitsuba's to relative 1e-4 (values under 1e-3 to 1e-7
    absolutely).  Anisotropic ones: our harness's tangent +x is Mitsuba's sh_frame.s."""
    mi = mitsuba()
    mat = _ours(tmp_path, BSDFS[name])
    assert mat.type == name.split("_")[0]
    bsdf = mi.load_string(BSDFS[name].replace("<bsdf ", '<bsdf version="3.0.0" ', 1))
    rng = np.random.default_rng(sum(map(ord, name)))
    n = 400
    sides = (1, 0) if name in BOTH_SIDES else (1,)
    for front in sides:
        wo, wi = _dirs(rng, n), _dirs(rng, n, below=0.4 if name in TRANSMITS else 0.0)
        f, p = bsdf_eval(runtime, [mat], wo, wi, front=front)
        flip = np.array([1.0, 1.0, 1.0 if front else -1.0])  # Mitsuba's frame: z outward
        mf, mp = _mi_eval(mi, bsdf, wo * flip, wi * flip)
        assert (mf.max(1) > 0).mean() > 0.5
        keep = _well_conditioned(wo, wi, mat.ior if front else 1 / mat.ior) if name.startswith("dielectric") \
            else slice(None)
        _assert_close(f[keep], mf[keep], f"{name} f cos (front={front})")
        _assert_close(p[keep], mp[keep], f"{name} pdf (front={front})")


def _well_conditioned(wo, wi, eta):
    """The pairs but refractions whose half vector h (along wo + eta wi) is within |cos| 0.02 of
    grazing wi: there the float32 h, rebuilt from wo + eta wi by cancellation, has few correct
    digits (a few tenths of a percent between us and Mitsuba, as test_materials' reciprocity)."""
    h = wo + eta * wi
    h /= np.linalg.norm(h, axis=1, keepdims=True)
    return (wi[:, 2] > 0) | (np.abs((h * wi).sum(1)) > 0.02)


RENDER_SCENE = """
<default name="resx" value="32"/><default name="resy" value="32"/><default name="spp" value="64"/>
""" + harness.mitsuba_sensor("0, -5.5, 4", 40, "$resx", "$resy", max_depth=6, spp="$spp", target="0, 0, 0.2",
                             up="0, 0, 1") + """<emitter type="constant"><rgb name="radiance" value="0.4, 0.5, 0.6"/></emitter>
<emitter type="point"><point name="position" x="3" y="-4" z="5"/><rgb name="intensity" value="40"/></emitter>
<shape type="sphere"><point name="center" x="-1.1" y="0" z="0.6"/><float name="radius" value="0.5"/>{0}</shape>
<shape type="sphere"><point name="center" x="0" y="0" z="0.6"/><float name="radius" value="0.5"/>{1}</shape>
<shape type="sphere"><point name="center" x="1.1" y="0" z="0.6"/><float name="radius" value="0.5"/>{2}</shape>
<shape type="rectangle">
    <transform name="to_world"><scale x="2.5" y="1.5"/>{3}<translate z="-0.01"/></transform>
    {4}
</shape>
"""
FLOOR_BSDF = """
    <bsdf type="principled">
        <texture name="base_color" type="checkerboard"><transform name="to_uv"><scale x="4" y="4"/></transform>
            <rgb name="color0" value="0.8, 0.7, 0.2"/><rgb name="color1" value="0.1, 0.3, 0.6"/></texture>
        <texture name="roughness" type="checkerboard"><transform name="to_uv"><scale x="3" y="3"/></transform>
            <float name="color0" value="0.1"/><float name="color1" value="0.7"/></texture>
        <texture name="metallic" type="checkerboard"><transform name="to_uv"><scale x="2" y="2"/></transform>
            <float name="color0" value="0.9"/><float name="color1" value="0"/></texture>
        <texture name="sheen" type="checkerboard"><float name="color0" value="0.8"/>
            <float name="color1" value="0"/></texture>
    </bsdf>"""
# an anisotropic Beckmann rough metal, rotated: its tangent is dp/du of the rectangle's UVs; alpha_v a texture
ROUGH_FLOOR = """
    <bsdf type="roughconductor"><string name="material" value="Al"/>
        <float name="alpha_u" value="0.35"/>
        <texture name="alpha_v" type="checkerboard"><float name="color0" value="0.04"/>
            <float name="color1" value="0.12"/></texture>
    </bsdf>"""
SPHERES = {  # three spheres, the floor's rotation and BSDF
    "plastics": (BSDFS["plastic_bk7_nonlinear"], BSDFS["roughplastic"], BSDFS["roughplastic_ggx_nonlinear"], "",
                 FLOOR_BSDF),
    "principled": (BSDFS["principled"], BSDFS["principled_glass"], BSDFS["principledthin"], "", FLOOR_BSDF),
    "rough": (BSDFS["conductor_beckmann_aniso_aC"], BSDFS["dielectric_beckmann"], BSDFS["dielectric_ggx_aniso"],
              '<rotate z="1" angle="35"/>', ROUGH_FLOOR),
}


@pytest.mark.parametrize("which", list(SPHERES))
def test_render_matches_mitsuba(tmp_path, which):
    """Three spheres of these BSDFs and a textured principled floor (checkerboards of base colour,
    roughness, metallic and sheen, with to_uv) under a constant environment and a point light, 32 x
    32, rendered by Mitsuba 3 (scalar_rgb, 8 batches of 64 spp: their spread gives its variance) and
    by us (512 spp): the image means per channel within 4 standard errors and 1% of each other,
    and every 8 x 8 tile within 5 standard errors.  "rough": rough conductors and dielectrics,
    Beckmann and GGX, anisotropic on the spheres (their tangent: dp/du of Mitsuba's unrotated sphere)
    and on a rotated floor (dp/du of its UVs) with a textured alpha_v.  The anisotropic principled
    and principledthin spheres follow the same tangent."""
    mi = mitsuba()
    path = write(tmp_path, RENDER_SCENE.format(*SPHERES[which]))
    w = h = 32
    theirs, their_var = _mitsuba_image(mi, path, w, h, 8, 64)
    scene, warned = load(path)
    assert warned == [], warned
    r = render_full(scene, spp=512, width=w, height=h, device="cpu", seed=3)
    ours, var = r.image.astype(np.float64), r.film.variance_of_mean()
    assert r.info["nonfinite_samples"] == 0
    m_ours, m_theirs = ours.mean((0, 1)), theirs.mean((0, 1))
    se = np.sqrt((var + their_var).sum((0, 1))) / (w * h)
    assert np.all(np.abs(m_ours - m_theirs) < 4 * se), (m_ours, m_theirs, se)
    assert np.allclose(m_ours, m_theirs, rtol=0.01), (m_ours / m_theirs)

    def tiles(a):
        return a.reshape(h // 8, 8, w // 8, 8, 3).sum(axis=(1, 3)) / 64

    # the variance floored at (1e-4 x the value)^2: the environment alone has none (and Mitsuba's
    # RGB radiance 0.4 is 0.39999977)
    tvar = np.maximum((tiles(var) + tiles(their_var)) / 64, (1e-4 * tiles(theirs)) ** 2)
    z = (tiles(ours) - tiles(theirs)) / np.sqrt(tvar)
    assert np.abs(z).max() < 5, np.round(z, 2)
