"""``pyopencl-rt bench pbrt-scenes``: the verdicts, the features named, the scene listing."""
import json
import sys

import pytest

from pyopencl_rt.bench import pbrt_scenes as ps
from pyopencl_rt.cli import main

CAMERA = """LookAt 0 0 5  0 0 0  0 1 0
Camera "perspective" "float fov" 40
Film "rgb" "integer xresolution" 32 "integer yresolution" 24
WorldBegin
LightSource "infinite" "rgb L" [1 1 1]
"""


@pytest.fixture
def scenes(tmp_path):
    """Three scenes: one we render, one with a material we refuse, one whose Include is absent;
    and the geometry file the first includes (no WorldBegin: not a scene)."""
    (tmp_path / "geometry").mkdir()
    (tmp_path / "geometry" / "tri.pbrt").write_text(
        'Shape "trianglemesh" "point3 P" [-1 -1 0 1 -1 0 0 1 0] "integer indices" [0 1 2]\n')
    (tmp_path / "fine.pbrt").write_text(CAMERA + 'Material "diffuse"\nInclude "geometry/tri.pbrt"\n')
    (tmp_path / "refused.pbrt").write_text(CAMERA + 'Material "hair"\nInclude "geometry/tri.pbrt"\n')
    (tmp_path / "missing.pbrt").write_text(CAMERA + 'Include "geometry/not-here.pbrt"\n'
                                           'Material "measured"\nInclude "geometry/tri.pbrt"\n')
    return tmp_path


def test_three_verdicts(scenes, capsys):
    out = scenes / "results.json"
    main(["bench", "pbrt-scenes", str(scenes), "--width", "8", "--height", "6", "--spp", "1", "--json", str(out)])
    results = json.loads(out.read_text())
    rows = {r["scene"]: r for r in results["scenes"]}
    assert sorted(rows) == ["fine.pbrt", "missing.pbrt", "refused.pbrt"]  # geometry/tri.pbrt is no scene
    assert rows["fine.pbrt"]["status"] == "ok" and rows["fine.pbrt"]["defects"] == []
    assert rows["refused.pbrt"]["status"] == "refused" and rows["refused.pbrt"]["feature"] == 'Material "hair"'
    assert rows["refused.pbrt"]["reason"].startswith(f"{scenes / 'refused.pbrt'}:6: ")
    missing = rows["missing.pbrt"]
    assert missing["status"] == "missing" and "not-here.pbrt" in missing["reason"] and "\n" not in missing["reason"]
    # the probe skips the missing file and finds what the rest of the scene asks for
    probe = missing["probe"]
    assert probe["status"] == "refused" and probe["feature"] == 'Material "measured"'
    assert len(probe["skipped"]) == 1 and "not-here.pbrt" in probe["skipped"][0]
    for row in rows.values():
        assert row["seconds"] > 0 and row["peak_rss_mib"] > 10  # a Python process at least
    assert results["verdicts"] == {"ok": 1, "refused": 1, "missing": 1, "error": 0, "timeout": 0}
    assert results["features"] == {'Material "hair"': {"blocks": 1, "spoils": 0, "behind_missing": 0},
                                   'Material "measured"': {"blocks": 0, "spoils": 0, "behind_missing": 1}}
    table = capsys.readouterr().out
    assert "1 ok, 1 refused, 1 missing, 0 error, 0 timeout" in table


STDERR_TRACEBACK = """Traceback (most recent call last):
  File "x.py", line 1, in <module>
ZeroDivisionError: division by zero
"""


