"""``pyopencl-rt bench scale``: the whole ``pyopencl-rt render`` command and Mitsuba 3's load and
render of the same file, on scenes of millions of triangles (issue 35; docs/BENCHMARKS.md,
"Scenes of millions of triangles").

For each size (millions of triangles) the scene of :mod:`.scale_scene` is written (a height-field
grid as a binary PLY, an area light, a constant environment: a PLY already in the work folder is
reused), then, ``repeat`` times in turn, two child processes run and are timed from outside:

* ours: ``python -m pyopencl_rt.cli render SCENE.xml -o OUT.exr -q --profile`` (the whole
  command: start-up, imports, load, BVH, kernel build, render, writing the image), its host stages
  read back from the JSON sidecar (``host_seconds``, docs/OUTPUT.md);
* Mitsuba: :mod:`.mitsuba_scale_runner` in the Mitsuba interpreter (import, ``load_file``,
  ``render``, ``write_bitmap``).

``baseline`` (``--baseline DIR``: a checkout or ``git archive`` of another version, whose
``pyopencl_rt`` the same render command then imports) adds a third child per repeat, before ours:
a before/after comparison in the same conditions.  Each child's wall time is measured around it
and its peak resident memory comes from ``wait4`` (``ru_maxrss`` of that child alone).  The figures are the medians of the repeats (wall) and the
maxima (RSS); ``--json`` writes every run.
"""
from __future__ import annotations

import contextlib
import json
import os
import statistics
import subprocess
import sys
import time
from pathlib import Path

from .timing import machine_info, write_results

DEFAULT_SIZES = (0.5, 2.0, 8.0)
BIG_SIZE = 32.0


def parse_millions(text: str, with_32m: bool = False) -> list:
    """The --sizes list (millions of triangles), with 32 added by --with-32m; UserError if bad."""
    from ..errors import UserError

    try:
        values = [float(x) for x in text.split(",") if x.strip()]
    except ValueError:
        raise UserError(f"--sizes must be numbers (millions of triangles), got {text!r}") from None
    if not values or min(values) <= 0:
        raise UserError(f"--sizes must be positive numbers, got {text!r}")
    return values + ([BIG_SIZE] if with_32m and BIG_SIZE not in values else [])


def run_child(command, env=None, cwd=None, log=None) -> dict:
    """Runs ``command``; {"seconds": wall, "max_rss_mb": its peak RSS, "returncode", "stdout"}."""
    out_path = Path(log) if log else None
    with open(out_path, "wb") if out_path else contextlib.nullcontext(subprocess.DEVNULL) as sink:
        start = time.perf_counter()
        proc = subprocess.Popen(command, stdout=subprocess.PIPE, stderr=sink, env=env, cwd=cwd)
        stdout = proc.stdout.read()
        proc.stdout.close()
        _, status, usage = os.wait4(proc.pid, 0)
        seconds = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
    return {"seconds": seconds, "max_rss_mb": usage.ru_maxrss / 1024.0, "returncode": proc.returncode,
            "stdout": stdout.decode("utf-8", "replace")}


def _ours(xml: Path, out: Path, device) -> list:
    command = [sys.executable, "-m", "pyopencl_rt.cli", "render", str(xml), "-o", str(out), "-q", "--profile"]
    for d in device or ():
        command += ["--device", d]
    return command


def _sidecar(out: Path) -> dict:
    try:
        info = json.loads(out.with_suffix(".json").read_text())
    except (OSError, ValueError):
        return {}
    keep = ("host_seconds", "render_seconds", "bvh_seconds", "kernel_build_seconds", "device", "triangles")
    return {k: info[k] for k in keep if k in info}


def _failed(name, result, log):
    tail = Path(log).read_text(errors="replace").strip().splitlines()[-3:] if log and Path(log).exists() else []
    return f"{name} failed (exit {result['returncode']}): " + " | ".join(tail)


