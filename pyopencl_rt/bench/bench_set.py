"""``pyopencl-rt bench set``: the benchmark set against Mitsuba 3 (issue 23), in one run.

For each scene of the set (by default :data:`DEFAULT_SCENES`: Mitsuba's Cornell box, the box with a
glass and a rough gold sphere, a textured scene under an environment map, a scene of every
material type Mitsuba renders the same, smooth, rough and thin glass on a plane under an
environment map, issue 34's caustics, one Mitsuba XML file, a hall lit by 3072 small lamps (issue 34's
many lights, our light BVH), the Cornell box with fog, a medium in glass and smoke (against
Mitsuba's volpath), and a textured height field of a million triangles, written on first use into
the bench cache (:data:`GENERATED`)), Mitsuba renders the very same scene, exported by
:mod:`.mitsuba_export`, and the set reports:

* **samples/s**, ours and Mitsuba's, timed in turns (:mod:`.render`: one persistent Mitsuba process
  per scene, warmed up, a render of each after the other in every round) at ``size`` x ``size``,
  and their ratio: the median of the rounds' ratios; with the lane width our kernels ran and why;
* **time to relMSE 1e-3** (:data:`TARGET`), ours (the scene's sampler, Sobol by default) against
  Mitsuba's best sampler: the curves of ``bench convergence --compare mitsuba`` (:mod:`.convergence`)
  at ``error_size`` x ``error_size`` against one reference of ours (independent samples,
  ``reference_spp``), with a curve for each of Mitsuba's ``mitsuba_samplers``.  Each curve is
  rendered with ``seeds`` seeds (ours: the seed of the render, 1 + ``first_seed`` + k; Mitsuba's:
  the ``seed`` of ``mi.render``, from ``(first_seed + k) x 1000003`` up), its share of the budget
  split between them, and the spp and time to the target are estimated on the **mean over the
  seeds of the relMSE** at each spp (:func:`.convergence_analysis.seed_estimate`): where that mean
  crosses the target, interpolated between the points that bracket it (measured); otherwise from
  the Monte Carlo model relMSE = c / N + floor fitted on the last two octaves of spp (extrapolated,
  marked so), ``floor`` being the relMSE that the reference's own noise adds to every measurement
  (counted in, as in the curves' own times: it lengthens every curve's time alike; a target
  within 4x of it is marked).  The spread: the standard error of each estimate over resamples of
  its seeds (a bootstrap), and the range of the seeds alone; a ratio's standard error from its two
  independent estimates'.  Mitsuba's best is the sampler whose time is shortest (a measured time
  before an extrapolated one): picked after the fact among five, so a best within its standard
  errors of another sampler's is no better than it.  The curves run one after the other, so a
  change of the machine's load between two of them moves the ratio of their times; the ratio
  "in turns" beside it does not: our spp to the target and that of the sampler of Mitsuba's that
  needed fewest, with the ratio of samples/s measured in turns above (Mitsuba's independent
  sampler's).

The references are rendered first, each once (they are cached, see :mod:`.convergence`), so that
every scene's ``budget`` goes to its curves.  The JSON holds the table's rows, the render bench's
results and, per scene, the convergence JSON written beside it (``<json stem>-<scene>.json``, with
its plot).
"""
from __future__ import annotations

import time
from pathlib import Path

from ..errors import UsageError
from .mitsuba_host import DEFAULT_VARIANT, require_mitsuba_python
from .timing import machine_info, write_results

SCHEMA = "pyopencl_rt.bench_set/1"
# Scenes too large to keep in scenes/, written by scale_scene.write_scene into the bench cache when a
# set names them: issue 34's textured mesh of at least a million triangles (1,011,042)
GENERATED = {"generated:textured-heightfield-1m": dict(triangles=1.01e6, textured=True)}
DEFAULT_SCENES = ("scenes/mitsuba-cbox.toml", "scenes/mitsuba-cbox-spheres.toml", "scenes/textured-sky.toml",
                  "scenes/materials.toml", "scenes/glass-env.xml", "scenes/many-lights.toml", "scenes/cornell-fog.toml",
                  "generated:textured-heightfield-1m")


def scene_path(name) -> str:
    """The file of a set's scene: ``name`` itself, or a :data:`GENERATED` scene's XML, written
    into the bench cache (``$PYOPENCL_RT_CACHE/scenes``) the first time."""
    if str(name) not in GENERATED:
        return str(name)
    from .convergence import cache_dir
    from .scale_scene import write_scene

    return str(write_scene(cache_dir().parent / "scenes", **GENERATED[str(name)]))
