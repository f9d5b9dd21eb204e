"""``pyopencl-rt bench scale`` (issue 35) on a tiny height field, ours only: the scene files it
writes (a binary PLY both renderers read, the XML), one child render measured from outside (wall
time, peak RSS from wait4) and the host stages from the sidecar.  Timings are not checked."""
import json
import math

import numpy as np

from pyopencl_rt.bench.scale_scene import grid_size, heightfield, write_scene
from pyopencl_rt.cli import main
from pyopencl_rt.scene.loaders import load_scene


def test_scale_scene_files(tmp_path):
    xml = write_scene(tmp_path, 2000, width=16, height=12, spp=2)
    k = grid_size(2000)
    assert xml.name == f"heightfield_{2 * k * k}.xml" and xml.with_suffix(".ply").exists()
    scene = load_scene(xml)
    v, f = heightfield(k)
    assert np.array_equal(scene.faces[: len(f)], f) and np.array_equal(scene.vertices[: len(v)], v)
    assert scene.normals is not None and scene.environment is not None  # computed normals, the constant env
    assert (scene.settings.width, scene.settings.height, scene.settings.spp) == (16, 12, 2)


def test_bench_scale_ours_only(tmp_path, capsys):
    out = tmp_path / "scale.json"
    main(["bench", "scale", "--sizes", "0.002", "--no-mitsuba", "--width", "8", "--height", "8", "--spp", "1",
          "--workdir", str(tmp_path / "work"), "--json", str(out)])
    data = json.loads(out.read_text())
    (row,) = data["sizes"]
    assert row["triangles"] == 2 * grid_size(2000) ** 2 and row["mitsuba"] == []
    (run,) = row["ours"]
    assert run["returncode"] == 0 and math.isfinite(run["seconds"]) and run["seconds"] > 0
    assert run["max_rss_mb"] > 10
    assert {"load", "mesh_read", "normals", "validation", "bvh", "kernel_build", "upload"} <= set(run["host_seconds"])
    assert "triangles" in capsys.readouterr().out


def test_baseline_runs_its_own_package(tmp_path, monkeypatch):
    """--baseline DIR renders with DIR's package even when the bench runs from a folder holding
    another one (``python -m`` puts the working folder before PYTHONPATH): a stub package there
    writes the sidecar the bench reads back."""
    from pathlib import Path

    import pyopencl_rt

    stub = tmp_path / "base" / "pyopencl_rt"
    stub.mkdir(parents=True)
    (stub / "__init__.py").write_text("")
    (stub / "cli.py").write_text(
        "import json, sys\n"
        "out = sys.argv[sys.argv.index('-o') + 1]\n"
        "open(out[:-4] + '.json', 'w').write(json.dumps({'host_seconds': {'stub': 1.0}}))\n")
    monkeypatch.chdir(Path(pyopencl_rt.__file__).parents[1])     # a folder holding our package
    out = tmp_path / "scale.json"
    main(["bench", "scale", "--sizes", "0.002", "--no-mitsuba", "--width", "8", "--height", "8", "--spp", "1",
          "--workdir", str(tmp_path / "work"), "--json", str(out), "--baseline", str(tmp_path / "base")])
    (row,) = json.loads(out.read_text())["sizes"]
    assert row["baseline"][0]["host_seconds"] == {"stub": 1.0}
    assert "bvh" in row["ours"][0]["host_seconds"]


def test_parse_millions():
    import pytest

    from pyopencl_rt.bench.scale import parse_millions
    from pyopencl_rt.errors import UserError

    assert parse_millions("0.5,2,8") == [0.5, 2.0, 8.0] and parse_millions("2", with_32m=True) == [2.0, 32.0]
    for bad in ("", "a,b", "0,1", "-2"):
        with pytest.raises(UserError):
            parse_millions(bad)


def test_textured_scene_for_the_benchmark_set(tmp_path, monkeypatch):
    """The set's generated scene (bench_set.GENERATED) has at least a million triangles; its
    textured variant, written small here, reads its texture coordinates through the binary PLY path
    (u, v over the grid), is flat-shaded, two-sided and textured, and exports to Mitsuba."""
    from pyopencl_rt.bench import bench_set
    from pyopencl_rt.bench.render import check_exportable
    from pyopencl_rt.render.settings import ImageSettings
    from pyopencl_rt.scene.mesh import PlyMesh, load_trimesh

    for name, spec in bench_set.GENERATED.items():
        assert 2 * grid_size(spec["triangles"]) ** 2 >= 1_000_000 and spec["textured"], name
    xml = write_scene(tmp_path, 2000, textured=True)
    k = grid_size(2000)
    ply = load_trimesh(tmp_path / f"heightfield_textured_{2 * k * k}.ply")
    assert isinstance(ply, PlyMesh)
    assert np.array_equal(ply.visual.uv, (ply.vertices[:, :2].astype(np.float64) + 1) / 2)
    scene = load_scene(xml)
    assert scene.has_textures() and not scene.has_shading_normals() and len(scene.faces) == 2 * k * k + 2
    check_exportable(str(xml), scene, ImageSettings.resolve(scene, width=8, height=8))
    monkeypatch.setenv("PYOPENCL_RT_CACHE", str(tmp_path / "cache"))
    monkeypatch.setattr(bench_set, "GENERATED", {"generated:small": dict(triangles=2000, textured=True)})
    path = bench_set.scene_path("generated:small")
    assert path.startswith(str(tmp_path / "cache")) and load_scene(path).has_textures()
    assert bench_set.scene_path("scenes/mitsuba-cbox.toml") == "scenes/mitsuba-cbox.toml"
