"""The numbers of the convergence benchmark (:mod:`.convergence`): error metrics, log-log slope
fits, times to a target error, the JSON schema, the plot and the table.

* ``rmse``: sqrt(mean over pixels and channels of (x - r)^2);
* ``relmse``: mean of (x - r)^2 / (r^2 + eps), ``eps`` = :data:`EPS` = 1e-2 (Rousselle et al.);
* ``mae``: mean of |x - r|.

Monte Carlo error falls as t^(-1/2) (RMSE) and t^(-1) (relMSE).  The reference has noise of its
own, which puts a floor under every curve, so slopes are fitted only on points whose MSE is above
:data:`FLOOR_FACTOR` times that floor.

A curve rendered with several seeds (``--seeds``) has the mean of its seeds' points as its own
(:func:`mean_points`), and its spp and time to a target come with their spread over the seeds
(:func:`seed_estimate`: on the mean relMSE, a bootstrap standard error over the seeds).
"""
from __future__ import annotations

import math
from pathlib import Path

import numpy as np

SCHEMA = "pyopencl_rt.convergence/1"
EPS = 1e-2
FLOOR_FACTOR = 4.0
TARGETS = (1e-2, 1e-3)


def metrics(image, reference, eps: float = EPS) -> dict:
    """RMSE, relative MSE ((x - r)^2 / (r^2 + eps), averaged) and MAE over pixels and channels."""
    x = np.asarray(image, np.float64)
    r = np.asarray(reference, np.float64)
    if x.shape != r.shape:
        raise ValueError(f"image {x.shape} and reference {r.shape} differ in shape")
    diff = x - r
    return {"rmse": float(np.sqrt(np.mean(diff * diff))), "relmse": float(np.mean(diff * diff / (r * r + eps))),
            "mae": float(np.mean(np.abs(diff)))}


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
                # reached before the first point: only the fit can say when
                break
            lt0, lt1, le0, le1 = np.log10(t[i - 1]), np.log10(t[i]), np.log10(e[i - 1]), np.log10(e[i])
            f = (np.log10(target) - le0) / (le1 - le0) if le1 != le0 else 1.0
            return {"seconds": float(10 ** (lt0 + f * (lt1 - lt0))), "extrapolated": False}
    if fit and fit.get("slope") is not None and fit["slope"] < 0:
        return {"seconds": float(10 ** ((math.log10(target) - fit["intercept"]) / fit["slope"])), "extrapolated": True}
    return {"seconds": None, "extrapolated": False}


# --------------------------------------------------------------------------------------------
# a curve rendered with several seeds: its mean error, and the spp to a target with a spread

BOOTSTRAP = 1000  # resamples of a curve's seeds, for the standard error of its spp to a target
TAIL = 4  # the 1/N model is fitted on the points of at least 1/TAIL of the last spp (two octaves)


def seed_runs(curve) -> list[list[dict]]:
    """A curve's renders, one list of points per seed: its ``seed_curves`` (a curve rendered with
    several seeds), else its own points (one seed, as every curve was before seeds)."""
    runs = curve.get("seed_curves")
    return [run["points"] for run in runs] if runs else [curve["points"]]


def common_spp(runs) -> list:
    """The spp at which every run has a point, in order."""
    return sorted(set.intersection(*({p["spp"] for p in run} for run in runs))) if runs else []


def mean_points(runs, pixels) -> list[dict]:
    """The points of a curve rendered with several seeds (``runs``: a list of points per seed), at
    each spp that every seed reached: the mean over seeds of the relMSE and MAE (and of any other
    number a point has), RMSE as the root of the mean MSE, the median of the times (a time, not an
    error: the first render of a Mitsuba stratifying sampler at a new sample count also pays
    Dr.Jit's compilation of its kernels, which the median of three seeds or more leaves out, as
    the untimed warm-up leaves out the first), samples/s as the samples over that time;
    ``relmse_sd``: the standard deviation of the seeds' relMSE; ``seeds``: how many.  One run: its
    points as they are."""
    if len(runs) == 1:
        return list(runs[0])
    points = []
    for spp in common_spp(runs):
        at = [next(p for p in run if p["spp"] == spp) for run in runs]
        point = {"spp": int(spp)}
        for key, value in at[0].items():
            values = [p.get(key) for p in at]
            if key == "spp" or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
                continue
            values = np.asarray(values, np.float64)
            if key in ("rmse", "raw_rmse"):
                point[key] = float(np.sqrt(np.mean(values ** 2)))
            else:
                point[key] = float(np.median(values) if key == "seconds" else values.mean())
        if point.get("seconds"):
            point["samples_per_second"] = spp * pixels / point["seconds"]
        point["relmse_sd"] = float(np.std([p["relmse"] for p in at], ddof=1))
        point["seeds"] = len(at)
        points.append(point)
    return points