TARGET = 1e-3
DEFAULT_SEEDS = 4  # each curve's renders: its share of the budget is split between them


def run_bench_set(scene_paths=DEFAULT_SCENES, *, devices=None, size=256, spp=64, repeat=5, error_size=64,
                  budget=150.0, reference_spp=16384, mitsuba_samplers=None, mitsuba_python=None, llvm_path=None,
                  mitsuba_variant=DEFAULT_VARIANT, seeds=DEFAULT_SEEDS, first_seed=0, json_path=None,
                  echo=print) -> dict:
    """The set (see the module docstring) on one device; returns what the JSON holds."""
    from ..device.devices import device_label, resolve
    from ..render.settings import ImageSettings
    from ..scene.loaders import load_scene
    from .convergence import MITSUBA_SAMPLERS, load_or_render_reference, run_convergence
    from .render import check_exportable, run_render_bench

    start = time.perf_counter()
    paths = [scene_path(p) for p in scene_paths]
    chosen = resolve(devices)
    if len(chosen) > 1:
        raise UsageError("bench set runs on one device")
    mitsuba_samplers = sampler_names(mitsuba_samplers or MITSUBA_SAMPLERS, MITSUBA_SAMPLERS)
    require_mitsuba_python(mitsuba_python, mitsuba_variant, llvm_path, echo)
    scenes = {path: load_scene(path) for path in paths}
    for path, scene in scenes.items():  # before minutes of timing: every scene must export
        check_exportable(path, scene, ImageSettings.resolve(scene, width=error_size, height=error_size))
    mitsuba = dict(mitsuba_python=mitsuba_python, llvm_path=llvm_path, variant=mitsuba_variant)

    echo(f"== samples/s at {size}x{size}, {spp} spp, {repeat} rounds, Mitsuba taking turns")
    render = run_render_bench(paths, devices=chosen, width=size, height=size, spp=spp, max_depth=None,
                              repeat=repeat, mitsuba=mitsuba, echo=echo)

    echo(f"== references at {error_size}x{error_size}, {reference_spp} spp (cached once rendered)")
    for path, scene in scenes.items():
        st = scene.settings
        load_or_render_reference(scene, path, width=error_size, height=error_size, max_depth=st.max_depth,
                                 rr_depth=st.rr_depth, device=chosen[0], spp=reference_spp, echo=echo)

    base = Path(json_path) if json_path else Path("out/bench-set.json")
    convergence = []
    for path in paths:
        echo(f"== time to relMSE {TARGET:g}: {path}, {budget:g} s of curves at {error_size}x{error_size}, "
             f"{seeds} seed{'s' if seeds > 1 else ''} each")
        out = base.with_name(f"{base.stem}-{Path(path).stem}.json")
        result = run_convergence(path, devices=chosen, reference_spp=reference_spp, budget=budget,
                                 width=error_size, height=error_size, compare=("mitsuba",),
                                 mitsuba_python=mitsuba_python, mitsuba_variant=mitsuba_variant, llvm_path=llvm_path,
                                 mitsuba_samplers=mitsuba_samplers, seeds=seeds, first_seed=first_seed, json_path=out,
                                 echo=echo)
        convergence.append(convergence_summary(result, out))
    rows = set_rows(render["summary"], convergence)
    results = {"schema": SCHEMA, "target_relmse": TARGET, "device": device_label(chosen[0]),
               "settings": {"size": size, "spp": spp, "repeat": repeat, "error_size": error_size, "budget": budget,
                            "reference_spp": reference_spp, "mitsuba_samplers": list(mitsuba_samplers),
                            "seeds": seeds, "first_seed": first_seed,
                            "mitsuba_variant": mitsuba_variant},
               "machine": machine_info(), "rows": rows, "render": render, "convergence": convergence,
               "total_seconds": time.perf_counter() - start}
    echo("")
    print_set_table(rows, echo)
    if json_path:
        write_results(json_path, results, echo)
    return results


def sampler_names(names, allowed) -> tuple:
    """Mitsuba's samplers from a comma-separated string or a sequence; one line for an unknown one."""
    names = [n.strip() for n in (names.split(",") if isinstance(names, str) else names) if n.strip()]
    for name in names:
        if name not in allowed:
            raise UsageError(f"unknown Mitsuba sampler {name!r}: use one or more of {', '.join(allowed)}")
    return tuple(names)


