"""pbrt-v4's coated conductor ("coatedconductor", cl/materials/coatedconductor.h): a random walk
between a dielectric coating and a conductor, as pbrt-v4's LayeredBxDF estimates it.

* Smooth coating over a smooth metal: every sample is a delta sample, and the mean weight is a closed
  form, the coating's reflection plus the light that crosses it, bounces k + 1 times on the metal and
  k times under the coating, each crossing attenuated by the layer, for the k that pbrt's maxdepth
  of 10 allows (k = 0..4): F + (1 - F)^2 t^2 Fc sum_k (F Fc t^2)^k.
* Rough layers: the directional albedo that sampling estimates (mean weight) against the one that
  f's estimates give, integrated over the hemisphere (z-test, |z| < 4.5): with one rough layer, and
  with two through each of f's two connections alone.  (pbrt-v4 weights the two connections with
  the power heuristic of densities of different directions, which adds a few per cent: measured in
  test_pbrt_weights_brighten_two_rough_layers.)
* The TOML keys pack into documented fields (test_material_registry.py), and pbrt's parameters load.
Lane widths' bits: test_materials.py's random records include this type."""
import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError, load_scene
from pyopencl_rt.scene.materials.conductor import METALS
from pyopencl_rt.scene.model import Material

import harness
from test_materials import HARNESS, _bsdf, bsdf_sample, direction, fresnel_complex, fresnel_dielectric, u3
from test_roughdiffuse import hemisphere

N = 1 << 17
Z_MAX = 4.5


def coated(coat=0.0, metal=0.0, thickness=0.01, ior=1.5, metal_name="copper"):
    m = Material("cc", type="coatedconductor", alpha=coat, ior=ior)
    m.eta, m.k = METALS[metal_name]
    m.params.update(conductor_alpha_u=metal, conductor_alpha_v=metal, thickness=thickness)
    return m


def series(theta, ior, eta, k, thickness, terms=5):
    """The mean sample weight of a smooth coating over a smooth metal, in float64."""
    c = np.cos(theta)
    F = fresnel_dielectric(c, ior)
    c_t = np.sqrt(1 - (1 - c * c) / ior ** 2)
    fc = np.array([fresnel_complex(c_t, e / ior, kk / ior) for e, kk in zip(eta, k)])
    t2 = np.exp(-2 * thickness / c_t)
    return F + (1 - F) ** 2 * t2 * fc * sum((F * fc * t2) ** n for n in range(terms))


def z_scores(a, b):
    """|mean a - mean b| over their standard errors, per channel (a, b: samples (n, 3))."""
    se = np.sqrt(a.var(0) / len(a) + b.var(0) / len(b))
    return np.abs(a.mean(0) - b.mean(0)) / np.maximum(se, 1e-12)


@pytest.mark.parametrize("theta_deg, thickness", [(0, 0.01), (40, 0.01), (75, 0.01), (40, 0.5)])
def test_smooth_layers_sum_the_series(runtime, rng, theta_deg, thickness):
    m = coated(thickness=thickness)
    wo = direction(np.radians(theta_deg) + 1e-3)
    wi, w, pdf, delta = bsdf_sample(runtime, [m], wo, u3(rng, N))
    got = w.max(1) > 0  # the others' walks ended inside (Russian roulette, maxdepth): weight 0
    assert delta[got].all() and not pdf.any() and got.mean() > 0.9
    assert np.allclose(wi[got], [-wo[0], -wo[1], wo[2]], atol=2e-6)  # smooth layers keep the mirror direction
    expect = series(np.radians(theta_deg) + 1e-3, 1.5, *METALS["copper"], thickness)
    se = np.maximum(w.std(0) / np.sqrt(N), 1e-7)
    assert (np.abs(w.mean(0) - expect) / se < Z_MAX).all(), (w.mean(0), expect)


def _eval(runtime, m, wo, wi, nee=0):
    kernels = HARNESS if nee == 0 else harness.Kernels(HARNESS.source, defines={"COATED_NEE": nee})
    out = _bsdf(runtime, "h_bsdf_eval", [m], wo, np.asarray(wi, np.float32), 0, 1, (0.0, 0.0, 1.0), 4,
                kernels=kernels).astype(np.float64)
    return out[:, :3], out[:, 3]


