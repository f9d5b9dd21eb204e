"""pbrt-v4 Film parameters of issue 37: maxcomponentvalue (a per-sample clamp in pbrt's sensor
space) and whitebalance."""
from __future__ import annotations

import numpy as np
import pytest

from pyopencl_rt.scene.loaders import SceneError, load_scene

# Rec. 709 linear RGB -> CIE XYZ (D65), for pbrt's cie1931 sensor
RGB_TO_XYZ = np.array([[0.412453, 0.357580, 0.180423],
                       [0.212671, 0.715160, 0.072169],
                       [0.019334, 0.119193, 0.950227]])

# an orthographic view of 9 x 9 pixels over [-1, 1]^2; an emitter covers x < 0 (4.5 columns): the
# middle column is half covered
SCENE = """LookAt 0 0 -1  0 0 0  0 1 0
Camera "orthographic"
Film "rgb" "integer xresolution" 9 "integer yresolution" 9 {film}
PixelFilter "box"
Sampler "independent" "integer pixelsamples" 64
Integrator "path" "integer maxdepth" 1
WorldBegin
AttributeBegin
  AreaLightSource "diffuse" "rgb L" [{L}] "bool twosided" true
  Material "diffuse" "rgb reflectance" [0 0 0]
  Shape "trianglemesh" "point3 P" [-10 -10 1  0 -10 1  0 10 1  -10 10 1] "integer indices" [0 1 2 0 2 3]
AttributeEnd
"""


def render(tmp_path, film="", L="100 100 100", name="s.pbrt", kernel_mode=None):
    import pyopencl_rt as rt

    path = tmp_path / name
    path.write_text(SCENE.format(film=film, L=L))
    scene = load_scene(path)
    return rt.render_full(scene, spp=64, width=9, height=9, device="cpu", seed=3,
                          kernel_mode=kernel_mode).image.astype(np.float64)


def lit_columns(image):
    """The four columns wholly on the emitter (mirroring aside: the brighter side), the half
    covered middle one, and the four dark ones."""
    left, right = image[:, :4].mean(), image[:, 5:].mean()
    lit, dark = (slice(0, 4), slice(5, 9)) if left > right else (slice(5, 9), slice(0, 4))
    return image[:, lit], image[:, 4], image[:, dark]


@pytest.mark.parametrize("L", ["100 100 100", "100 10 1"])
def test_maxcomponentvalue_clamps_each_sample_in_xyz(tmp_path, L):
    free = render(tmp_path, L=L, name="free.pbrt")
    clamped = render(tmp_path, film='"float maxcomponentvalue" 20', L=L, name="clamped.pbrt")
    lit_free, _, dark = lit_columns(free)
    rgb = lit_free.reshape(-1, 3).mean(0)  # the emitter's radiance as we render it
    assert np.allclose(lit_free, rgb, rtol=1e-5)
    m = (RGB_TO_XYZ @ rgb).max()
    assert m > 20
    expect = rgb * 20 / m  # scaled, hue kept: the largest of X, Y, Z becomes 20
    lit, middle, dark = lit_columns(clamped)
    assert np.allclose(lit, expect, rtol=1e-4)
    assert np.allclose((RGB_TO_XYZ @ lit.reshape(-1, 3).T).max(0), 20, rtol=1e-4)
    assert np.all(dark == 0)
    # per sample, not per pixel: the half-covered column averages clamped samples with black ones,
    # about half of expect (a clamp of the pixel's mean would give expect itself)
    assert np.all(np.abs(middle.mean(0) / expect - 0.5) < 0.2)


def test_maxcomponentvalue_in_the_wavefront_kernels(tmp_path):
    """The wavefront's accumulate stage clamps as the megakernel does: the same image."""
    film = '"float maxcomponentvalue" 20'
    mega = render(tmp_path, film=film, name="m.pbrt", kernel_mode="megakernel")
    wave = render(tmp_path, film=film, name="w.pbrt", kernel_mode="wavefront")
    lit, _, _ = lit_columns(wave)
    assert (RGB_TO_XYZ @ lit.reshape(-1, 3).T).max() <= 20 * (1 + 1e-5)
    assert np.allclose(wave, mega, rtol=1e-5, atol=1e-6)