def convergence_summary(result: dict, json_path) -> dict:
    """Per scene: each curve's samples/s and its spp and time to :data:`TARGET` with their spread
    over seeds (:func:`.convergence_analysis.seed_estimate`: on the mean over the curve's seeds of
    the relMSE at each spp, measured where that mean crosses the target, else extrapolated with
    relMSE = c / N + the reference's floor; the standard error by resampling the seeds, the range
    of the seeds alone), ours (the first of our curves) and Mitsuba's best (the shortest time among
    its samplers' curves that reached the target, else among their extrapolations).  A curve's spp
    to the target does not depend on how busy the machine was while the curve ran.  A curve of a
    JSON written before seeds is one seed: the same estimate, without a standard error."""
    from .convergence_analysis import FLOOR_FACTOR, seed_estimate, seed_runs

    floor = (result["reference"].get("floor") or {}).get("relmse")
    curves = []
    for curve in result["curves"]:
        last = curve["points"][-1] if curve["points"] else {}
        est = seed_estimate(seed_runs(curve), TARGET, floor)
        curves.append({"label": curve["label"], "renderer": curve["renderer"], "sampler": curve.get("sampler"),
                       "samples_per_second": last.get("samples_per_second"), "spp": last.get("spp"),
                       "elapsed": last.get("seconds"), "seeds": est["seeds"],
                       "time_to_target": est["seconds"], "extrapolated": est["extrapolated"],
                       "below_reference_floor": bool(floor is not None and TARGET < FLOOR_FACTOR * floor),
                       "spp_to_target": est["spp"], "time_to_target_se": est["seconds_se"],
                       "spp_to_target_se": est["spp_se"], "time_to_target_range": est["seconds_range"],
                       "spp_to_target_range": est["spp_range"], "relmse_x_spp": est["relmse_x_spp"],
                       "relmse_x_spp_per_seed": [r["relmse_x_spp"] for r in est["per_seed"]]})
    ours = next((c for c in curves if c["renderer"] == "pyopencl_rt"), None)
    # measured times first: a curve's line extrapolated beyond its last point is a guess
    theirs = [c for c in curves if c["renderer"] == "mitsuba" and c["time_to_target"]]
    best = min(theirs, key=lambda c: (c["extrapolated"], c["time_to_target"]), default=None)
    fewest = min(theirs, key=lambda c: (c["extrapolated"], c["spp_to_target"]), default=None)
    return {"scene": result["scene"], "json": str(json_path), "plot": result.get("plot"),
            "width": result["width"], "height": result["height"], "seeds": result.get("seeds", 1),
            "reference": {k: result["reference"].get(k) for k in ("spp", "seconds", "source", "floor")},
            "curves": curves, "ours": ours, "mitsuba_best": best, "mitsuba_fewest_spp": fewest}


def set_rows(render_summary, convergence) -> list[dict]:
    """The table: a row per scene (and variant) of the render bench, with its scene's times to the
    target and their ratio, measured (``mitsuba_time_over_ours``, against the sampler of Mitsuba's
    that got there first: the curves ran one after the other, so a change of load between them
    moves it) and from the interleaved samples/s (``mitsuba_time_over_ours_interleaved``: the spp
    to the target of the sampler of Mitsuba's that needed fewest over ours, times our samples/s
    over Mitsuba's as the render bench measured them in turns, its independent sampler's).  Each
    has its standard error over seeds (``*_se``; a ratio's from its two estimates', which are
    independent: :func:`.convergence_analysis.ratio_se`), each time its range over single seeds."""
    from .convergence_analysis import ratio_se

    by_scene = {c["scene"]: c for c in convergence}
    rows = []
    for row in render_summary:
        conv = by_scene.get(row["scene"], {})
        ours, best = conv.get("ours") or {}, conv.get("mitsuba_best") or {}
        fewest = conv.get("mitsuba_fewest_spp") or {}
        t_ours, t_theirs = ours.get("time_to_target"), best.get("time_to_target")
        spp_ours, spp_theirs, ratio = ours.get("spp_to_target"), fewest.get("spp_to_target"), row["ratio_to_mitsuba"]
        spp_ratio_se = ratio_se(spp_theirs, fewest.get("spp_to_target_se"), spp_ours, ours.get("spp_to_target_se"))
        rows.append({**row, "seeds": conv.get("seeds", 1), "ours_sampler": ours.get("sampler"),
                     "time_to_target": t_ours, "time_to_target_se": ours.get("time_to_target_se"),
                     "time_to_target_range": ours.get("time_to_target_range"),
                     "time_to_target_extrapolated": ours.get("extrapolated"), "spp_to_target": spp_ours,
                     "spp_to_target_se": ours.get("spp_to_target_se"),
                     "mitsuba_best_sampler": best.get("sampler"), "mitsuba_time_to_target": t_theirs,
                     "mitsuba_time_to_target_se": best.get("time_to_target_se"),
                     "mitsuba_time_to_target_range": best.get("time_to_target_range"),
                     "mitsuba_time_to_target_extrapolated": best.get("extrapolated"),
                     "mitsuba_spp_to_target": best.get("spp_to_target"),
                     "mitsuba_fewest_spp_sampler": fewest.get("sampler"), "mitsuba_fewest_spp_to_target": spp_theirs,
                     "mitsuba_fewest_spp_to_target_se": fewest.get("spp_to_target_se"),
                     "mitsuba_time_over_ours": t_theirs / t_ours if t_theirs and t_ours else None,
                     "mitsuba_time_over_ours_se": ratio_se(t_theirs, best.get("time_to_target_se"), t_ours,
                                                           ours.get("time_to_target_se")),
                     "mitsuba_time_over_ours_interleaved": (spp_theirs / spp_ours * ratio
                                                            if spp_theirs and spp_ours and ratio else None),
                     "mitsuba_time_over_ours_interleaved_se": spp_ratio_se * ratio if spp_ratio_se and ratio else None,
                     "near_floor": bool(ours.get("below_reference_floor"))})
    return rows