def run_scale_bench(*, sizes=DEFAULT_SIZES, workdir, repeat=1, width=256, height=256, spp=16, device=None,
                    mitsuba=True, mitsuba_python=None, llvm_path=None, variant="llvm_ad_rgb", json_path=None,
                    baseline=None, echo=print) -> dict:
    from .mitsuba_host import mitsuba_env, require_mitsuba_python
    from .scale_scene import write_scene

    workdir = Path(workdir).resolve()     # the children run in their package's folder
    workdir.mkdir(parents=True, exist_ok=True)
    python = require_mitsuba_python(mitsuba_python, variant, llvm_path, echo) if mitsuba else None
    runner = Path(__file__).with_name("mitsuba_scale_runner.py")
    env = dict(os.environ)
    package_root = str(Path(__file__).resolve().parents[2])
    env["PYTHONPATH"] = package_root + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    results = {"machine": machine_info(), "width": width, "height": height, "spp": spp, "repeat": repeat,
               "variant": variant if mitsuba else None, "sizes": []}
    echo(f"{'triangles':>10}  {'ours s':>8} {'ours MB':>8}  {'Mitsuba s':>9} {'Mitsuba MB':>10}  {'time x':>6} {'RSS x':>6}")
    for size in sizes:
        t = time.perf_counter()
        xml = write_scene(workdir, float(size) * 1e6, width, height, spp)
        triangles = int(xml.stem.split("_")[-1])
        row = {"millions": float(size), "triangles": triangles, "scene": str(xml),
               "scene_write_seconds": time.perf_counter() - t, "ours": [], "mitsuba": [], "baseline": []}
        for k in range(repeat):
            if baseline:
                out, log = workdir / f"baseline_{triangles}.exr", workdir / f"baseline_{triangles}.log"
                # in the baseline's folder: ``python -m`` puts the working folder before PYTHONPATH,
                # so from a checkout of ours the "baseline" was ours
                root = str(Path(baseline).resolve())
                r = run_child(_ours(xml, out, device), env=dict(env, PYTHONPATH=root), cwd=root, log=log)
                if r["returncode"] != 0:
                    raise RuntimeError(_failed("the baseline's render", r, log))
                r.pop("stdout")
                r.update(_sidecar(out))
                row["baseline"].append(r)
            out = workdir / f"ours_{triangles}.exr"
            log = workdir / f"ours_{triangles}.log"
            r = run_child(_ours(xml, out, device), env=env, cwd=package_root, log=log)
            if r["returncode"] != 0:
                raise RuntimeError(_failed("pyopencl-rt render", r, log))
            r.update(_sidecar(out))
            r.pop("stdout")
            row["ours"].append(r)
            if python:
                mlog = workdir / f"mitsuba_{triangles}.log"
                m = run_child([python, str(runner), str(xml), str(workdir / f"mitsuba_{triangles}.exr"),
                               "--variant", variant], env=mitsuba_env(llvm_path), log=mlog)
                if m["returncode"] != 0:
                    raise RuntimeError(_failed("Mitsuba", m, mlog))
                lines = [ln for ln in m.pop("stdout").splitlines() if ln.startswith("{")]
                m.update(json.loads(lines[-1]) if lines else {})
                row["mitsuba"].append(m)
        for who in ("ours", "mitsuba", "baseline"):
            if row[who]:
                row[f"{who}_seconds"] = statistics.median(r["seconds"] for r in row[who])
                row[f"{who}_max_rss_mb"] = max(r["max_rss_mb"] for r in row[who])
        if row["mitsuba"]:
            row["time_ratio"] = row["ours_seconds"] / row["mitsuba_seconds"]
            row["rss_ratio"] = row["ours_max_rss_mb"] / row["mitsuba_max_rss_mb"]
        results["sizes"].append(row)
        mi = (f"{row['mitsuba_seconds']:9.2f} {row['mitsuba_max_rss_mb']:10.0f}  {row['time_ratio']:6.2f} "
              f"{row['rss_ratio']:6.2f}") if row["mitsuba"] else f"{'-':>9} {'-':>10}  {'-':>6} {'-':>6}"
        echo(f"{triangles:>10}  {row['ours_seconds']:8.2f} {row['ours_max_rss_mb']:8.0f}  {mi}")
        if row["baseline"]:
            echo(f"{'baseline':>10}  {row['baseline_seconds']:8.2f} {row['baseline_max_rss_mb']:8.0f}")
        host = row["ours"][-1].get("host_seconds")
        if host:
            echo("            ours, host stages: " + ", ".join(f"{k} {v:.2f}" for k, v in host.items()))
    if json_path:
        write_results(json_path, results, echo)
    return results