def test_maxcomponentvalue_leaves_dim_samples_alone(tmp_path):
    free = render(tmp_path, L="1 1 1", name="free.pbrt")
    clamped = render(tmp_path, film='"float maxcomponentvalue" 20', L="1 1 1", name="clamped.pbrt")
    assert np.array_equal(free, clamped)


@pytest.mark.parametrize("value", ["0", "-1"])
def test_bad_maxcomponentvalue_is_one_error_line(tmp_path, value):
    path = tmp_path / "s.pbrt"
    path.write_text(SCENE.format(film=f'"float maxcomponentvalue" {value}', L="1 1 1"))
    with pytest.raises(SceneError, match=rf':3: Film "float maxcomponentvalue" must be > 0, got {value}$'):
        load_scene(path)


# -- whitebalance ------------------------------------------------------------------------------------

def neutral_error(rgb):
    rgb = np.asarray(rgb, np.float64)
    return float(np.abs(rgb / rgb.mean() - 1).max())


def test_white_balance_maps_the_illuminant_to_white():
    """Balanced for T, a white lit by the CIE daylight of T comes out neutral: D50 (x, y) =
    (0.3457, 0.3585), the D series at 5003 K, which pbrt-v4 asks for as 5000 (its cct is
    T x 1.4388 / 1.4380)."""
    from pyopencl_rt.scene.loaders.pbrt_film import white_balance_matrix

    x, y = 0.3457, 0.3585
    d50 = np.linalg.inv(RGB_TO_XYZ) @ np.array([x / y, 1.0, (1 - x - y) / y])
    assert neutral_error(d50) > 0.1  # warm before
    assert neutral_error(white_balance_matrix(5000) @ d50) < 2e-3
    # balanced for D65 (6504 K) nothing changes; a warmer balance makes a white bluer
    assert np.allclose(white_balance_matrix(6500), np.eye(3), atol=2e-3)
    cool = white_balance_matrix(3200) @ np.ones(3)
    assert cool[2] > cool[1] > cool[0]


def test_below_4000_kelvin_the_source_is_a_black_body():
    """pbrt-v4's D(T) is a black body below a cct of 4000 K: the Planckian locus at 3000 K is
    (0.4369, 0.4041) (CIE 15)."""
    from pyopencl_rt.scene.loaders.pbrt_film import daylight_xy

    x, y = daylight_xy(3000 * 1.4380 / 1.4388)
    assert abs(x - 0.4369) < 1e-3 and abs(y - 0.4041) < 1e-3
    x, y = daylight_xy(6504 * 1.4380 / 1.4388)  # D65, the D series at 6504 K: (0.3127, 0.3290)
    assert abs(x - 0.3127) < 1e-3 and abs(y - 0.3290) < 1e-3


def test_white_balance_is_applied_to_the_rendered_image(tmp_path):
    from pyopencl_rt.scene.loaders.pbrt_film import white_balance_matrix

    free = render(tmp_path, L="3 2 1", name="free.pbrt")
    balanced = render(tmp_path, film='"float whitebalance" 4000', L="3 2 1", name="wb.pbrt")
    expect = free @ white_balance_matrix(4000).T
    assert free.max() > 1 and np.allclose(balanced, expect, rtol=1e-5, atol=1e-6)
    assert not np.allclose(balanced, free, rtol=1e-2)


def test_negative_white_balance_is_one_error_line(tmp_path):
    path = tmp_path / "s.pbrt"
    path.write_text(SCENE.format(film='"float whitebalance" -5', L="1 1 1"))
    with pytest.raises(SceneError, match=r':3: Film "float whitebalance" must be 0 \(none\) or a temperature > 0'):
        load_scene(path)
