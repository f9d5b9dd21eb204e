"""The benchmark subcommands on tiny inputs (a few seconds each): the numbers they report are
consistent with what they measure, and a missing Mitsuba or libLLVM is one clear line."""
import json
import math
import os
import stat

import pytest

from pyopencl_rt.bench import mitsuba_host
from pyopencl_rt.cli import main

CORNELL = "scenes/cornell-box.toml"


def finite_positive(x):
    return isinstance(x, (int, float)) and math.isfinite(x) and x > 0


def test_bench_bvh_binned_against_sweep(tmp_path, capsys):
    """Every kind at 2k triangles, swept too: the binned/sweep SAH ratio is within the 10% quality
    target.  The full sweep is greedy (best split per node), not the optimal tree, so a binned
    build may come out a little cheaper: the lower bound only rules out a broken cost (a ratio
    far below 1 would mean the two are not measuring the same thing)."""
    out = tmp_path / "bvh.json"
    main(["bench", "bvh", "--sizes", "2k", "--sweep-size", "2000", "--repeat", "1", "--check", "--json", str(out)])
    data = json.loads(out.read_text())
    rows = data["results"]
    assert [r["kind"] for r in rows] == ["sphere", "torus", "soup", "slivers"]
    for row in rows:
        assert row["size"] == 2000 and 1000 <= row["triangles"] <= 2000
        binned, sweep = row["binned"], row["sweep"]
        assert finite_positive(binned["build_seconds"]) and finite_positive(sweep["build_seconds"])
        assert row["sah_ratio"] == pytest.approx(binned["sah_cost"] / sweep["sah_cost"])
        assert 0.9 < row["sah_ratio"] < 1.10, row
        assert sum(binned["leaf_size_histogram"].values()) > 0
    assert f"wrote {out}" in capsys.readouterr().out


def test_bench_bvh_without_sweep_and_unknown_kind(tmp_path, capsys):
    out = tmp_path / "bvh.json"
    main(["bench", "bvh", "--sizes", "1k", "--kinds", "soup", "--sweep-size", "0", "--repeat", "1", "--json", str(out)])
    (row,) = json.loads(out.read_text())["results"]
    assert row["triangles"] == 1000 and "sweep" not in row and "sah_ratio" not in row
    with pytest.raises(SystemExit) as exc:
        main(["bench", "bvh", "--kinds", "soup,cube"])
    assert exc.value.code != 0
    assert "unknown mesh kind 'cube'" in capsys.readouterr().err


def test_bench_materials_tiny(tmp_path, own_features):
    """The texture pair at 16x16, 1 spp (each pair is two kernel builds of its own): only the pair
    asked for is run, the ratio is the ratio of the medians, and variant b is compiled without
    textures (else it would time the same kernel twice)."""
    out = tmp_path / "materials.json"
    main(["bench", "materials", "--device", "cpu", "--pairs", "textures", "--width", "16", "--height", "16",
          "--spp", "1", "--repeat", "1", "--json", str(out)])
    data = json.loads(out.read_text())
    assert "rough_vs_smooth" not in data and "gltf_vs_diffuse" not in data
    pair = data["textured_vs_untextured"]
    assert finite_positive(pair["a_samples_per_second"]) and finite_positive(pair["b_samples_per_second"])
    assert pair["a_over_b"] == pytest.approx(pair["a_samples_per_second"] / pair["b_samples_per_second"])
    assert len(pair["a_all"]) == len(pair["b_all"]) == 1
    assert any("HAS_TEXTURES" in f for f in pair["features_a"])
    assert not any("HAS_TEXTURES" in f for f in pair["features_b"])


def test_bench_render_with_both_intersectors(tmp_path):
    """--intersector opencl,embree: one row per intersector, labelled and recorded as such; the
    two trace the same paths (same seed), so their rays per sample agree closely."""
    out = tmp_path / "render.json"
    main(["bench", "render", CORNELL, "--device", "cpu", "--width", "16", "--height", "16", "--spp", "2",
          "--repeat", "1", "--intersector", "opencl,embree", "--json", str(out)])
    rows = json.loads(out.read_text())["devices"]
    assert len(rows) == 2
    by_intersector = {row["intersector"]: (label, row) for label, row in rows.items()}
    assert set(by_intersector) == {"opencl", "embree"}
    for name, (label, row) in by_intersector.items():
        assert label.startswith(f"{name}: ")
        assert finite_positive(row["samples_per_second_median"]) and finite_positive(row["rays_per_sample"])
    rays = [row["rays_per_sample"] for _label, row in by_intersector.values()]
    assert rays[0] == pytest.approx(rays[1], rel=0.05)


