"""Convergence benchmark: error against a reference as a function of render time.

``pyopencl-rt bench convergence SCENE`` renders SCENE progressively (1, 2, 3, 4, 6, 8, 12, ... spp,
one growing film per curve) on each device x integrator x intersector, optionally with Mitsuba 3
beside it, and measures after each step the wall time of the passes so far (kernel build and a
warm-up pass reported apart) and the error against a reference image:

* ``rmse``: sqrt(mean over pixels and channels of (x - r)^2);
* ``relmse``: mean of (x - r)^2 / (r^2 + eps), ``eps`` = :data:`EPS` = 1e-2 (Rousselle et al.);
* ``mae``: mean of |x - r|.

Monte Carlo error falls as t^(-1/2) (RMSE) and t^(-1) (relMSE).  The reference has noise of its
own, which puts a floor under every curve; its expected contribution (from the reference film's
per-pixel variance) is recorded and the slopes are fitted only on points whose MSE is above
:data:`FLOOR_FACTOR` times that floor.  Without ``--reference`` the reference is rendered first
(our ``path`` integrator, its own seed) and cached under ``~/.cache/pyopencl_rt/references`` keyed
by a hash of the scene file's bytes and the settings that change the image.
"""
from __future__ import annotations

import hashlib
import json
import math
import os
import platform
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

from ..errors import UserError

SCHEMA = "pyopencl_rt.convergence/1"
EPS = 1e-2
FLOOR_FACTOR = 4.0
TARGETS = (1e-2, 1e-3)
REFERENCE_SHARE = 0.3  # of the budget, when the reference must be rendered
REFERENCE_SEED = 0x5EED5EED
LLVM_CANDIDATES = ("/usr/lib/x86_64-linux-gnu/libLLVM.so.19.1", "/usr/lib/x86_64-linux-gnu/libLLVM-19.so")


# --------------------------------------------------------------------------------------------
# metrics and fits


def metrics(image, reference, eps: float = EPS) -> dict:
    """RMSE, relative MSE ((x - r)^2 / (r^2 + eps), averaged) and MAE over pixels and channels."""
    x = np.asarray(image, np.float64)
    r = np.asarray(reference, np.float64)
    if x.shape != r.shape:
        raise ValueError(f"image {x.shape} and reference {r.shape} differ in shape")
    d = x - r
    return {"rmse": float(np.sqrt(np.mean(d * d))), "relmse": float(np.mean(d * d / (r * r + eps))),
            "mae": float(np.mean(np.abs(d)))}


def reference_floor(reference, variance, eps: float = EPS) -> dict:
    """Expected MSE and relMSE that the reference's own noise adds to every measurement."""
    r = np.asarray(reference, np.float64)
    v = np.asarray(variance, np.float64)
    if not np.isfinite(v).all():
        return {"mse": None, "relmse": None}
    return {"mse": float(v.mean()), "relmse": float(np.mean(v / (r * r + eps)))}


def fit_slope(x, y) -> dict:
    """Least-squares line through (log10 x, log10 y): {'slope', 'intercept', 'n'} (None if < 2 points)."""
    x = np.asarray(x, np.float64)
    y = np.asarray(y, np.float64)
    ok = (x > 0) & (y > 0) & np.isfinite(x) & np.isfinite(y)
    if ok.sum() < 2:
        return {"slope": None, "intercept": None, "n": int(ok.sum())}
    slope, intercept = np.polyfit(np.log10(x[ok]), np.log10(y[ok]), 1)
    return {"slope": float(slope), "intercept": float(intercept), "n": int(ok.sum())}


def time_to_reach(times, errors, target, fit=None) -> dict:
    """First time at which the error falls to ``target``: log-log interpolation between the
    measured points that bracket it; beyond the last point, the fitted line (``extrapolated``)."""
    t = np.asarray(times, np.float64)
    e = np.asarray(errors, np.float64)
    for i in range(len(t)):
        if e[i] <= target:
            if i == 0:
                # before the first point: the fit (or the first time as an upper bound)
                break
            lt0, lt1, le0, le1 = np.log10(t[i - 1]), np.log10(t[i]), np.log10(e[i - 1]), np.log10(e[i])
            f = (np.log10(target) - le0) / (le1 - le0) if le1 != le0 else 1.0
            return {"seconds": float(10 ** (lt0 + f * (lt1 - lt0))), "extrapolated": False}
    if fit and fit.get("slope") is not None and fit["slope"] < 0:
        return {"seconds": float(10 ** ((math.log10(target) - fit["intercept"]) / fit["slope"])), "extrapolated": True}
    return {"seconds": None, "extrapolated": False}


