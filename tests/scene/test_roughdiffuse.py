"""The Oren-Nayar rough diffuse BSDF ("roughdiffuse", cl/materials/roughdiffuse.h) added as a unit:
its eval against a float64 transcription of Oren & Nayar's formulas in Mitsuba 0.6's parameters,
its directional albedo against a closed form at normal incidence and a float64 quadrature
elsewhere, the mean of its sample weights against that integral (z-test, |z| < 4.5), sigma = 0
against Lambert's law, and its TOML and Mitsuba XML front ends.  The chi-square test of its sampled
directions is among tests/scene/test_materials.py's cases, as are its lane widths' bits."""
import numpy as np
import pytest

from pyopencl_rt.render.api import render_full
from pyopencl_rt.scene.loaders import SceneError, load_scene
from pyopencl_rt.scene.model import Material

from test_materials import bsdf_eval, bsdf_sample, direction, u3
from test_mitsuba_xml import write

RHO = (0.9, 0.5, 0.1)
ALPHAS = [0.0, 0.1, 0.3, 0.7, 1.5]


def rough(alpha, fast=False, albedo=RHO):
    return Material("rd", type="roughdiffuse", albedo=albedo, alpha=alpha, params={"fast_approx": fast})


def oren_nayar(wo, wi, alpha, fast, rho=RHO):
    """f |cos_i| in float64, from the model's angles (arccos, atan) rather than the kernel's sines."""
    rho = np.asarray(rho, np.float64)
    th_o, th_i = np.arccos(np.clip(wo[:, 2], -1, 1)), np.arccos(np.clip(wi[:, 2], -1, 1))
    ph_o, ph_i = np.arctan2(wo[:, 1], wo[:, 0]), np.arctan2(wi[:, 1], wi[:, 0])
    cos_phi = np.where((np.sin(th_o) > 1e-4) & (np.sin(th_i) > 1e-4), np.cos(ph_i - ph_o), 0.0)
    a, b = np.maximum(th_o, th_i), np.minimum(th_o, th_i)
    s2 = alpha ** 2 / 2
    A, B = 1 - 0.5 * s2 / (s2 + 0.33), 0.45 * s2 / (s2 + 0.09)
    if fast:
        single, twice = A + B * np.maximum(cos_phi, 0) * np.sin(a) * np.tan(b), 0.0 * a
    else:
        c2 = B * np.where(cos_phi >= 0, np.sin(a), np.sin(a) - (2 * b / np.pi) ** 3)
        c3 = 0.125 * s2 / (s2 + 0.09) * (4 * a * b / np.pi ** 2) ** 2
        single = A + cos_phi * c2 * np.tan(b) + (1 - np.abs(cos_phi)) * c3 * np.tan((a + b) / 2)
        twice = 0.17 * s2 / (s2 + 0.13) * (1 - cos_phi * (2 * b / np.pi) ** 2)
    f = (rho * single[:, None] + rho ** 2 * twice[:, None]) / np.pi
    up = (wo[:, 2] > 0) & (wi[:, 2] > 0)
    return np.where(up[:, None], f * wi[:, 2:3], 0.0)


def hemisphere(rng, n):
    v = rng.normal(size=(n, 3))
    v /= np.linalg.norm(v, axis=1, keepdims=True)
    v[:, 2] = np.abs(v[:, 2])
    return v


@pytest.mark.parametrize("fast", [False, True], ids=["full", "fast"])
@pytest.mark.parametrize("alpha", ALPHAS)
def test_eval_is_oren_nayar_in_float64(runtime, rng, alpha, fast):
    """4096 random (wo, wi) pairs over the upper hemisphere, some near the normal and near grazing:
    f |cos_i| within 2e-4 relative (+ 1e-6: the kernel's acos is a polynomial) of the float64
    formulas, the pdf cos_i / pi, and 0 with wi below the surface."""
    n = 4096
    wo, wi = hemisphere(rng, n), hemisphere(rng, n)
    wo[:64] = direction(0.0)
    wi[64:128] = direction(np.radians(89.9), 1.0)
    f, pdf = bsdf_eval(runtime, [rough(alpha, fast)], wo, wi)
    expect = oren_nayar(wo, wi, alpha, fast)
    assert np.allclose(f, expect, rtol=2e-4, atol=1e-6), np.abs(f - expect).max()
    assert np.allclose(pdf, wi[:, 2] / np.pi, rtol=1e-5, atol=1e-7)
    below = wi.copy()
    below[:, 2] *= -1
    f_below, pdf_below = bsdf_eval(runtime, [rough(alpha, fast)], wo, below)
    assert not f_below.any() and not pdf_below.any()


@pytest.mark.parametrize("fast", [False, True], ids=["full", "fast"])
def test_sigma_zero_is_lambert(runtime, rng, fast):
    wo, wi = hemisphere(rng, 1024), hemisphere(rng, 1024)
    f, _ = bsdf_eval(runtime, [rough(0.0, fast)], wo, wi)
    assert np.allclose(f, np.asarray(RHO) / np.pi * wi[:, 2:3], rtol=2e-6, atol=0)


