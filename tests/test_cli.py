"""The ``pyopencl-rt`` command line, run as a separate process (``python -m pyopencl_rt.cli``)."""
import json
import re
import math
import os
import subprocess
import sys
from pathlib import Path

import pyopencl as cl
import pytest

from pyopencl_rt.device import devices as dv

REPO = Path(__file__).resolve().parents[1]


def run_cli(*args, cwd, timeout=300):
    env = dict(os.environ)
    env.pop("PYOPENCL_CTX", None)
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return subprocess.run(
        [sys.executable, "-m", "pyopencl_rt.cli", *args],
        cwd=cwd, env=env, capture_output=True, text=True, timeout=timeout,
    )


# These tests are about the PoCL CPU device (a dependency: pocl-binary-distribution, so always
# present) and the "cpu" spec that selects it: they run on it by design, not on the device fixture.
@pytest.fixture(scope="module")
def pocl_info():
    for e, info in zip(dv.all_devices(), dv.list_devices()):
        if "portable computing language" in info.platform.lower() and e[2].type & cl.device_type.CPU:
            return info
    pytest.fail("PoCL CPU device not found")


def without_memory(entry: dict) -> dict:
    """PoCL's memory sizes follow the system's free memory, which changes between processes."""
    return {k: v for k, v in entry.items() if k not in ("global_mem_bytes", "max_alloc_bytes")}


