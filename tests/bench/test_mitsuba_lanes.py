"""Mitsuba's LLVM vector width for the benchmarks (``--mitsuba-lanes``, ``$PYOPENCL_RT_MITSUBA_LANES``;
pyopencl_rt/bench/mitsuba_runner.py): the runner compiles Mitsuba's kernels for the width asked,
and reports it; the width changes how fast Mitsuba renders, not what: the same seed gives the
same image but for the rounding of reordered arithmetic.

Tolerance: the two images' means agree to 1e-4 relative, and no pixel differs by more than 1e-3
of the image's mean (measured on the Cornell box at 16 x 16, 4 spp, widths 4, 8 and AVX2 against
16: at most 4e-8 and 2.4e-6).  A width that was not applied shows as the reported width; a runner
that rendered something else (another seed, another scene) differs by percents.  Needs an llvm_*
variant that runs: skipped where Mitsuba or its libLLVM is missing (``find_mitsuba_python`` says
which).
"""
import json
import subprocess

import numpy as np
import pytest

from pyopencl_rt import load_scene
from pyopencl_rt.bench import mitsuba_host
from pyopencl_rt.bench.mitsuba_export import save_scene_npz, scene_arrays
from pyopencl_rt.bench.mitsuba_runner import LANES_ENV, set_llvm_lanes
from pyopencl_rt.render.settings import ImageSettings


def test_unknown_width_is_one_line(monkeypatch):
    monkeypatch.setenv(LANES_ENV, "12")
    with pytest.raises(SystemExit, match=r"PYOPENCL_RT_MITSUBA_LANES=12: use one of 4, 8, 16, avx2"):
        set_llvm_lanes(None, "llvm_ad_rgb")
    assert set_llvm_lanes(None, "scalar_rgb") == (None, None)  # no LLVM, nothing to set


def render(python, tmp_path, name, lanes):
    out = tmp_path / name
    env = mitsuba_host.mitsuba_env()
    env.pop(LANES_ENV, None)
    if lanes:
        env[LANES_ENV] = lanes
    subprocess.run([python, str(mitsuba_host.HERE / "mitsuba_runner.py"), str(tmp_path / "scene.npz"), str(out),
                    "--checkpoints", "4", "--variant", "llvm_ad_rgb"],
                   check=True, capture_output=True, env=env, timeout=300)
    info = json.loads((out / "mitsuba.json").read_text())
    return info, np.load(out / "mitsuba_4.npy").astype(np.float64)


def test_runner_renders_at_the_width_asked(tmp_path):
    python, why = mitsuba_host.find_mitsuba_python(variant="llvm_ad_rgb")
    if python is None:
        pytest.skip(f"no llvm_ad_rgb: {why}")
    scene = load_scene("scenes/mitsuba-cbox.toml")
    save_scene_npz(tmp_path / "scene.npz", scene_arrays(scene, ImageSettings.resolve(scene, width=16, height=16)))
    wide, image = render(python, tmp_path, "host", None)
    avx2, image_avx2 = render(python, tmp_path, "avx2", "avx2")
    assert (avx2["lanes"], avx2["target_cpu"]) == (8, "haswell")
    assert wide["lanes"] in (4, 8, 16) and wide["target_cpu"]
    mean = image.mean()
    assert mean > 0.05  # the box, lit
    assert abs(image_avx2.mean() - mean) <= 1e-4 * mean
    assert np.abs(image_avx2 - image).max() <= 1e-3 * mean
