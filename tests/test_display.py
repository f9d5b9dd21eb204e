"""The PNG's display transform (pyopencl_rt/display.py), the compare metrics (pyopencl_rt/compare.py)
and the output files (imageio.write_outputs).  Host-only."""
import numpy as np
import pytest

from pyopencl_rt import compare, display
from pyopencl_rt.errors import UserError
from pyopencl_rt.display import linear_to_srgb
from pyopencl_rt.imageio import read_exr, read_exr_channels, write_outputs

RAMP = np.geomspace(1e-6, 1e4, 20001)
LUMA = np.array([0.2126, 0.7152, 0.0722])


def grey(x):
    return np.stack([x, x, x], -1)


def test_clamp_is_the_identity_on_0_1_and_exposure_doubles():
    x = np.random.default_rng(1).random((50, 3))
    np.testing.assert_array_equal(display.tonemap(x, "clamp"), x)
    np.testing.assert_array_equal(display.tonemap(np.array([[-1.0, 2.0, np.nan]]), "clamp"), [[0.0, 1.0, 0.0]])
    # +1 EV doubles the linear value: the display of x at +1 EV is that of 2x at 0 EV
    np.testing.assert_array_equal(display.display(x / 4, exposure=1.0), display.display(x / 2))
    np.testing.assert_allclose(display.display(x / 4, exposure=2.0), linear_to_srgb(x), atol=1e-15)


@pytest.mark.parametrize("curve", display.TONEMAPS)
def test_curves_are_monotonic_and_bounded(curve):
    y = display.tonemap(grey(RAMP), curve)
    assert (np.diff(y, axis=0) >= 0).all()
    assert y.min() >= 0 and y.max() <= 1
    assert display.tonemap(grey(np.zeros(1)), curve).max() < 1e-3  # black stays black
    assert y[-1].min() > 0.99  # 10^4 is white
    # any colour scaled up: the display luminance never falls (AgX mixes channels, so per channel
    # it is only nearly monotonic; 1e-6 is far below one 8-bit step)
    for c in np.random.default_rng(2).random((30, 3)):
        lum = display.tonemap(RAMP[:, None] * c, curve) @ LUMA
        assert np.diff(lum).min() >= -1e-6, c


def test_filmic_is_the_aces_fit():
    # Narkowicz's fit at 0.6 x: 0.18 (mid grey) maps to 0.140 and the curve saturates near 16
    x = 0.6 * 0.18
    expect = x * (2.51 * x + 0.03) / (x * (2.43 * x + 0.59) + 0.14)
    assert display.tonemap(grey(np.array([0.18])), "filmic")[0, 0] == pytest.approx(expect, rel=1e-12)
    assert expect == pytest.approx(0.1401, abs=1e-4)


def test_compare_metrics_closed_forms():
    rng = np.random.default_rng(3)
    ref = rng.random((16, 20, 3)) + 0.1
    m = compare.metrics(ref * 1.1, ref)
    np.testing.assert_allclose(m["mean_ratio"], 1.1, rtol=1e-12)
    assert m["mse"] == pytest.approx(np.mean((0.1 * ref) ** 2), rel=1e-12)
    assert m["rmse"] == pytest.approx(np.sqrt(m["mse"]), rel=1e-12)
    assert m["relmse"] == pytest.approx(np.mean((0.1 * ref) ** 2 / (ref**2 + 1e-2)), rel=1e-12)
    same = compare.metrics(ref, ref)
    assert same["mse"] == 0 and same["relmse"] == 0 and same["mean_ratio"] == [1.0, 1.0, 1.0]
    with pytest.raises(UserError, match="differ in size"):
        compare.metrics(ref[:8], ref)


def test_flip_and_heatmap(tmp_path):
    pytest.importorskip("flip_evaluator")  # installed by the dev extra
    rng = np.random.default_rng(4)
    ref = rng.random((32, 32, 3)).astype(np.float32)
    assert compare.compare(ref, ref)["flip"] == pytest.approx(0.0, abs=1e-6)
    noisy = ref + rng.normal(0, 0.3, ref.shape).astype(np.float32)
    worse = ref + rng.normal(0, 0.6, ref.shape).astype(np.float32)
    a = compare.compare(noisy, ref, heatmap=tmp_path / "h.png")
    assert 0 < a["flip"] < compare.compare(worse, ref)["flip"]
    from PIL import Image

    assert Image.open(tmp_path / "h.png").size == (32, 32)


def test_write_outputs_png_beside_exr_and_no_exr(tmp_path):
    image = np.random.default_rng(5).random((6, 7, 3)).astype(np.float32)
    layers = {"albedo.R": image[..., 0], "depth.Z": image[..., 1]}
    paths = write_outputs(tmp_path / "a.png", image, {"x": 1}, layers=layers, exposure=1.0, tonemap="agx")
    assert set(paths) == {"exr", "png", "json"} and paths["exr"].endswith("a.exr")
    np.testing.assert_array_equal(read_exr(paths["exr"]), image)  # the EXR stays linear
    ch = read_exr_channels(paths["exr"])
    np.testing.assert_array_equal(ch["depth.Z"], image[..., 1])
    from PIL import Image

    png = np.asarray(Image.open(paths["png"]))
    np.testing.assert_array_equal(png, display.to_8bit(image, 1.0, "agx"))
    only = write_outputs(tmp_path / "b.png", image, {}, exr=False)
    assert "exr" not in only and not (tmp_path / "b.exr").exists()
    with pytest.raises(UserError, match="must be an .exr or a .png"):
        write_outputs(tmp_path / "c.tiff", image, {})
