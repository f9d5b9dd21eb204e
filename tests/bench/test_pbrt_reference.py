"""pbrt-v4 as the reference of pbrt scenes (pyopencl_rt/bench/pbrt_reference.py): the scene copy
at another resolution, the two-sided z-test, and (only where a pbrt binary is given in $PBRT_BIN)
a scene judged against pbrt's render."""
from __future__ import annotations

import os
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.bench.pbrt_reference import Render, judge, resized_text
from pyopencl_rt.bench.pbrt_scenes import judge_against_pbrt
from pyopencl_rt.errors import UserError

FEATURES = Path(__file__).resolve().parents[2] / "scenes" / "pbrt-features"


def test_resized_text_sets_the_film_resolution_outside_comments():
    text = ('# Film "rgb" "integer xresolution" [ 1500 ]\n'
            'Film "rgb" "string filename" "a # b.exr"\n'
            '    "integer yresolution" [ 700 ] # "integer xresolution" 9\n'
            '    "integer xresolution" 640\n'
            'WorldBegin\n')
    out = resized_text(text, 160, 120)
    assert out.splitlines() == [
        '# Film "rgb" "integer xresolution" [ 1500 ]',
        'Film "rgb" "integer xresolution" [ 160 ] "integer yresolution" [ 120 ] "string filename" "a # b.exr"',
        '     # "integer xresolution" 9',
        '    ',
        'WorldBegin']
    with pytest.raises(UserError, match="no Film directive"):
        resized_text('Include "camera.pbrt"\nWorldBegin\n', 16, 16)


def _render(image, variance, spp):
    return Render(np.asarray(image, np.float64), np.asarray(variance, np.float64), spp, 0.0)


def test_the_z_test_passes_noise_of_the_stated_variance_and_fails_a_bias():
    """Two renders of the same image, each with Gaussian noise of its stated variance of the mean,
    pass (at most 0.25% of channels beyond the Sidak bound, which noise exceeds with probability
    about 1% over the whole image); a 3% brighter one with the same noise fails, and its mean
    ratio says 1.03."""
    rng = np.random.default_rng(7)
    truth = rng.uniform(0.2, 1.0, (120, 160, 3))
    var_a, var_b = np.full_like(truth, 1e-4), np.full_like(truth, 4e-5)
    a = truth + rng.normal(0, np.sqrt(var_a))
    b = truth + rng.normal(0, np.sqrt(var_b))
    verdict = judge(_render(a, var_a, 64), _render(b, var_b, 1024))
    assert verdict.passed and verdict.accepted_fraction > 0.999 and abs(verdict.mean_ratio - 1) < 1e-3
    biased = judge(_render(1.03 * truth + rng.normal(0, np.sqrt(var_a)), var_a, 64), _render(b, var_b, 1024))
    assert not biased.passed and biased.mean_ratio == pytest.approx(1.03, abs=2e-3)
    with pytest.raises(UserError, match="differ in size"):
        judge(_render(a[:10], var_a[:10], 64), _render(b, var_b, 1024))


def test_a_pbrt_that_fails_is_a_row_not_a_crash(tmp_path):
    """A binary that is not pbrt (or fails) gives the row "pbrt-error" and its reason."""
    fake = tmp_path / "pbrt"
    fake.write_text("#!/bin/sh\necho 'Error: not really pbrt' >&2\nexit 3\n")
    fake.chmod(0o755)
    row = judge_against_pbrt({"scene": str(FEATURES / "diffuse.pbrt")}, fake, 16, 12, 4, 2, 60.0)
    assert row == {"verdict": "pbrt-error", "reason": "pbrt failed on diffuse.pbrt (exit status 3): "
                                                      "Error: not really pbrt"}
    assert not list(FEATURES.glob(f".diffuse.pbrt.pbrt-reference-{os.getpid()}.pbrt"))  # the resized copy is gone


@pytest.mark.stress
def test_a_diffuse_scene_agrees_with_pbrt():
    """Needs a pbrt-v4 binary in $PBRT_BIN (not part of this project; docs/BENCHMARKS.md says how
    one was built): our render of scenes/pbrt-features/diffuse.pbrt against pbrt's."""
    pbrt = os.environ.get("PBRT_BIN")
    if not pbrt:
        pytest.skip("PBRT_BIN is not set: no pbrt-v4 binary to compare with")
    row = judge_against_pbrt({"scene": str(FEATURES / "diffuse.pbrt")}, pbrt, 160, 120, 32, 8, 600.0)
    assert row["verdict"] == "pass" and abs(row["mean_ratio"] - 1) < 0.01, row