def reach(spp, relmse, seconds, target, floor=None) -> dict:
    """The spp and time at which a curve's relMSE (its mean over seeds) falls to ``target``.

    Measured where the curve crosses it: log-log interpolation between the two points that bracket
    it, as :func:`time_to_reach` does.  Otherwise (``extrapolated``) the Monte Carlo model
    relMSE(N) = c / N + floor, ``floor`` the relMSE that the reference's own noise adds to every
    measurement (it is part of the error measured, as in the curves' own times to the target):
    c, the error per sample (``relmse_x_spp``), is the mean of (relMSE - floor) x N over the points
    of the last two octaves (N >= last N / :data:`TAIL`) that stand above :data:`FLOOR_FACTOR`
    times the floor (all of those points when none does), and N = c / (target - floor), its time
    N times the seconds per spp of the last point.  None when the target is not above the floor.
    ``relmse_x_spp`` is given either way (the per-sample error beyond the reference's)."""
    n, e, t = (np.asarray(a, np.float64) for a in (spp, relmse, seconds))
    out = {"spp": None, "seconds": None, "extrapolated": False, "relmse_x_spp": None}
    if len(n) == 0:
        return out
    f = float(floor or 0.0)
    tail = n * TAIL >= n[-1]
    above = tail & (e > FLOOR_FACTOR * f)
    use = above if above.any() else tail
    c = float(np.mean((e[use] - f) * n[use]))
    out["relmse_x_spp"] = c if c > 0 else None
    for i in range(len(n)):
        if e[i] <= target:
            if i == 0:  # reached before the first point: only the model can say where
                break
            if e[i - 1] > e[i] > 0:
                w = (math.log10(target) - math.log10(e[i - 1])) / (math.log10(e[i]) - math.log10(e[i - 1]))
            else:
                w = 1.0
            log_n = math.log10(n[i - 1]) + w * (math.log10(n[i]) - math.log10(n[i - 1]))
            log_t = math.log10(t[i - 1]) + w * (math.log10(t[i]) - math.log10(t[i - 1]))
            return {**out, "spp": 10 ** log_n, "seconds": 10 ** log_t}
    if c > 0 and target > f and n[-1] > 0:
        needed = c / (target - f)
        return {**out, "spp": needed, "seconds": needed * t[-1] / n[-1], "extrapolated": True}
    return out


