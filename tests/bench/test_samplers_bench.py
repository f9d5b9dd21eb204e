"""``pyopencl-rt bench samplers``: relMSE per sampler at equal spp against one reference, ours and
(where this interpreter has Mitsuba 3) Mitsuba's scalar_rgb, on a 16 x 16 Cornell box."""
import json
import sys
from pathlib import Path

import pytest

from pyopencl_rt.cli import main

REPO = Path(__file__).resolve().parents[2]
CORNELL = str(REPO / "scenes" / "mitsuba-cbox.toml")


def test_bench_samplers_end_to_end(tmp_path, monkeypatch, device_spec):
    """Rows of ours and of Mitsuba against Mitsuba's reference: every relMSE above the reference's
    own noise (each figure contains it) and far below that of an image of zeros (about 1); Sobol's
    below independent's at 16 spp (about 2x apart here, more than the spread between seeds)."""
    pytest.importorskip("mitsuba")
    monkeypatch.setenv("PYOPENCL_RT_MITSUBA_PYTHON", sys.executable)
    out = tmp_path / "samplers.json"
    main(["bench", "samplers", CORNELL, "--device", device_spec, "--width", "16", "--height", "16", "--spp", "16",
          "--seeds", "1", "--sampler", "sobol,independent", "--reference-spp", "1024", "--compare", "mitsuba",
          "--mitsuba-variant", "scalar_rgb", "--mitsuba-sampler", "multijitter", "--json", str(out),
          "--save-reference", str(tmp_path / "ref.exr")])
    data = json.loads(out.read_text())
    assert data["reference"]["renderer"] == "mitsuba" and data["reference"]["spp"] == 1024
    floor = data["reference"]["floor"]["relmse"]
    rows = {(r["renderer"].split()[0], r["sampler"]): r for r in data["rows"]}
    assert set(rows) == {("pyopencl_rt", "sobol"), ("pyopencl_rt", "independent"), ("mitsuba", "multijitter")}
    for row in rows.values():
        assert len(row["runs"]) == 1 and floor < row["relmse"] < 0.2, row
    assert rows["pyopencl_rt", "sobol"]["relmse"] < rows["pyopencl_rt", "independent"]["relmse"]
    from pyopencl_rt.imageio import read_exr

    assert read_exr(tmp_path / "ref.exr").shape == (16, 16, 3)  # for bench convergence --reference