def test_bench_render_unknown_intersector(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", "render", CORNELL, "--intersector", "opencl,optix"])
    assert exc.value.code != 0
    assert capsys.readouterr().err.strip().splitlines() == [
        "pyopencl-rt: error: unknown intersector 'optix': use one or more of opencl, embree"]


# -- Mitsuba and libLLVM discovery: nothing is guessed, and what is missing is said in one line -------

def fake_python(path, output, status):
    """An 'interpreter' that prints ``output`` and exits with ``status`` whatever it is asked."""
    path.write_text(f"#!/bin/sh\ncat <<'EOF'\n{output}\nEOF\nexit {status}\n")
    path.chmod(path.stat().st_mode | stat.S_IXUSR)
    return str(path)


def test_mitsuba_cornell_box_without_mitsuba(tmp_path, monkeypatch, capsys):
    monkeypatch.setenv("PYOPENCL_RT_MITSUBA_PYTHON", str(tmp_path / "no-such-python"))
    with pytest.raises(SystemExit) as exc:
        main(["bench", "mitsuba-cornell-box"])
    assert exc.value.code == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("pyopencl-rt: error: Mitsuba 3 not found: $PYOPENCL_RT_MITSUBA_PYTHON=")
    assert "no such file" in line and "--mitsuba-python" in line


def test_named_interpreter_is_not_replaced(tmp_path, monkeypatch):
    """--mitsuba-python wins over $PYOPENCL_RT_MITSUBA_PYTHON, and one that cannot import mitsuba
    is reported as such, not silently swapped for another interpreter."""
    no_mitsuba = fake_python(tmp_path / "python", "ModuleNotFoundError: No module named 'mitsuba'", 3)
    monkeypatch.setenv("PYOPENCL_RT_MITSUBA_PYTHON", str(tmp_path / "elsewhere"))
    python, why = mitsuba_host.find_mitsuba_python(no_mitsuba, "scalar_rgb")
    assert python is None
    assert why.startswith(f"Mitsuba 3 not found: --mitsuba-python={no_mitsuba} cannot import mitsuba")


def test_missing_or_unusable_libllvm(tmp_path, monkeypatch):
    ok = fake_python(tmp_path / "python", "3.9.1", 0)
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH", raising=False)
    assert mitsuba_host.find_mitsuba_python(ok, "llvm_ad_rgb") == (ok, "--mitsuba-python, Mitsuba 3.9.1")
    # a named libLLVM that is not there: said before anything runs, naming where it came from
    python, why = mitsuba_host.find_mitsuba_python(ok, "llvm_ad_rgb", llvm_path=str(tmp_path / "libLLVM.so"))
    assert python is None and f"--llvm-path={tmp_path / 'libLLVM.so'} is no such file" in why
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", str(tmp_path / "gone.so"))
    python, why = mitsuba_host.find_mitsuba_python(ok, "llvm_ad_rgb")
    assert python is None and "$DRJIT_LIBLLVM_PATH=" in why and "no such file" in why
    assert mitsuba_host.find_mitsuba_python(ok, "scalar_rgb")[0] == ok  # no LLVM needed
    # an LLVM too old for Dr.Jit's kernels aborts the process: the LLVM line and the fix, no addresses
    llvm_abort = "LLVM ERROR: Cannot select: 0x55d0: f32 = fminimum 0x55d1, 0x55d2\nIn function: drjit_1"
    old_llvm = fake_python(tmp_path / "python-old-llvm", llvm_abort, 134)
    monkeypatch.delenv("DRJIT_LIBLLVM_PATH")
    python, why = mitsuba_host.find_mitsuba_python(old_llvm, "llvm_ad_rgb")
    assert python is None
    assert "Cannot select: f32 = fminimum" in why and "0x" not in why
    assert "--llvm-path" in why and "DRJIT_LIBLLVM_PATH" in why and "\n" not in why


def test_llvm_path_reaches_the_mitsuba_process(tmp_path, monkeypatch):
    monkeypatch.setenv("DRJIT_LIBLLVM_PATH", "/from/the/environment.so")
    assert mitsuba_host.mitsuba_env()["DRJIT_LIBLLVM_PATH"] == "/from/the/environment.so"
    assert mitsuba_host.mitsuba_env("/given.so")["DRJIT_LIBLLVM_PATH"] == "/given.so"
    assert os.environ["DRJIT_LIBLLVM_PATH"] == "/from/the/environment.so"  # ours is left alone


def test_mitsuba_export_loads_without_the_package():
    """mitsuba_runner.py loads mitsuba_export.py by file path in Mitsuba's interpreter, where
    pyopencl_rt may not import: the module must not import the package at load time."""
    import importlib.util

    path = mitsuba_host.HERE / "mitsuba_export.py"
    spec = importlib.util.spec_from_file_location("standalone_mitsuba_export", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert callable(module.dict_from_arrays) and callable(module.load_scene_npz)


# -- bench render --mitsuba: Mitsuba takes its turn in every round -------------------------------------

def test_interleaved_rates_call_other_renderers_in_every_round(monkeypatch):
    """Each round renders every variant, then every other renderer, after the variants' untimed
    warm-ups, with the pause before each timed render."""
    from types import SimpleNamespace

    from pyopencl_rt.bench import timing
    from pyopencl_rt.render import api

    log = []

    def fake_render_full(scene, spp, wavefront, profile=False):
        log.append((wavefront, spp))
        return SimpleNamespace(info={"samples_per_second": 10.0 * len(log)})

    monkeypatch.setattr(api, "render_full", fake_render_full)
    monkeypatch.setattr(timing.time, "sleep", lambda s: log.append(("sleep", s)))

    def other(spp):
        log.append(("other", spp))
        return 7.0

    rates, _info = timing.interleaved_render_rates({"a": (None, "A"), "b": (None, "B")}, 4, 2,
                                                   others={"other": other}, pause=0.5)
    round_ = [("sleep", 0.5), ("A", 4), ("sleep", 0.5), ("B", 4), ("sleep", 0.5), ("other", 4)]
    assert log == [("A", 1), ("B", 1)] + round_ + round_
    assert rates == {"a": [40.0, 100.0], "b": [60.0, 120.0], "other": [7.0, 7.0]}


def test_bench_render_with_mitsuba_takes_turns(tmp_path, monkeypatch):
    """--mitsuba: Mitsuba renders the same scene (our export, at our size) once per repetition (its
    warm-up apart), its rates are what its timings say, and each row's per-round ratio is ours over
    Mitsuba's of that round."""
    pytest.importorskip("mitsuba")
    from pyopencl_rt.bench import render

    monkeypatch.setattr(render, "MITSUBA_PAUSE", 0.0)  # the round order is tested above
    out = tmp_path / "render.json"
    main(["bench", "render", CORNELL, "--device", "cpu", "--width", "16", "--height", "16", "--spp", "1",
          "--repeat", "3", "--mitsuba", "--mitsuba-variant", "scalar_rgb", "--json", str(out)])
    data = json.loads(out.read_text())
    theirs = data["mitsuba"]
    assert theirs["variant"] == "scalar_rgb" and len(theirs["renders"]) == 3
    assert (theirs["width"], theirs["height"], theirs["max_depth"]) == (16, 16, 8)
    pixels = theirs["width"] * theirs["height"]
    for render, rate in zip(theirs["renders"], theirs["samples_per_second_all"]):
        assert render["spp"] == 1 and rate == pytest.approx(pixels / render["seconds"])
    (row,) = data["devices"].values()
    ours = row["samples_per_second_all"]
    assert row["ratio_to_mitsuba_per_round"] == pytest.approx([a / b for a, b in zip(ours, theirs["samples_per_second_all"])])
    assert row["ratio_to_mitsuba"] == pytest.approx(row["samples_per_second_median"] / theirs["samples_per_second_median"])
    (summary,) = data["summary"]
    assert summary["ratio_to_mitsuba"] == pytest.approx(row["ratio_to_mitsuba_per_round_median"])


def test_bench_render_several_scenes_with_mitsuba(tmp_path, monkeypatch, capsys):
    """Two scenes in one run, each with its own Mitsuba process rendering that scene: a result per
    scene with its rows' ratios, and the summary table, a row per scene."""
    pytest.importorskip("mitsuba")
    from pyopencl_rt.bench import render

    monkeypatch.setattr(render, "MITSUBA_PAUSE", 0.0)
    out = tmp_path / "render.json"
    scenes = ["scenes/mitsuba-cbox.toml", "scenes/textured-sky.toml"]
    main(["bench", "render", *scenes, "--device", "cpu", "--width", "8", "--height", "8", "--spp", "1",
          "--repeat", "2", "--mitsuba", "--mitsuba-variant", "scalar_rgb", "--json", str(out)])
    data = json.loads(out.read_text())
    assert [result["scene"] for result in data["scenes"]] == scenes
    for result in data["scenes"]:
        assert len(result["mitsuba"]["renders"]) == 2 and result["mitsuba"]["width"] == 8
        (row,) = result["devices"].values()
        assert len(row["ratio_to_mitsuba_per_round"]) == 2 and finite_positive(row["ratio_to_mitsuba"])
        # the width the rule gives this device (0: one path per work-item), and why
        assert row["lanes"] in (0, 8, 16)
        assert row["lanes_reason"].startswith(f"{row['lanes']} lanes" if row["lanes"] else "one path")
    assert [row["scene"] for row in data["summary"]] == scenes
    for row, result in zip(data["summary"], data["scenes"]):
        (ours,) = result["devices"].values()
        assert row["samples_per_second"] == ours["samples_per_second_median"]
        assert row["mitsuba_samples_per_second"] == result["mitsuba"]["samples_per_second_median"]
        assert row["ratio_to_mitsuba"] == ours["ratio_to_mitsuba_per_round_median"]
        assert row["lanes"] == (ours["lanes"] or 1)
    table = capsys.readouterr().out.splitlines()
    header = next(i for i, line in enumerate(table) if line.startswith("scene "))
    assert [line.split()[0] for line in table[header + 1:header + 3]] == scenes


def test_bench_render_refuses_a_scene_mitsuba_cannot_render(capsys):
    """--mitsuba with a scene the export refuses (glTF materials): one line before any timing."""
    with pytest.raises(SystemExit) as exc:
        main(["bench", "render", "scenes/mitsuba-cbox.toml", "scenes/textured.toml", "--mitsuba"])
    assert exc.value.code == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("pyopencl-rt: error: scenes/textured.toml: Mitsuba cannot render the same scene")


def test_bench_render_mitsuba_that_fails_is_one_line(tmp_path, capsys):
    """A Mitsuba interpreter that passes the probe but whose render server dies: one line, exit 1."""
    script = tmp_path / "python"
    script.write_text("#!/bin/sh\ncase \"$1\" in\n  *mitsuba_runner.py) echo 'RuntimeError: out of luck' >&2; exit 5;;\n"
                      "esac\necho 3.9.1\nexit 0\n")
    script.chmod(script.stat().st_mode | stat.S_IXUSR)
    with pytest.raises(SystemExit) as exc:
        main(["bench", "render", CORNELL, "--device", "cpu", "--width", "8", "--height", "8", "--spp", "1",
              "--repeat", "1", "--mitsuba", "--mitsuba-variant", "scalar_rgb", "--mitsuba-python", str(script)])
    assert exc.value.code == 1
    (line,) = capsys.readouterr().err.strip().splitlines()
    assert line.startswith("pyopencl-rt: error: Mitsuba (scalar_rgb) failed") and "out of luck" in line


# -- bench set: the scenes against Mitsuba, samples/s and time to relMSE 1e-3 -------------------------

def test_bench_set_best_mitsuba_sampler_and_rows():
    """Mitsuba's best sampler is the one that reached the target soonest (a measured time before
    any extrapolated one); each row joins the render bench's summary with its scene's times, and
    the time ratio from each curve's spp to the target and the ratio of samples/s in turns.  The
    curves are exact, relMSE = c / N, so each time is c / 1e-3 spp times the seconds per spp; a
    curve of two seeds is estimated on their mean, with a standard error and the seeds' range."""
    from pyopencl_rt.bench.bench_set import convergence_summary, set_rows
    from pyopencl_rt.bench.convergence_analysis import spp_schedule

    def points(c, per_spp, max_spp):
        return [{"spp": n, "seconds": n * per_spp, "relmse": c / n, "samples_per_second": 10 / per_spp}
                for n in spp_schedule(max_spp)]

    def curve(renderer, sampler, c, per_spp=0.01, max_spp=1024, seeds=None):
        out = {"label": f"{renderer} {sampler}", "renderer": renderer, "sampler": sampler,
               "points": points(c, per_spp, max_spp) if c else []}
        if seeds:
            out["seed_curves"] = [{"seed": k, "points": points(ck, per_spp, max_spp)} for k, ck in enumerate(seeds)]
        return out

    # a reference floor small enough to change none of the times (its part: tests/bench/test_seed_estimate.py)
    result = {"scene": "s.toml", "width": 2, "height": 5, "reference": {"spp": 64, "floor": {"relmse": 1e-9}},
              "curves": [curve("pyopencl_rt", "sobol", 0.3), curve("mitsuba", "independent", 0.5),
                         curve("mitsuba", "multijitter", 0.2, per_spp=0.02),
                         curve("mitsuba", "ldsampler", 0.05, max_spp=16),  # 50 spp, beyond its 16: extrapolated
                         curve("mitsuba", "stratified", 0.09, per_spp=0.05), curve("mitsuba", "orthogonal", None)]}
    summary = convergence_summary(result, "s.json")
    assert summary["ours"]["sampler"] == "sobol" and summary["mitsuba_best"]["sampler"] == "multijitter"
    assert summary["ours"]["spp_to_target"] == pytest.approx(300, rel=1e-3)
    assert summary["mitsuba_best"]["spp_to_target"] == pytest.approx(200, rel=1e-3)
    assert summary["mitsuba_fewest_spp"]["sampler"] == "stratified"  # 90 spp; ldsampler's 50 are extrapolated
    assert summary["ours"]["seeds"] == 1 and summary["ours"]["time_to_target_se"] is None
    ld = next(c for c in summary["curves"] if c["sampler"] == "ldsampler")
    assert ld["extrapolated"] and ld["spp_to_target"] == pytest.approx(50, rel=1e-3)
    summary_only_guesses = convergence_summary({**result, "curves": result["curves"][:1] + [
        curve("mitsuba", "independent", 9.0, max_spp=64), curve("mitsuba", "stratified", 7.0, max_spp=64)]}, "s.json")
    assert summary_only_guesses["mitsuba_best"]["sampler"] == "stratified"
    render_row = {"scene": "s.toml", "variant": "cpu", "samples_per_second": 2e6, "mitsuba_samples_per_second": 1e6,
                  "ratio_to_mitsuba": 2.1, "lanes": 8, "lanes_reason": "8 lanes"}
    (row,) = set_rows([render_row], [summary])
    assert row["ratio_to_mitsuba"] == 2.1 and row["lanes"] == 8
    assert (row["time_to_target"], row["mitsuba_time_to_target"]) == (pytest.approx(3.0, rel=1e-3),
                                                                      pytest.approx(4.0, rel=1e-3))
    assert row["mitsuba_best_sampler"] == "multijitter" and row["mitsuba_time_over_ours"] == pytest.approx(4 / 3)
    # in turns: the sampler that needed fewest spp (stratified, 90) against our 300, times our 2.1x speed
    assert row["mitsuba_fewest_spp_sampler"] == "stratified"
    assert row["mitsuba_time_over_ours_interleaved"] == pytest.approx(90 / 300 * 2.1, rel=1e-3)
    assert row["mitsuba_time_over_ours_se"] is None  # one seed: no spread to tell
    # seeds: ours from two seeds of c 0.2 and 0.4 (mean 0.3), Mitsuba's multijitter from 0.1 and 0.3
    seeded = {**result, "seeds": 2, "curves": [curve("pyopencl_rt", "sobol", 0.3, seeds=[0.2, 0.4]),
                                               curve("mitsuba", "multijitter", 0.2, per_spp=0.02, seeds=[0.1, 0.3])]}
    summary = convergence_summary(seeded, "s.json")
    ours = summary["ours"]
    assert ours["seeds"] == 2 and ours["spp_to_target"] == pytest.approx(300, rel=1e-3)
    assert ours["spp_to_target_range"] == [pytest.approx(200, rel=1e-3), pytest.approx(400, rel=1e-3)]
    assert ours["relmse_x_spp_per_seed"] == [pytest.approx(0.2, rel=1e-3), pytest.approx(0.4, rel=1e-3)]
    assert 0 < ours["spp_to_target_se"] < 200 and ours["time_to_target_se"] == pytest.approx(ours["spp_to_target_se"]
                                                                                             * 0.01, rel=1e-6)
    (row,) = set_rows([render_row], [summary])
    assert row["seeds"] == 2 and row["mitsuba_time_over_ours"] == pytest.approx(4 / 3, rel=1e-3)
    theirs = summary["mitsuba_best"]
    assert row["mitsuba_time_over_ours_se"] == pytest.approx(4 / 3 * math.hypot(
        theirs["time_to_target_se"] / 4.0, ours["time_to_target_se"] / 3.0), rel=1e-3)
    assert row["mitsuba_time_over_ours_interleaved_se"] > 0


def test_bench_set_end_to_end(tmp_path, monkeypatch, capsys):
    """One tiny scene through the whole set (Mitsuba's scalar variant, two of its samplers, two
    seeds): the row has our and Mitsuba's samples/s, the ratio, the lanes and the times, and the
    scene's convergence JSON is written beside the set's, with each seed's curve."""
    pytest.importorskip("mitsuba")
    from pyopencl_rt.bench import render

    monkeypatch.setattr(render, "MITSUBA_PAUSE", 0.0)
    monkeypatch.setenv("PYOPENCL_RT_CACHE", str(tmp_path / "cache"))
    out = tmp_path / "set.json"
    main(["bench", "set", "scenes/mitsuba-cbox.toml", "--device", "cpu", "--size", "8", "--spp", "1", "--repeat", "2",
          "--error-size", "8", "--budget", "1", "--reference-spp", "64", "--mitsuba-sampler", "independent,stratified",
          "--seeds", "2", "--mitsuba-variant", "scalar_rgb", "--json", str(out)])
    data = json.loads(out.read_text())
    assert data["schema"] == "pyopencl_rt.bench_set/1" and data["target_relmse"] == 1e-3
    (row,) = data["rows"]
    assert row["scene"] == "scenes/mitsuba-cbox.toml" and row["lanes"] >= 1
    assert finite_positive(row["samples_per_second"]) and finite_positive(row["mitsuba_samples_per_second"])
    assert finite_positive(row["ratio_to_mitsuba"])
    assert row["seeds"] == 2 and data["settings"]["seeds"] == 2
    (conv,) = data["convergence"]
    assert {c["sampler"] for c in conv["curves"] if c["renderer"] == "mitsuba"} == {"independent", "stratified"}
    curves = json.loads((tmp_path / "set-mitsuba-cbox.json").read_text())
    assert curves["scene"] == "scenes/mitsuba-cbox.toml" and curves["seeds"] == 2
    # every curve, ours and each of Mitsuba's samplers, rendered twice with different seeds: the
    # renders differ at every spp they share, and the curve's points are their mean
    assert {c["renderer"] for c in curves["curves"]} == {"pyopencl_rt", "mitsuba"}
    for curve in curves["curves"]:
        first, second = (run["points"] for run in curve["seed_curves"])
        assert curve["points"], curve["label"]
        for i, point in enumerate(curve["points"]):
            assert first[i]["spp"] == second[i]["spp"] == point["spp"]
            assert first[i]["relmse"] != second[i]["relmse"], (curve["label"], point["spp"])
            assert point["relmse"] == pytest.approx((first[i]["relmse"] + second[i]["relmse"]) / 2)
    lines = capsys.readouterr().out.splitlines()
    header = max(i for i, line in enumerate(lines) if line.startswith("scene ") and "t Mitsuba s" in line)
    assert lines[header + 1].split()[0] == "scenes/mitsuba-cbox.toml"


def test_bench_set_refuses_an_unknown_mitsuba_sampler(capsys):
    with pytest.raises(SystemExit) as exc:
        main(["bench", "set", "--mitsuba-sampler", "independent,sobol"])
    assert exc.value.code == 2
    assert "unknown Mitsuba sampler 'sobol'" in capsys.readouterr().err