def seed_estimate(runs, target, floor=None, bootstrap: int = BOOTSTRAP) -> dict:
    """The spp and time to relMSE ``target`` of a curve rendered with several seeds (``runs``: a
    list of points per seed), with their spread over the seeds.

    The estimate is :func:`reach` on the mean over seeds of the relMSE at each spp that every seed
    reached (and the median of their times there, as in :func:`mean_points`): the mean of
    independent renders' relMSE is an unbiased estimate of the renderer's expected relMSE at that
    spp, where one render's is that plus its luck.  The spread is that of the error over the
    seeds, the times at each spp held at their median: ``spp_se`` and ``seconds_se``, the standard
    deviation of the estimate over ``bootstrap`` resamples of the seeds with replacement (the
    standard error of the estimate; none with one seed), and ``spp_range``, ``seconds_range``: the
    lowest and highest estimate of a seed alone (``per_seed``), as wide as single renders' luck.
    The resampling is seeded, so the same runs give the same spread.  (Timing noise is another
    matter: the ratio "in turns" of ``bench set`` is the one that load does not move.)"""
    k = len(runs)
    spp = common_spp(runs)
    out = {"seeds": k, "spp": None, "seconds": None, "extrapolated": False, "relmse_x_spp": None,
           "spp_se": None, "seconds_se": None, "spp_range": None, "seconds_range": None, "per_seed": []}
    if not spp:
        return out
    at = [{p["spp"]: p for p in run} for run in runs]
    e = np.array([[a[n]["relmse"] for n in spp] for a in at], np.float64)
    t = np.array([[a[n]["seconds"] for n in spp] for a in at], np.float64)
    times = np.median(t, 0)
    out.update(reach(spp, e.mean(0), times, target, floor))
    per_seed = [reach(spp, e[i], times, target, floor) for i in range(k)]
    out["per_seed"] = per_seed
    for key in ("spp", "seconds"):
        values = [r[key] for r in per_seed if r[key] is not None]
        out[f"{key}_range"] = [min(values), max(values)] if values else None
    if k > 1 and bootstrap:
        draws = np.random.default_rng(0).integers(0, k, (bootstrap, k))
        boot = [reach(spp, e[d].mean(0), times, target, floor) for d in draws]
        for key in ("spp", "seconds"):
            values = np.array([r[key] for r in boot if r[key] is not None], np.float64)
            out[f"{key}_se"] = float(values.std(ddof=1)) if len(values) > 1 else None
        out["bootstrap"] = {"resamples": int(bootstrap), "without_estimate": sum(r["spp"] is None for r in boot)}
    return out


def ratio_se(a, a_se, b, b_se):
    """The standard error of a / b from those of two independent estimates a and b (the delta
    method: relative errors add in quadrature); None when either is missing."""
    if not a or not b or a_se is None or b_se is None:
        return None
    return a / b * math.sqrt((a_se / a) ** 2 + (b_se / b) ** 2)


def spp_schedule(limit: int = 1 << 20):
    """1, 2, 3, 4, 6, 8, 12, 16, ...: about half an octave apart."""
    schedule, k = [], 0
    while True:
        for spp in (1 << k, 3 << (k - 1) if k >= 1 else None):
            if spp and spp <= limit and spp not in schedule:
                schedule.append(spp)
        if (1 << k) > limit:
            return sorted(schedule)
        k += 1


def analyse(curves, floor) -> None:
    """Slopes, times to the relMSE targets and the speed-up over the PoCL CPU curve of the same
    integrator (at equal relMSE: the ratio of the times to 1e-2), in place."""
    for curve in curves:
        points = curve["points"]
        times = [p["seconds"] for p in points]
        keep = [i for i, p in enumerate(points)
                if floor.get("mse") is None or p["rmse"] ** 2 > FLOOR_FACTOR * floor["mse"]]
        curve["fit_points"] = len(keep)
        curve["slope_rmse"] = fit_slope([times[i] for i in keep], [points[i]["rmse"] for i in keep])
        curve["slope_relmse"] = fit_slope([times[i] for i in keep], [points[i]["relmse"] for i in keep])
        curve["time_to_relmse"] = {f"{x:g}": time_to_reach(times, [p["relmse"] for p in points], x,
                                                           curve["slope_relmse"]) for x in TARGETS}
        floor_relmse = floor.get("relmse")
        for target, reached in curve["time_to_relmse"].items():
            if floor_relmse is not None and float(target) < FLOOR_FACTOR * floor_relmse:
                reached["below_reference_floor"] = True
        if curve.get("denoised"):
            curve["denoise"] = denoise_gain(points)
        if curve.get("seed_curves"):  # the spp and time to each target over the seeds, with their spread
            curve["seed_estimate"] = {f"{x:g}": seed_estimate(seed_runs(curve), x, floor_relmse) for x in TARGETS}
    baselines = {}
    for curve in curves:
        if curve.get("denoised") or curve.get("adaptive"):
            continue
        if curve["renderer"] == "pyopencl_rt" and curve["intersector"] == "opencl" and "cpu" in curve["device"].lower():
            baselines.setdefault(curve["integrator"], curve)
    for curve in curves:
        baseline = baselines.get(curve["integrator"])
        curve["speedup_vs_cpu"] = None
        if baseline is not None:
            t_baseline = baseline["time_to_relmse"]["0.01"]["seconds"]
            t_curve = curve["time_to_relmse"]["0.01"]["seconds"]
            if t_baseline and t_curve:
                curve["speedup_vs_cpu"] = {"baseline": baseline["label"], "at_relmse": 1e-2,
                                           "speedup": t_baseline / t_curve}
    for curve in curves:
        if curve.get("adaptive"):
            curve["adaptive_gain"] = adaptive_gain(curve, curves)