def spp_schedule(limit: int = 1 << 20):
    """1, 2, 3, 4, 6, 8, 12, 16, ...: about half an octave apart."""
    out, k = [], 0
    while True:
        for v in (1 << k, 3 << (k - 1) if k >= 1 else None):
            if v and v <= limit and v not in out:
                out.append(v)
        if (1 << k) > limit:
            return sorted(out)
        k += 1


# --------------------------------------------------------------------------------------------
# reference


def cache_dir() -> Path:
    base = os.environ.get("PYOPENCL_RT_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "pyopencl_rt")
    return Path(base) / "references"


def reference_key(scene_path, settings: dict) -> str:
    """Cache key of a reference: the scene file, the settings, and the kernel sources -- a cached
    reference must not outlive a change to the renderer (one rendered before the spawn-offset
    fix kept a biased image in the cache)."""
    from ..device.kernels import cl_dir

    h = hashlib.sha256()
    h.update(Path(scene_path).read_bytes())
    h.update(json.dumps(settings, sort_keys=True).encode())
    for src in sorted(cl_dir().rglob("*")):
        if src.suffix in (".h", ".cl"):
            h.update(src.name.encode())
            h.update(src.read_bytes())
    return h.hexdigest()[:24]


def load_or_render_reference(scene, scene_path, *, width, height, max_depth, rr_depth, device, seconds=None,
                             spp=None, use_cache=True, echo=print) -> dict:
    """The reference image (float64 H x W x 3), its variance (or None) and a description."""
    from ..render.api import render_full

    settings = {"width": width, "height": height, "max_depth": max_depth, "rr_depth": rr_depth,
                "integrator": "path", "seed": REFERENCE_SEED}
    key = reference_key(scene_path, settings)
    d = cache_dir()
    npz, meta = d / f"{key}.npz", d / f"{key}.json"
    if use_cache and npz.exists() and meta.exists():
        info = json.loads(meta.read_text())
        if spp is None or info.get("spp", 0) >= spp:
            with np.load(npz) as z:
                echo(f"reference: cached {npz} ({info['spp']} spp)")
                return {"image": z["image"], "variance": z["variance"], "info": {**info, "source": "cache", "path": str(npz)}}
    echo(f"reference: rendering ({'%d spp' % spp if spp else '%.0f s' % seconds}) ...")
    r = render_full(scene, spp=spp, time_limit=None if spp else seconds, device=device, seed=REFERENCE_SEED,
                    width=width, height=height, max_depth=max_depth, integrator="path")
    if r.stats.passes < 2:
        raise UserError("the reference got fewer than 2 passes: raise --budget or give --reference-spp")
    info = {**settings, "spp": r.info["spp"], "seconds": r.info["render_seconds"], "device": r.info["device"],
            "key": key, "scene": str(scene_path)}
    image, var = r.film.image().astype(np.float64), r.film.variance_of_mean()
    if use_cache:
        d.mkdir(parents=True, exist_ok=True)
        tmp = d / f".{key}.{os.getpid()}.npz"
        np.savez_compressed(tmp, image=image.astype(np.float32), variance=var.astype(np.float32))
        os.replace(tmp, npz)
        meta.write_text(json.dumps(info, indent=2))
    return {"image": image, "variance": var, "info": {**info, "source": "rendered", "path": str(npz) if use_cache else None}}


# --------------------------------------------------------------------------------------------
# our renderer, progressively


def short_device(dev) -> str:
    if "portable" in dev.platform.name.lower():
        return "PoCL " + ("CPU" if "cpu" in str(dev.type).lower() or dev.type == 2 else dev.name[:20])
    return dev.name.strip()[:28]


def run_curve(scene, *, device, integrator, intersector, width, height, max_depth, rr_depth, reference, seconds,
              seed=1, echo=print) -> dict:
    """One curve: a growing film, metrics after each step of :func:`spp_schedule`, until ``seconds``."""
    from ..device.devices import device_label, select_device
    from ..render.film import Film
    from ..render.wavefront import Wavefront

    dev = select_device(device)
    cls = Wavefront
    if intersector == "embree":
        from ..render.embree_wavefront import EmbreeWavefront as cls
    t0 = time.perf_counter()
    wf = cls(scene, dev, width=width, height=height, integrator=integrator, max_depth=max_depth,
             rr_depth=rr_depth, seed=seed)
    setup = time.perf_counter() - t0
    t0 = time.perf_counter()
    wf.run(Film(width, height), passes=1, first_pass=1 << 20)  # warm-up: first launches compile work-groups
    warmup = time.perf_counter() - t0
    film = Film(width, height)
    points, elapsed, done = [], 0.0, 0
    for target in spp_schedule():
        if done and elapsed * target / done > seconds:  # the next step would overrun the share
            break
        stats = wf.run(film, passes=target - done, first_pass=done)
        elapsed += stats.seconds
        done = target
        m = metrics(film.image(), reference)
        points.append({"spp": done, "seconds": elapsed, **m,
                       "samples_per_second": done * width * height / elapsed if elapsed > 0 else None})
    label = f"{short_device(dev)} / {integrator}" + (" / embree" if intersector == "embree" else "")
    echo(f"  {label}: {done} spp in {elapsed:.2f} s (build {wf.timings.get('build_seconds', 0):.2f} s, "
         f"warm-up {warmup:.2f} s)")
    return {"label": label, "renderer": "pyopencl_rt", "device": device_label(dev), "integrator": integrator,
            "intersector": intersector, "build_seconds": wf.timings.get("build_seconds"),
            "bvh_seconds": wf.timings.get("bvh_seconds"), "setup_seconds": setup, "warmup_seconds": warmup,
            "points": points}


# --------------------------------------------------------------------------------------------
# Mitsuba 3, in its own interpreter


def find_mitsuba_python(explicit=None):
    """(python executable, how found) for an interpreter that imports mitsuba, or (None, why not)."""
    tried = []
    cands = []
    if explicit:
        cands.append(("--mitsuba-python", explicit))
    env = os.environ.get("PYOPENCL_RT_MITSUBA_PYTHON")
    if env:
        cands.append(("PYOPENCL_RT_MITSUBA_PYTHON", env))
    if not explicit:
        cands.append(("this interpreter", sys.executable))
    for how, py in cands:
        if not (py and Path(py).exists()):
            tried.append(f"{how}={py} (no such file)")
            continue
        try:
            r = subprocess.run([py, "-c", "import mitsuba"], capture_output=True, timeout=120, env=mitsuba_env())
        except (OSError, subprocess.TimeoutExpired) as exc:
            tried.append(f"{how}={py} ({exc})")
            continue
        if r.returncode == 0:
            return py, how
        tried.append(f"{how}={py} (cannot import mitsuba)")
    return None, "; ".join(tried)


def mitsuba_env() -> dict:
    env = dict(os.environ)
    if "DRJIT_LIBLLVM_PATH" not in env:
        for c in LLVM_CANDIDATES:
            if Path(c).exists():
                env["DRJIT_LIBLLVM_PATH"] = c
                break
    return env


def run_mitsuba_curve(scene, python, *, width, height, max_depth, rr_depth, reference, seconds, variant,
                      workdir, echo=print) -> dict:
    from .mitsuba_export import save_scene_npz, scene_arrays

    npz = Path(workdir) / "scene.npz"
    save_scene_npz(npz, scene_arrays(scene, width, height, 1, max_depth, rr_depth))
    runner = Path(__file__).with_name("mitsuba_runner.py")
    cmd = [python, str(runner), str(npz), str(workdir), "--variant", variant, "--budget", f"{seconds:.3f}",
           "--checkpoints", ",".join(str(s) for s in spp_schedule())]
    t0 = time.perf_counter()
    r = subprocess.run(cmd, capture_output=True, text=True, env=mitsuba_env())
    wall = time.perf_counter() - t0
    if r.returncode != 0:
        tail = (r.stderr or r.stdout).strip().splitlines()[-3:]
        raise UserError(f"Mitsuba ({variant}) failed: {' | '.join(tail)}")
    info = json.loads((Path(workdir) / "mitsuba.json").read_text())
    points = []
    for p in info["points"]:
        img = np.load(p["image"]).astype(np.float64)
        points.append({"spp": p["spp"], "seconds": p["seconds"], **metrics(img, reference),
                       "samples_per_second": p["spp"] * width * height / p["seconds"] if p["seconds"] > 0 else None})
    last = points[-1] if points else {"spp": 0, "seconds": 0.0}
    echo(f"  mitsuba {info['version']} {variant}: {last['spp']} spp in {last['seconds']:.2f} s "
         f"(JIT warm-up {info['warmup_seconds']:.2f} s)")
    return {"label": f"Mitsuba {info['version']} {variant} / path", "renderer": "mitsuba", "device": variant,
            "integrator": "path", "intersector": "mitsuba", "build_seconds": info["warmup_seconds"],
            "warmup_seconds": info["warmup_seconds"], "setup_seconds": info["load_seconds"] + info["import_seconds"],
            "process_seconds": wall, "version": info["version"], "points": points}


# --------------------------------------------------------------------------------------------
# analysis, JSON, plot


def analyse(curves, floor) -> None:
    """Slopes, times to the relMSE targets and the speed-up over the PoCL CPU curve of the same
    integrator (at equal relMSE: the ratio of the times to 1e-2), in place."""
    for c in curves:
        pts = c["points"]
        t = [p["seconds"] for p in pts]
        keep = [i for i, p in enumerate(pts)
                if floor.get("mse") is None or p["rmse"] ** 2 > FLOOR_FACTOR * floor["mse"]]
        c["fit_points"] = len(keep)
        c["slope_rmse"] = fit_slope([t[i] for i in keep], [pts[i]["rmse"] for i in keep])
        c["slope_relmse"] = fit_slope([t[i] for i in keep], [pts[i]["relmse"] for i in keep])
        c["time_to_relmse"] = {f"{x:g}": time_to_reach(t, [p["relmse"] for p in pts], x, c["slope_relmse"])
                               for x in TARGETS}
        floor_rel = floor.get("relmse")
        for x, v in c["time_to_relmse"].items():
            if floor_rel is not None and float(x) < FLOOR_FACTOR * floor_rel:
                v["below_reference_floor"] = True
    base = {}
    for c in curves:
        if c["renderer"] == "pyopencl_rt" and c["intersector"] == "opencl" and "cpu" in c["device"].lower():
            base.setdefault(c["integrator"], c)
    for c in curves:
        b = base.get(c["integrator"])
        c["speedup_vs_cpu"] = None
        if b is not None:
            tb = b["time_to_relmse"]["0.01"]["seconds"]
            tc = c["time_to_relmse"]["0.01"]["seconds"]
            if tb and tc:
                c["speedup_vs_cpu"] = {"baseline": b["label"], "at_relmse": 1e-2, "speedup": tb / tc}


def write_plot(path, result) -> str | None:
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for ax, key, expect in ((axes[0], "rmse", -0.5), (axes[1], "relmse", -1.0)):
        for c in result["curves"]:
            t = [p["seconds"] for p in c["points"]]
            e = [p[key] for p in c["points"]]
            fit = c[f"slope_{key}"]
            lab = c["label"] + (f"  (slope {fit['slope']:.2f})" if fit["slope"] is not None else "")
            line, = ax.loglog(t, e, "o-", ms=3, label=lab)
            if fit["slope"] is not None:
                tt = np.array([min(t), max(t)])
                ax.loglog(tt, 10 ** (fit["intercept"] + fit["slope"] * np.log10(tt)), ":", color=line.get_color())
        fl = result["reference"].get("floor", {})
        fv = fl.get("mse") if key == "rmse" else fl.get("relmse")
        if fv:
            ax.axhline(math.sqrt(fv) if key == "rmse" else fv, color="grey", lw=0.8, ls="--", label="reference noise")
        if key == "relmse":
            for x in TARGETS:
                ax.axhline(x, color="k", lw=0.5, alpha=0.4)
        ax.set_xlabel("render time (s, excluding kernel build / JIT)")
        ax.set_ylabel({"rmse": "RMSE", "relmse": f"relMSE (eps = {EPS:g})"}[key])
        ax.set_title(f"{key}: Monte Carlo slope {expect:g}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{Path(result['scene']).name} {result['width']}x{result['height']}, max_depth {result['max_depth']}, "
                 f"{result['host']}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


REQUIRED_KEYS = {
    "schema": str, "scene": str, "width": int, "height": int, "max_depth": int, "rr_depth": int, "eps": float,
    "budget_seconds": (float, type(None)), "total_seconds": float, "host": str, "reference": dict, "curves": list,
    "skipped": list,
}
CURVE_KEYS = {
    "label": str, "renderer": str, "device": str, "integrator": str, "intersector": str, "points": list,
    "slope_rmse": dict, "slope_relmse": dict, "time_to_relmse": dict, "build_seconds": (float, type(None)),
    "warmup_seconds": float,
}
POINT_KEYS = {"spp": int, "seconds": float, "rmse": float, "relmse": float, "mae": float}


def validate(result: dict) -> None:
    """Raise ValueError if ``result`` lacks a required key or has one of the wrong type."""
    def check(obj, spec, where):
        for k, typ in spec.items():
            if k not in obj:
                raise ValueError(f"{where}: missing key {k!r}")
            if not isinstance(obj[k], typ) or isinstance(obj[k], bool):
                raise ValueError(f"{where}.{k}: {type(obj[k]).__name__}, expected {typ}")
    check(result, REQUIRED_KEYS, "result")
    if result["schema"] != SCHEMA:
        raise ValueError(f"schema {result['schema']!r} is not {SCHEMA!r}")
    for i, c in enumerate(result["curves"]):
        check(c, CURVE_KEYS, f"curves[{i}]")
        for j, p in enumerate(c["points"]):
            check(p, POINT_KEYS, f"curves[{i}].points[{j}]")
        for x in ("0.01", "0.001"):
            if x not in c["time_to_relmse"]:
                raise ValueError(f"curves[{i}].time_to_relmse: missing {x}")


# --------------------------------------------------------------------------------------------
# the command


def run_convergence(scene_path, *, devices=None, integrators=("path",), intersectors=("opencl",), reference=None,
                    reference_spp=None, budget=60.0, width=None, height=None, max_depth=None, compare=(),
                    mitsuba_python=None, mitsuba_variant="llvm_ad_rgb", json_path="out/convergence.json",
                    plot_path=None, use_cache=True, echo=print) -> dict:
    from ..device.devices import resolve
    from ..imageio import read_exr, write_json
    from ..scene.scenefile import load_scene

    start = time.perf_counter()
    scene = load_scene(scene_path)
    st = scene.settings
    width, height = int(width or st.width), int(height or st.height)
    max_depth = int(st.max_depth if max_depth is None else max_depth)
    rr_depth = int(st.rr_depth)
    devs = resolve(list(devices)) if devices else resolve(["cpu"])
    skipped, notes = [], []
    mitsuba_py = None
    if "mitsuba" in compare:
        mitsuba_py, how = find_mitsuba_python(mitsuba_python)
        if mitsuba_py is None:
            msg = ("Mitsuba comparison skipped: Mitsuba 3 not found (pip install mitsuba in this environment, or "
                   f"point --mitsuba-python / PYOPENCL_RT_MITSUBA_PYTHON at an interpreter that has it); tried {how}")
            echo(msg)
            skipped.append({"what": "mitsuba", "why": msg})
        else:
            echo(f"Mitsuba: {mitsuba_py} ({how})")
    for c in compare:
        if c != "mitsuba":
            raise UserError(f"--compare {c}: only 'mitsuba' is supported")

    # reference
    if reference is not None:
        ref_img = read_exr(reference).astype(np.float64)
        if ref_img.shape != (height, width, 3):
            raise UserError(f"{reference}: {ref_img.shape[1]}x{ref_img.shape[0]}, but the benchmark renders {width}x{height}")
        ref = {"image": ref_img, "variance": None, "info": {"source": "file", "path": str(reference)}}
    else:
        ref = load_or_render_reference(scene, scene_path, width=width, height=height, max_depth=max_depth,
                                       rr_depth=rr_depth, device=devs[0],
                                       seconds=None if budget is None else REFERENCE_SHARE * budget,
                                       spp=reference_spp if (reference_spp or budget is None) else None,
                                       use_cache=use_cache, echo=echo)
    floor = reference_floor(ref["image"], ref["variance"]) if ref["variance"] is not None else {"mse": None, "relmse": None}
    ref_info = {**ref["info"], "floor": floor}

    jobs = [("ours", d, i, x) for d in devs for i in integrators for x in intersectors]
    if mitsuba_py:
        jobs.append(("mitsuba", None, "path", "mitsuba"))
    curves = []
    per_curve_default = 10.0
    for n, (kind, dev, integ, inter) in enumerate(jobs):
        if budget is not None:
            left = budget - (time.perf_counter() - start)
            # a share of what is left, less a guess of the fixed costs (build, warm-up, start-up)
            share = max(0.5, left / (len(jobs) - n) - (4.0 if kind == "mitsuba" else 1.0))
        else:
            share = per_curve_default
        if kind == "ours":
            curves.append(run_curve(scene, device=dev, integrator=integ, intersector=inter, width=width, height=height,
                                    max_depth=max_depth, rr_depth=rr_depth, reference=ref["image"], seconds=share,
                                    echo=echo))
        else:
            work = tempfile.mkdtemp(prefix="pyopencl_rt_mitsuba_")
            try:
                curves.append(run_mitsuba_curve(scene, mitsuba_py, width=width, height=height, max_depth=max_depth,
                                                rr_depth=rr_depth, reference=ref["image"], seconds=share,
                                                variant=mitsuba_variant, workdir=work, echo=echo))
            finally:
                shutil.rmtree(work, ignore_errors=True)
    analyse(curves, floor)
    result = {
        "schema": SCHEMA, "scene": str(scene_path), "width": width, "height": height, "max_depth": max_depth,
        "rr_depth": rr_depth, "eps": EPS, "budget_seconds": None if budget is None else float(budget),
        "host": platform.node(), "cpu_count": os.cpu_count(), "created": time.strftime("%Y-%m-%dT%H:%M:%S"),
        "reference": ref_info, "curves": curves, "skipped": skipped, "notes": notes,
        "total_seconds": 0.0,
    }
    json_path = Path(json_path)
    json_path.parent.mkdir(parents=True, exist_ok=True)
    plot_path = Path(plot_path) if plot_path else json_path.with_suffix(".png")
    result["total_seconds"] = time.perf_counter() - start
    result["plot"] = write_plot(plot_path, result)
    if result["plot"] is None:
        msg = "plot skipped: matplotlib is not installed (pip install 'pyopencl-rt[plot]')"
        echo(msg)
        skipped.append({"what": "plot", "why": msg})
    validate(result)
    write_json(json_path, result)
    print_table(result, echo)
    echo(f"wrote {json_path}" + (f" and {result['plot']}" if result["plot"] else ""))
    return result


def print_table(result, echo=print) -> None:
    echo(f"{'curve':<52} {'spp':>6} {'time s':>8} {'Msamp/s':>8} {'slope RMSE':>10} {'slope relMSE':>12} "
         f"{'t(1e-2) s':>10} {'t(1e-3) s':>10} {'vs CPU':>7}")
    for c in result["curves"]:
        last = c["points"][-1] if c["points"] else {"spp": 0, "seconds": 0.0, "samples_per_second": None}

        def fmt_t(x):
            v = c["time_to_relmse"][x]
            if v["seconds"] is None:
                return "-"
            return f"{v['seconds']:.3g}" + ("*" if v["extrapolated"] else "")

        def fmt_s(k):
            s = c[k]["slope"]
            return "-" if s is None else f"{s:.3f}"

        sps = last.get("samples_per_second")
        su = c.get("speedup_vs_cpu")
        echo(f"{c['label'][:52]:<52} {last['spp']:>6} {last['seconds']:>8.2f} {(sps or 0) / 1e6:>8.3f} "
             f"{fmt_s('slope_rmse'):>10} {fmt_s('slope_relmse'):>12} {fmt_t('0.01'):>10} {fmt_t('0.001'):>10} "
             f"{(('%.2fx' % su['speedup']) if su else '-'):>7}")
    echo("* extrapolated along the fitted line")