def hemisphere_rule(k=48, m=96):
    """Directions over the upper hemisphere and their weights (solid angle): Gauss-Legendre in
    cos(theta) (k nodes) times the midpoint rule in phi (m nodes)."""
    x, w = np.polynomial.legendre.leggauss(k)
    MU, PHI = np.meshgrid((x + 1) / 2, (np.arange(m) + 0.5) * 2 * np.pi / m, indexing="ij")
    s = np.sqrt(1 - MU ** 2)
    wi = np.stack([s * np.cos(PHI), s * np.sin(PHI), MU], -1).reshape(-1, 3)
    return wi, np.repeat(w / 2, m) * (2 * np.pi / m)


def albedo_quadrature(runtime, mat, wo):
    """The directional albedo, the integral of the device's f |cos_i| over the hemisphere."""
    wi, weights = hemisphere_rule()
    f, _ = bsdf_eval(runtime, [mat], wo, wi)
    return (f * weights[:, None]).sum(0)


@pytest.mark.parametrize("fast", [False, True], ids=["full", "fast"])
@pytest.mark.parametrize("alpha", [0.2, 0.6, 1.2])
def test_albedo_at_normal_incidence_is_the_closed_form(runtime, alpha, fast):
    """At theta_o = 0 the azimuth is undefined and b = 0, so only C1 (= A) and the
    interreflection C4 remain: albedo = rho A + rho^2 C4 (full), rho A (fast)."""
    s2 = alpha ** 2 / 2
    A, C4 = 1 - 0.5 * s2 / (s2 + 0.33), 0.17 * s2 / (s2 + 0.13)
    rho = np.asarray(RHO)
    expect = rho * A + (0.0 if fast else rho ** 2 * C4)
    got = albedo_quadrature(runtime, rough(alpha, fast), direction(0.0))
    assert np.allclose(got, expect, rtol=2e-4), (got, expect)


@pytest.mark.parametrize("fast", [False, True], ids=["full", "fast"])
@pytest.mark.parametrize("alpha, theta_o", [(0.3, 30.0), (0.7, 60.0), (1.2, 80.0)])
def test_sample_weights_average_to_the_float64_albedo(runtime, rng, alpha, theta_o, fast):
    """The mean sample weight (f |cos| / pdf) over 200k samples estimates the directional albedo:
    within 4.5 standard errors of the float64 formulas' integral (the same quadrature over
    oren_nayar), which the device's own quadrature matches to 2e-4."""
    wo = direction(np.radians(theta_o), 0.4)
    mat = rough(alpha, fast)
    wi, weights = hemisphere_rule()
    ref = (oren_nayar(np.tile(wo, (len(wi), 1)), wi, alpha, fast) * weights[:, None]).sum(0)
    assert np.allclose(albedo_quadrature(runtime, mat, wo), ref, rtol=2e-4)
    n = 200_000
    wi_s, weight, pdf, delta = bsdf_sample(runtime, [mat], wo, u3(rng, n))
    assert not delta.any() and np.all(pdf > 0) and np.isfinite(weight).all()
    mean, se = weight.mean(0), weight.std(0) / np.sqrt(n)
    assert np.all(np.abs(mean - ref) < 4.5 * se + 1e-6), (mean, ref, se)


def test_toml_and_mitsuba_xml_front_ends(tmp_path, device):
    """A TOML [materials] table and Mitsuba's <bsdf type="roughdiffuse"> give the same record
    (Mitsuba's is one-sided, as its BSDFs are), the scene renders finite and at alpha 0 as bright
    as diffuse (the same film within 1e-3 relative: the same cosine samples in the two frames), and
    Mitsuba 0.6's camelCase parameter is refused in one line."""
    def scene_file(name, bsdf):
        return write(tmp_path, f"""{bsdf}
            <shape type="rectangle"><ref id="rd"/></shape>
            <emitter type="constant"><rgb name="radiance" value="1"/></emitter>
            <sensor type="perspective"><transform name="to_world"><lookat origin="0, 0, 3" target="0, 0, 0"
                up="0, 1, 0"/></transform><film type="hdrfilm"><integer name="width" value="24"/>
                <integer name="height" value="24"/></film></sensor>""", name=name)

    xml = scene_file("rd.xml", """<bsdf type="roughdiffuse" id="rd"><rgb name="reflectance" value="0.2 0.4 0.6"/>
        <float name="alpha" value="0.3"/><boolean name="use_fast_approx" value="true"/></bsdf>""")
    (mat,) = [m for m in load_scene(xml).materials if m.name == "rd"]
    assert (mat.type, mat.one_sided, mat.alpha, mat.params["fast_approx"]) == ("roughdiffuse", True, 0.3, True)
    assert np.allclose(mat.albedo, (0.2, 0.4, 0.6))
    bad = scene_file("bad.xml", """<bsdf type="roughdiffuse" id="rd"><boolean name="useFastApprox" value="true"/>
        </bsdf>""")
    with pytest.raises(SceneError, match="useFastApprox"):
        load_scene(bad)
    images = {}
    for kind in ("roughdiffuse", "diffuse"):
        alpha = '<float name="alpha" value="0"/>' if kind == "roughdiffuse" else ""
        scene = load_scene(scene_file(f"{kind}.xml", f"""<bsdf type="{kind}" id="rd">
            <rgb name="reflectance" value="0.2 0.4 0.6"/>{alpha}</bsdf>"""))
        images[kind] = render_full(scene, device=device, spp=16, seed=3).image
    assert np.isfinite(images["roughdiffuse"]).all() and images["roughdiffuse"].mean() > 0
    assert abs(images["roughdiffuse"].mean() / images["diffuse"].mean() - 1) < 1e-3
