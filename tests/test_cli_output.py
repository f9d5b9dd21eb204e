"""The render command's outputs (PNG, EXR layers, display options, preview) and ``compare``,
run as a separate process like the rest of the CLI tests."""
import json

import numpy as np
from PIL import Image

from pyopencl_rt import display
from pyopencl_rt.imageio import read_exr, read_exr_channels
from test_cli import REPO, run_cli

SCENE = str(REPO / "scenes/cornell-box.toml")
SMALL = ("--width", "16", "--height", "12", "--spp", "2", "--max-depth", "3", "-q", "--device", "cpu")


def test_png_output_with_aov_layers_and_display_options(tmp_path):
    r = run_cli("render", SCENE, "-o", "out/a.png", "--aov", "albedo,depth,spp", "--tonemap", "filmic",
                "--exposure", "1", "--preview-every", "0.01", *SMALL, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = tmp_path / "out"
    channels = read_exr_channels(out / "a.exr")
    assert set(channels) == {"R", "G", "B", "albedo.R", "albedo.G", "albedo.B", "depth.Z", "spp.Y"}
    np.testing.assert_array_equal(channels["spp.Y"], 2)
    depth = channels["depth.Z"]
    assert np.isfinite(depth[6, 8]) and (depth > 0).all()  # +inf where the wide image misses the box
    info = json.loads((out / "a.json").read_text())
    assert info["aovs"] == ["albedo", "depth", "spp"] and info["film_aovs"] is True
    assert info["display"] == {"exposure": 1.0, "tonemap": "filmic"}
    # the PNG is the display transform of the EXR's linear beauty
    png = np.asarray(Image.open(out / "a.png"))
    np.testing.assert_array_equal(png, display.to_8bit(read_exr(out / "a.exr"), 1.0, "filmic"))


def test_no_exr_and_bad_output_options_are_one_line_errors(tmp_path):
    r = run_cli("render", SCENE, "-o", "b.png", "--no-exr", "--aov", "albedo", *SMALL, cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert (tmp_path / "b.png").exists() and not (tmp_path / "b.exr").exists()
    for args, message in ((("-o", "c.tif"), "must be an .exr or a .png"), (("--aov", "albedo,shadow"), "unknown AOV"),
                          (("-o", "d.exr", "--no-exr"), "--no-exr needs a .png")):
        r = run_cli("render", SCENE, *args, *SMALL, cwd=tmp_path)
        assert r.returncode != 0
        lines = r.stderr.strip().splitlines()
        assert len(lines) == 1 and lines[0].startswith("pyopencl-rt: error:") and message in lines[0], r.stderr


def test_compare_command(tmp_path):
    from pyopencl_rt.imageio import write_exr

    ref = np.full((8, 10, 3), 0.5, np.float32)
    write_exr(tmp_path / "ref.exr", ref)
    write_exr(tmp_path / "img.exr", ref * np.array([1.0, 1.0, 1.2], np.float32))
    r = run_cli("compare", "img.exr", "ref.exr", "--json", "--heatmap", "h.png", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    m = json.loads(r.stdout)
    np.testing.assert_allclose(m["mean_ratio"], [1.0, 1.0, 1.2], rtol=1e-6)
    assert abs(m["mse"] - 0.1**2 / 3) < 1e-8  # one channel of three off by 0.1
    assert (tmp_path / "h.png").exists()
    r = run_cli("compare", "img.exr", "missing.exr", cwd=tmp_path)
    assert r.returncode != 0 and "missing.exr: no such file" in r.stderr