def test_devices_lists_pocl(tmp_path, pocl_info):
    r = run_cli("devices", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    out = r.stdout
    assert f"[{pocl_info.index}] {pocl_info.name}" in out
    block = out.split(f"[{pocl_info.index}] {pocl_info.name}", 1)[1].split("\n[", 1)[0]
    assert f"platform: {pocl_info.platform}" in block
    assert "type: CPU" in block
    assert f"compute units: {pocl_info.compute_units}" in block
    # PoCL reports a share of the memory free at the time, so it differs between processes
    assert re.search(r"memory: \d+\.\d GiB", block)
    assert pocl_info.opencl_version in block
    # one entry per device
    assert out.count("platform: ") == len(dv.all_devices())


def test_devices_json(tmp_path, pocl_info):
    r = run_cli("devices", "--json", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert isinstance(data, list) and len(data) == len(dv.all_devices())
    entry = next(d for d in data if d["index"] == pocl_info.index)
    assert without_memory(entry) == without_memory(pocl_info.as_dict())
    assert entry["type"] == "CPU"
    assert isinstance(entry["compute_units"], int) and entry["compute_units"] > 0
    assert isinstance(entry["global_mem_bytes"], int) and entry["global_mem_bytes"] > 0
    assert entry["opencl_version"].startswith("OpenCL ")


def test_devices_json_filtered_by_device(tmp_path, pocl_info):
    r = run_cli("devices", "--json", "--device", "cpu", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    data = json.loads(r.stdout)
    assert [without_memory(d) for d in data] == [without_memory(pocl_info.as_dict())]
    assert data[0]["global_mem_bytes"] > 0 and data[0]["max_alloc_bytes"] > 0


@pytest.mark.parametrize("command", [["devices"], ["bench", "rays", "--sizes", "1k", "--rays", "16"]],
                         ids=["devices", "bench-rays"])
def test_unknown_device_is_one_line_error(tmp_path, command, pocl_info):
    r = run_cli(*command, "--device", "nosuchdevice", cwd=tmp_path)
    assert r.returncode == 2
    lines = r.stderr.strip().splitlines()
    assert len(lines) == 1, r.stderr
    assert lines[0].startswith("pyopencl-rt: error:")
    assert "nosuchdevice" in lines[0]
    assert pocl_info.name in lines[0] and pocl_info.index in lines[0]
    assert "Traceback" not in r.stderr + r.stdout
    assert not list(tmp_path.iterdir())  # nothing was written


@pytest.mark.parametrize("command, expected", [
    ([], ["devices", "bench"]),
    (["devices"], ["--json", "--device"]),
    (["bench"], ["rays"]),
    (["bench", "rays"], ["--sizes", "--rays", "--repeat", "--json", "--device", "--no-embree"]),
], ids=["top", "devices", "bench", "bench-rays"])
def test_help(tmp_path, command, expected):
    r = run_cli(*command, "--help", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    assert "Usage:" in r.stdout
    for word in expected:
        assert word in r.stdout


def test_bench_rays_smoke(tmp_path, pocl_info):
    """Smoke test of the command on a tiny mesh: the JSON is complete (no timing asserts)."""
    out = tmp_path / "out.json"
    r = run_cli("bench", "rays", "--device", "cpu", "--sizes", "2k", "--rays", "4096", "--repeat", "1",
                "--json", str(out), cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    data = json.loads(out.read_text())
    label = dv.describe(next(e for e in dv.all_devices() if dv.describe(e).index == pocl_info.index)).label()
    assert data["devices"] == [label]
    assert data["repeat"] == 1
    (mesh,) = data["meshes"]
    assert 1500 <= mesh["triangles"] <= 2500
    assert mesh["bvh_build_seconds"] > 0
    assert [s["set"] for s in mesh["sets"]] == ["primary", "diffuse"]
    primary = mesh["sets"][0]
    assert primary["rays"] == 4096
    assert 0 < mesh["sets"][1]["rays"] <= 4096  # one diffuse ray per primary hit
    for s in mesh["sets"]:
        assert set(s["backends"]) == {label, "embree"}
        for b in s["backends"].values():
            assert math.isfinite(b["rays_per_second"]) and b["rays_per_second"] > 0
            assert b["rays_per_second"] == pytest.approx(s["rays"] / b["seconds_median"])
    assert f"wrote {out}" in r.stdout


def test_render_embree_profile_sidecar_has_host_stage_times(tmp_path):
    """--intersector embree --profile: the extend and shadow stages run on the host (no device
    event), so their times come from the host clock; the sidecar is written once, after they are
    merged, and must hold them (positive: Embree did trace rays) beside the device stages."""
    out = tmp_path / "cbox.exr"
    r = run_cli("render", str(REPO / "scenes" / "cornell-box.toml"), "-o", str(out), "--spp", "2", "--width", "24",
                "--height", "16", "--intersector", "embree", "--profile", "--quiet", "--device", "cpu", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    info = json.loads(out.with_suffix(".json").read_text())
    stages = info["stage_seconds"]
    assert set(stages) == {"generate", "extend", "shade", "shadow", "accumulate"}
    assert stages["extend"] > 0 and stages["shadow"] > 0 and stages["shade"] > 0
    assert info["intersector"] == "embree"
    assert info["spp"] == 2 and info["width"] == 24 and info["height"] == 16
    # what the terminal shows is what the sidecar holds
    shown = {m.group(1): float(m.group(2)) for m in re.finditer(r"^(\w+)\s+([0-9.]+)\s+[0-9.]+%$", r.stderr, re.M)}
    assert set(shown) == set(stages)
    assert f"lanes: {info['lanes_reason']}" in r.stderr and info["lanes"] == 0  # the wavefront: one path
    for name, seconds in shown.items():
        assert abs(seconds - stages[name]) < 1e-3 + 1e-3 * seconds


def test_render_adaptive_sidecar_and_spp_layer(tmp_path):
    """--adaptive --target-error: the sidecar records both settings and the per-pixel spp (which
    varies), the EXR's spp layer holds the counts, and the summary line gives the mean."""
    from pyopencl_rt.imageio import read_exr_channels

    out = tmp_path / "a.exr"
    r = run_cli("render", str(REPO / "scenes" / "mitsuba-cbox.toml"), "-o", str(out), "--spp", "128", "--width", "16",
                "--height", "12", "--adaptive", "--target-error", "0.05", "--aov", "spp", "--quiet", "--device", "cpu",
                cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    info = json.loads(out.with_suffix(".json").read_text())
    assert info["adaptive"] is True and info["target_error"] == 0.05 and info["spp"] == 128
    record = info["adaptive_sampling"]
    assert 32 <= record["spp_min"] < record["spp_mean"] < record["spp_max"] == 128
    spp = read_exr_channels(out)["spp.Y"]
    assert spp.shape == (12, 16) and spp.min() == record["spp_min"] and spp.mean() == pytest.approx(record["spp_mean"])
    assert info["samples"] == int(spp.sum())
    assert f"{record['spp_mean']:.1f} spp per pixel on average" in r.stdout


def test_progress_bar_of_an_adaptive_render_counts_samples(tmp_path):
    """The bar of an adaptive render shows the mean spp and the samples/s actually taken (the
    passes reach far beyond --spp for the pixels refined most; passes x pixels overstated the
    rate 8x), so its last figure agrees with the summary line's."""
    out = tmp_path / "a.exr"
    r = run_cli("render", str(REPO / "scenes" / "mitsuba-cbox.toml"), "-o", str(out), "--spp", "64", "--width", "32",
                "--height", "32", "--adaptive", "--device", "cpu", cwd=tmp_path)
    assert r.returncode == 0, r.stderr
    last = r.stderr.replace("\r", "\n").strip().splitlines()[-1]
    shown, total = (int(v) for v in re.search(r"(\d+)/(\d+) spp", last).groups())
    bar_rate = float(re.search(r"([\d.]+) Msamples/s", last).group(1))
    summary_rate = float(re.search(r"\(([\d.]+) Msamples/s\)", r.stdout).group(1))
    assert shown == total == 64
    assert bar_rate == pytest.approx(summary_rate, rel=0.3)
