"""`bench convergence --denoise`: the denoised curve beside the raw one and where it stops helping."""
import numpy as np
import pytest

from pyopencl_rt import load_scene
from pyopencl_rt.bench import convergence as cv
from pyopencl_rt.bench.convergence_analysis import denoise_gain


def test_denoise_gain_finds_where_denoising_stops_helping():
    raw = [0.4, 0.2, 0.1, 0.05, 0.025]
    den = [0.04, 0.04, 0.05, 0.05, 0.03]  # a bias floor near 0.04: no gain from the 4th point on
    points = [{"spp": 1 << i, "relmse": d, "raw_relmse": r, "rmse": d, "raw_rmse": 2 * r}
              for i, (r, d) in enumerate(zip(raw, den))]
    g = denoise_gain(points)
    np.testing.assert_allclose(g["relmse_gain"], np.array(raw) / den)
    assert g["stops_helping_at_spp_relmse"] == 8 and g["stops_helping_at_spp_rmse"] is None and g["max_spp"] == 16


# 64x64, not smaller: at 24x24 the light is one or two pixels whose HDR radiance OIDN spreads over
# the ceiling pixels beside it (relMSE 0.78 denoised against 0.13 raw at 1 spp, with the light's
# albedo guide 0 and the ceiling's 0.72); at 64x64 the denoised 1-spp relMSE is 0.012 against 0.21.
def test_denoised_curve_has_raw_errors_beside_it(device):
    pytest.importorskip("pyoidn")
    scene = load_scene("scenes/cornell-box.toml")
    size = dict(width=64, height=64, max_depth=4, rr_depth=3, integrator="path", intersector="opencl")
    from pyopencl_rt.render.api import render_full

    reference = render_full(scene, spp=256, device=device, width=64, height=64, max_depth=4, seed=5).image
    curve = cv.run_curve(scene, device=device, reference=reference, seconds=1.0, denoise=True, **size)
    assert curve["denoised"] and curve["label"].endswith("+ OIDN")
    first = curve["points"][0]
    assert first["spp"] == 1 and first["relmse"] < first["raw_relmse"]  # at 1 spp the denoiser wins
    assert first["seconds"] >= first["denoise_seconds"] > 0