def test_classify():
    ok = ps.classify(0, "pyopencl-rt: warning: a.pbrt:3: Film sensor 'canon_eos_100d': rendered as cie1931\n"
                        "pyopencl-rt: warning: a.pbrt:4: Material \"dielectric\": glass-BK7 rendered without "
                        "dispersion, at its d-line index 1.5168\n")
    assert ok["status"] == "ok" and len(ok["defects"]) == 1 and "sensor" in ok["defects"][0]
    assert len(ok["warnings"]) == 1 and "dispersion" in ok["warnings"][0]
    assert ps.feature_of(ok["defects"][0]) == "Film sensor"
    crash = ps.classify(1, STDERR_TRACEBACK)
    assert crash["status"] == "error" and "ZeroDivisionError" in crash["reason"]
    # a traceback after our error line is still a crash
    assert ps.classify(1, "pyopencl-rt: error: x\n" + STDERR_TRACEBACK)["status"] == "error"
    assert ps.classify(-9, "")["status"] == "error" and "SIGKILL" in ps.classify(-9, "")["reason"]
    assert ps.classify(1, "Segmentation fault\n")["status"] == "error"
    assert ps.classify(1, "pyopencl-rt: error: the OpenCL device failed: out of resources\n")["status"] == "error"
    missing = ps.classify(1, "pyopencl-rt: error: s.pbrt:9: Shape \"plymesh\": file 'geometry/m.ply' not found "
                             "(looked for /x/geometry/m.ply)\n")
    assert missing["status"] == "missing" and missing["feature"] is None
    refused = ps.classify(1, 'pyopencl-rt: error: s.pbrt:9: g.pbrt:2: Shape "curve": shape type "curve" is not '
                             'supported\n')
    assert refused["status"] == "refused" and refused["feature"] == 'Shape "curve"'
    assert ps.classify(None, "", timed_out=True)["status"] == "timeout"


@pytest.mark.parametrize("message, feature", [
    ('material "leaf": material type "subsurface" is not supported', 'Material "subsurface"'),
    ('Material "measured": material type "measured" is not supported', 'Material "measured"'),
    ('"float whitebalance" of Film "rgb": not supported; ignored', '"float whitebalance" of Film "rgb"'),
    ('LightSource "goniometric": not supported; ignored', 'LightSource "goniometric"'),
    ('MakeNamedMedium "smoke": medium type "nanovdb" is not supported', 'Medium "nanovdb"'),
    ('Texture "t" "ptex": texture class "ptex" is not supported', 'Texture "ptex"'),
])
def test_feature_names(message, feature):
    assert ps.feature_of(f"a/b.pbrt:12: {message}") == feature


def test_timeout_kills_the_render(tmp_path):
    row = ps.run_scene(tmp_path / "x.pbrt", timeout=0.5, command=[sys.executable, "-c", "import time; time.sleep(30)"])
    assert row["status"] == "timeout" and row["seconds"] < 10


def test_listing(tmp_path):
    import gzip

    (tmp_path / "a").mkdir()
    (tmp_path / "a" / "s.pbrt").write_text("# WorldBegin in a comment only\nWorldBegin\n")
    (tmp_path / "a" / "geometry.pbrt").write_text('# WorldBegin\nShape "sphere"\n')  # included by scenes
    (tmp_path / "z.pbrt.gz").write_bytes(gzip.compress(b"WorldBegin\n"))
    (tmp_path / "notes.txt").write_text("WorldBegin\n")
    assert ps.list_scenes(tmp_path) == [tmp_path / "a" / "s.pbrt", tmp_path / "z.pbrt.gz"]
    with pytest.raises(ps.UserError, match="no pbrt-v4 scene"):
        ps.run_bench(tmp_path / "a", only=("nothing",), echo=lambda *_: None)


@pytest.mark.parametrize("message, feature", [
    ('material "saphire": displacement is not supported; ignored', "Material displacement"),
    ('material "m": "texture roughness": textures are not supported here; using the default',
     '"texture roughness" of Material'),
    ('Material "conductor": "texture roughness": textures are not supported here; using the default',
     '"texture roughness" of Material'),
    ("Integrator: regularize is not supported; ignored", "Integrator: regularize"),
    ("ActiveTransform StartTime: motion blur is not supported; ignored", "ActiveTransform StartTime: motion blur"),
    ("Film sensor 'canon_eos_100d': rendered as cie1931", "Film sensor"),
])
def test_feature_names_are_the_same_from_scene_to_scene(message, feature):
    """Keys without the names a scene gives its materials or values, so counts add up."""
    assert ps.feature_of(f"x.pbrt:3: {message}") == feature


@pytest.mark.parametrize("message, feature", [
    ('Texture "book31-proj": mapping "planar" read as "uv"', 'Texture mapping "planar"'),
    ('"vector3 v1" of Texture "book31-proj": not supported; ignored', '"vector3 v1" of Texture'),
    ('Texture "t": filter "ewa": we filter bilinearly (no mipmaps)', 'Texture filter "ewa"'),
])
def test_texture_features_without_the_texture_names(message, feature):
    assert ps.feature_of(f"m.pbrt:7: {message}") == feature