def adaptive_gain(curve, curves) -> dict | None:
    """An adaptive curve's time to relMSE against the plain curve of the same device, integrator,
    intersector and sampler, at the lowest target both reach (measured, not extrapolated)."""
    same = ("device", "integrator", "intersector", "sampler", "renderer")
    plain = next((c for c in curves if not c.get("adaptive") and not c.get("denoised")
                  and all(c.get(k) == curve.get(k) for k in same)), None)
    if plain is None:
        return None
    for target in sorted(TARGETS):
        a, b = curve["time_to_relmse"][f"{target:g}"], plain["time_to_relmse"][f"{target:g}"]
        if a["seconds"] and b["seconds"] and not a["extrapolated"] and not b["extrapolated"]:
            return {"plain": plain["label"], "at_relmse": target, "seconds": a["seconds"],
                    "plain_seconds": b["seconds"], "speedup": b["seconds"] / a["seconds"]}
    return None


def denoise_gain(points) -> dict:
    """How much a denoised curve gains over the raw image of the same film, point by point
    (raw error / denoised error, for relMSE and RMSE), and where it stops helping: per metric, the
    first spp from which the denoised error is no lower than the raw one (the denoiser's bias
    floor reached), None if that never happens within the curve."""
    out = {"max_spp": points[-1]["spp"] if points else 0}
    for key in ("relmse", "rmse"):
        out[f"{key}_gain"] = [p[f"raw_{key}"] / p[key] if p[key] > 0 else None for p in points]
        out[f"stops_helping_at_spp_{key}"] = next((p["spp"] for p in points if p[key] >= p[f"raw_{key}"]), None)
    return out


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
        for key, expected in spec.items():
            if key not in obj:
                raise ValueError(f"{where}: missing key {key!r}")
            if not isinstance(obj[key], expected) or isinstance(obj[key], bool):
                raise ValueError(f"{where}.{key}: {type(obj[key]).__name__}, expected {expected}")
    check(result, REQUIRED_KEYS, "result")
    if result["schema"] != SCHEMA:
        raise ValueError(f"schema {result['schema']!r} is not {SCHEMA!r}")
    for i, curve in enumerate(result["curves"]):
        check(curve, CURVE_KEYS, f"curves[{i}]")
        for j, point in enumerate(curve["points"]):
            check(point, POINT_KEYS, f"curves[{i}].points[{j}]")
        for target in ("0.01", "0.001"):
            if target not in curve["time_to_relmse"]:
                raise ValueError(f"curves[{i}].time_to_relmse: missing {target}")


