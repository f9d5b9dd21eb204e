"""pbrt-v4's diffuse transmission ("diffusetransmission", cl/materials/diffusetransmission.h) added as a
unit: f against its closed form on both sides, the side sampled in proportion to the two colours'
largest channels (binomial z-test), the sample weights' exact values, R = T = 0 scatters nothing, and
the pbrt front end (scale, clamping, a transmittance texture refused).  Its chi-square test is among
tests/scene/test_materials.py's cases, and the lane widths' bits there cover it."""
import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError, load_scene
from pyopencl_rt.scene.model import Material

from test_materials import bsdf_eval, bsdf_sample, direction, u3

R, T = (0.2, 0.5, 0.1), (0.6, 0.3, 0.9)


def sheet(r=R, t=T):
    return Material("dt", type="diffusetransmission", albedo=r, params={"transmittance": t})


def _sphere(rng, n):
    v = rng.normal(size=(n, 3))
    return v / np.linalg.norm(v, axis=1, keepdims=True)


def test_eval_is_lambert_on_each_side(runtime, rng):
    wo = np.abs(_sphere(rng, 4096))
    wi = _sphere(rng, 4096)
    f, pdf = bsdf_eval(runtime, [sheet()], wo, wi)
    same = (wi[:, 2] > 0)[:, None]
    expect = np.where(same, R, T) / np.pi * np.abs(wi[:, 2:3])
    assert np.allclose(f, expect, rtol=2e-6, atol=1e-9)
    pr = 0.5 / (0.5 + 0.9)
    assert np.allclose(pdf, np.abs(wi[:, 2]) / np.pi * np.where(same[:, 0], pr, 1 - pr), rtol=2e-6, atol=1e-9)


def test_sampling_picks_the_side_by_the_largest_channels(runtime, rng):
    n = 200_000
    wi, w, pdf, delta = bsdf_sample(runtime, [sheet()], direction(np.radians(30)), u3(rng, n))
    pr = 0.5 / (0.5 + 0.9)
    up = wi[:, 2] > 0
    assert abs(up.mean() - pr) / np.sqrt(pr * (1 - pr) / n) < 4.5
    assert not delta.any() and (pdf > 0).all()
    assert np.allclose(w[up], np.asarray(R) / pr, rtol=1e-6) and np.allclose(w[~up], np.asarray(T) / (1 - pr), rtol=1e-6)
    assert np.allclose(pdf, np.abs(wi[:, 2]) / np.pi * np.where(up, pr, 1 - pr), rtol=1e-5)
    # the mean weight is the albedo of both sides, R + T
    se = w.std(0) / np.sqrt(n)
    assert (np.abs(w.mean(0) - (np.asarray(R) + T)) / se < 4.5).all()


def test_black_scatters_nothing(runtime, rng):
    wi, w, pdf, delta = bsdf_sample(runtime, [sheet((0, 0, 0), (0, 0, 0))], direction(0.3), u3(rng, 256))
    assert not w.any() and not pdf.any()
    f, p = bsdf_eval(runtime, [sheet((0, 0, 0), (0, 0, 0))], direction(0.3), _sphere(rng, 256))
    assert not f.any() and not p.any()


def test_pbrt_front_end(tmp_path):
    def load(text):
        (tmp_path / "d.pbrt").write_text('Camera "perspective"\nWorldBegin\nLightSource "infinite" "rgb L" [1 1 1]\n'
                                         f'{text}\nShape "sphere" "float radius" [1]\n')
        return load_scene(tmp_path / "d.pbrt")

    m = load('Material "diffusetransmission"').materials[0]
    assert m.type == "diffusetransmission" and m.albedo == (0.25,) * 3 and m.params["transmittance"] == (0.25,) * 3  # pbrt's
    m = load('Material "diffusetransmission" "rgb reflectance" [0.5 0.2 0.9] "rgb transmittance" [0.1 0.6 0.3] '
             '"float scale" 1.5').materials[0]
    assert np.allclose(m.albedo, (0.75, 0.3, 1.0)) and np.allclose(m.params["transmittance"], (0.15, 0.9, 0.45))
    rec = m.record()
    assert np.allclose(rec["albedo"], m.albedo) and np.allclose(rec["table"][:3], m.params["transmittance"])
    assert rec["ior"] == 0 and not rec["specular"].any()  # the transmittance in its block, no other field
    with pytest.raises(SceneError, match="texture transmittance"):
        load('Texture "t" "spectrum" "constant" "rgb value" [0.5 0.5 0.5]\n'
             'Material "diffusetransmission" "texture transmittance" "t"')