def rows_again(json_path, echo=print) -> dict:
    """The rows of a set's JSON derived again from what it measured (its render results and the
    convergence JSONs beside it), and the table printed: for a table whose derived columns
    changed after the run.  The JSON is rewritten."""
    import json

    from ..imageio import write_json

    results = json.loads(Path(json_path).read_text())
    convergence = [convergence_summary(json.loads(Path(c["json"]).read_text()), c["json"])
                   for c in results["convergence"]]
    results.update(convergence=convergence, rows=set_rows(results["render"]["summary"], convergence))
    write_json(json_path, results)
    print_set_table(results["rows"], echo)
    return results


def print_set_table(rows, echo=print) -> None:
    from .render import lanes_text

    def seconds(value, se, extrapolated, floor):
        if value is None:
            return "-"
        return (f"{value:.3g}" + (f"+-{se:.2g}" if se is not None else "") + ("*" if extrapolated else "")
                + ("!" if floor else ""))

    def times(value, se=None):
        return f"{value:.2f}x" + (f"+-{se:.2f}" if se is not None else "") if value else "-"

    width = max([len("scene")] + [len(r["scene"]) for r in rows])
    echo(f"{'scene':<{width}} {'ours Ms/s':>9} {'Mitsuba':>8} {'ratio':>6} {'lanes':>7} {'seeds':>5} "
         f"{'t ours s':>14} {'t Mitsuba s':>14} {'(sampler)':<13} {'Mi/ours t':>11} {'(turns)':>11} {'(sampler)':<13}")
    for r in rows:
        ours_t = seconds(r["time_to_target"], r.get("time_to_target_se"), r["time_to_target_extrapolated"],
                         r["near_floor"])
        theirs_t = seconds(r["mitsuba_time_to_target"], r.get("mitsuba_time_to_target_se"),
                           r["mitsuba_time_to_target_extrapolated"], r["near_floor"])
        theirs = r["mitsuba_samples_per_second"]
        echo(f"{r['scene']:<{width}} {r['samples_per_second'] / 1e6:9.3f} "
             f"{f'{theirs / 1e6:.3f}' if theirs else '-':>8} {times(r['ratio_to_mitsuba']):>6} {lanes_text(r):>7} "
             f"{r.get('seeds', 1):5d} {ours_t:>14} {theirs_t:>14} {'(' + (r['mitsuba_best_sampler'] or '-') + ')':<13} "
             f"{times(r['mitsuba_time_over_ours'], r.get('mitsuba_time_over_ours_se')):>11} "
             f"{times(r['mitsuba_time_over_ours_interleaved'], r.get('mitsuba_time_over_ours_interleaved_se')):>11} "
             f"{'(' + (r['mitsuba_fewest_spp_sampler'] or '-') + ')':<13}")
    echo(f"Ms/s: Msamples/s; ratio: ours / Mitsuba's, the median of the rounds' ratios; t: time to relMSE {TARGET:g} "
         "of the mean over seeds of the relMSE (ours: the scene's sampler; Mitsuba: its best sampler), +- its standard "
         "error over seeds (resampled); * extrapolated with relMSE = c/N + the reference's noise; "
         "! the target is within 4x of the reference's own noise; Mi/ours t > 1: we reach it sooner, as measured "
         "and (turns) from the spp to the target, ours and that of Mitsuba's sampler that needed fewest, and the "
         "ratio of samples/s measured in turns; +- the ratio's standard error from the two times'")