def _albedos(runtime, rng, m, theta, nee=0):
    """(weights of the non-delta samples, zero elsewhere; f cos / uniform pdf of uniform directions)"""
    wo = direction(np.radians(theta))
    _, w, _, delta = bsdf_sample(runtime, [m], wo, u3(rng, N))
    f, pdf = _eval(runtime, m, wo, hemisphere(rng, N), nee)
    assert np.isfinite(f).all() and (pdf > 0).all()
    return np.where(delta[:, None], 0.0, w), f * 2 * np.pi


@pytest.mark.parametrize("coat, metal, nee", [(0.3, 0.0, 0), (0.0, 0.3, 0), (0.3, 0.4, 1), (0.3, 0.4, 2)],
                         ids=["rough-coat", "rough-metal", "both-rough-via-wi", "both-rough-via-coat"])
def test_f_integrates_to_the_sampled_albedo(runtime, rng, coat, metal, nee):
    """The glossy part of the directional albedo (at 40 degrees), by sampling and by f: the delta samples
    (a smooth coating's reflection) are f's delta part, which no f can give."""
    sampled, integrated = _albedos(runtime, rng, coated(coat, metal), 40.0, nee)
    assert (z_scores(sampled, integrated) < Z_MAX).all(), (sampled.mean(0), integrated.mean(0))
    assert sampled.mean(0)[0] > 0.3  # the test has something to compare


def test_pbrt_weights_brighten_two_rough_layers(runtime, rng):
    """pbrt-v4's f weights its connection out through a rough coating with the density of wi given the
    bounce, where its partner's weight takes the density of the bounce given wi: the weights do not sum
    to one, and with both layers rough its f integrates a little above the albedo that sampling (and
    either connection alone) gives.  We render as pbrt does; this records by how much (7-8 % here)."""
    sampled, integrated = _albedos(runtime, rng, coated(0.3, 0.4), 40.0)
    ratio = integrated.mean(0) / sampled.mean(0)
    assert (ratio > 1.03).all() and (ratio < 1.15).all(), ratio


def test_toml_and_pbrt_front_ends(tmp_path):
    (tmp_path / "c.pbrt").write_text(
        'Camera "perspective"\nWorldBegin\nLightSource "infinite" "rgb L" [1 1 1]\n'
        'Material "coatedconductor" "float interface.eta" [1.4] "float interface.roughness" [0.04] '
        '"float conductor.uroughness" [0.09] "float conductor.vroughness" [0.16] "rgb reflectance" [0.5 0.5 0.5] '
        '"float thickness" [0.02] "integer maxdepth" [6] "integer nsamples" [2]\n'
        'Shape "sphere" "float radius" [1]\n')
    m = load_scene(tmp_path / "c.pbrt").materials[0]
    rec = m.record()
    assert m.type == "coatedconductor" and rec["ior"] == np.float32(1.4)
    assert np.isclose(rec["alpha"], 0.2)  # pbrt's RoughnessToAlpha: sqrt
    assert np.allclose(rec["eta"], 1 / 1.4) and np.allclose(rec["k"], 2 / 1.4)  # r = 0.5: k = 2
    assert np.allclose(rec["table"][:5], [0.3, 0.4, 0.02, 6, 2])
    (tmp_path / "a.pbrt").write_text((tmp_path / "c.pbrt").read_text().replace(
        '"integer nsamples" [2]', '"rgb albedo" [0.5 0.5 0.5]'))
    with pytest.raises(SceneError, match="scattering coating"):
        load_scene(tmp_path / "a.pbrt")
    (tmp_path / "t.toml").write_text('[materials.m]\ntype = "coatedconductor"\nsamples = 1.5\n[[shape]]\n'
                                     'type = "sphere"\nmaterial = "m"\ncenter = [0, 0, 0]\nradius = 1\n')
    with pytest.raises(SceneError, match="whole number"):
        load_scene(tmp_path / "t.toml")