def write_plot(path, result) -> str | None:
    """Log-log RMSE and relMSE against time, one line per curve with its fit; None without matplotlib."""
    try:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt
    except ImportError:
        return None
    fig, axes = plt.subplots(1, 2, figsize=(12, 5))
    for ax, key, expected_slope in ((axes[0], "rmse", -0.5), (axes[1], "relmse", -1.0)):
        for curve in result["curves"]:
            times = [p["seconds"] for p in curve["points"]]
            errors = [p[key] for p in curve["points"]]
            fit = curve[f"slope_{key}"]
            label = curve["label"] + (f"  (slope {fit['slope']:.2f})" if fit["slope"] is not None else "")
            line, = ax.loglog(times, errors, "s--" if curve.get("adaptive") else "o-", ms=3, label=label)
            if fit["slope"] is not None:
                ends = np.array([min(times), max(times)])
                ax.loglog(ends, 10 ** (fit["intercept"] + fit["slope"] * np.log10(ends)), ":", color=line.get_color())
        floor = result["reference"].get("floor", {})
        floor_value = floor.get("mse") if key == "rmse" else floor.get("relmse")
        if floor_value:
            ax.axhline(math.sqrt(floor_value) if key == "rmse" else floor_value, color="grey", lw=0.8, ls="--",
                       label="reference noise")
        if key == "relmse":
            for target in TARGETS:
                ax.axhline(target, color="k", lw=0.5, alpha=0.4)
        ax.set_xlabel("render time (s, excluding kernel build / JIT)")
        ax.set_ylabel({"rmse": "RMSE", "relmse": f"relMSE (eps = {EPS:g})"}[key])
        ax.set_title(f"{key}: Monte Carlo slope {expected_slope:g}")
        ax.grid(True, which="both", alpha=0.3)
        ax.legend(fontsize=7)
    fig.suptitle(f"{Path(result['scene']).name} {result['width']}x{result['height']}, max_depth {result['max_depth']}, "
                 f"{result['host']}")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return str(path)


def print_table(result, echo=print) -> None:
    echo(f"{'curve':<52} {'spp':>6} {'time s':>8} {'Msamp/s':>8} {'slope RMSE':>10} {'slope relMSE':>12} "
         f"{'t(1e-2) s':>10} {'t(1e-3) s':>10} {'vs CPU':>7}")
    for curve in result["curves"]:
        last = curve["points"][-1] if curve["points"] else {"spp": 0, "seconds": 0.0, "samples_per_second": None}

        def time_cell(target):
            reached = curve["time_to_relmse"][target]
            if reached["seconds"] is None:
                return "-"
            return f"{reached['seconds']:.3g}" + ("*" if reached["extrapolated"] else "")

        def slope_cell(key):
            slope = curve[key]["slope"]
            return "-" if slope is None else f"{slope:.3f}"

        rate = last.get("samples_per_second")
        speedup = curve.get("speedup_vs_cpu")
        echo(f"{curve['label'][:52]:<52} {last['spp']:>6} {last['seconds']:>8.2f} {(rate or 0) / 1e6:>8.3f} "
             f"{slope_cell('slope_rmse'):>10} {slope_cell('slope_relmse'):>12} {time_cell('0.01'):>10} "
             f"{time_cell('0.001'):>10} {(('%.2fx' % speedup['speedup']) if speedup else '-'):>7}")
    echo("* extrapolated along the fitted line")
    for curve in result["curves"]:
        for target, est in (curve.get("seed_estimate") or {}).items():
            if est["spp"] is None:
                continue
            se = f" +- {est['spp_se']:.3g}" if est["spp_se"] is not None else ""
            low, high = est["spp_range"] or (None, None)
            echo(f"{curve['label']}: relMSE {target} at {est['spp']:.4g}{se} spp, {est['seconds']:.3g} s "
                 f"({'extrapolated with c/N + floor, ' if est['extrapolated'] else ''}the mean of {est['seeds']} "
                 f"seeds; a seed alone {low:.4g} to {high:.4g} spp)")
    for curve in result["curves"]:
        gain = curve.get("adaptive_gain")
        if gain:
            echo(f"{curve['label']}: relMSE {gain['at_relmse']:g} in {gain['seconds']:.3g} s against "
                 f"{gain['plain_seconds']:.3g} s without adaptive sampling ({gain['speedup']:.2f}x)")
    for curve in result["curves"]:
        d = curve.get("denoise")
        if d and d["relmse_gain"]:
            parts = []
            for key, name in (("relmse", "relMSE"), ("rmse", "RMSE")):
                gains, stop = d[f"{key}_gain"], d[f"stops_helping_at_spp_{key}"]
                parts.append(f"{name} {gains[0]:.2g}x lower than raw at {curve['points'][0]['spp']} spp, "
                             f"{gains[-1]:.2g}x at {d['max_spp']} spp, "
                             + (f"no gain from {stop} spp" if stop else "a gain at every spp"))
            echo(f"{curve['label']}: " + "; ".join(parts))
