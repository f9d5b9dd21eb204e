"""The spp to a relMSE target of a curve rendered with several seeds (``bench set``, ``bench
convergence --seeds``; pyopencl_rt/bench/convergence_analysis.py): on synthetic curves whose answer
is known, the estimate recovers it within its stated tolerance, its standard error covers the
truth as often as a standard error should, and the reference's floor counts as it does in the
curves' own times.  Our renders with different seeds differ, and a reseeded engine renders what a
fresh one of that seed does."""
import math

import numpy as np
import pytest

from pyopencl_rt.bench.convergence_analysis import (mean_points, ratio_se, reach, seed_estimate, seed_runs,
                                                    spp_schedule)

TARGET = 1e-3


def synthetic_runs(rng, *, c, seeds, max_spp, floor=0.0, sigma=0.25, jitter=0.02, seconds_per_spp=0.01):
    """``seeds`` progressive curves relMSE(N) = c / N x (the seed's luck) + floor: the luck a
    mean-one lognormal factor per seed (sigma: one render's spread, about that of our scenes'),
    with a small independent jitter per point; the expected relMSE is c / N + floor exactly."""
    runs = []
    for _ in range(seeds):
        luck = math.exp(sigma * rng.standard_normal() - sigma ** 2 / 2)
        points = []
        for n in spp_schedule(max_spp):
            wobble = math.exp(jitter * rng.standard_normal() - jitter ** 2 / 2)
            points.append({"spp": n, "seconds": n * seconds_per_spp * (1 + 0.05 * rng.random()),
                           "relmse": c / n * luck * wobble + floor, "rmse": 0.1, "mae": 0.05})
        runs.append(points)
    return runs


def test_exact_curve_is_recovered_measured_and_extrapolated():
    """No noise: where the curve crosses the target the interpolation is exact (c / N is a line in
    log-log); past its last point the model c / N is exact too, marked extrapolated."""
    c = 3.0  # the target at N = 3000
    exact = [[{"spp": n, "seconds": 0.01 * n, "relmse": c / n} for n in spp_schedule(8192)]]
    est = seed_estimate(exact, TARGET)
    assert est["spp"] == pytest.approx(3000, rel=1e-9) and not est["extrapolated"]
    assert est["seconds"] == pytest.approx(30.0, rel=1e-9) and est["relmse_x_spp"] == pytest.approx(c)
    assert est["seeds"] == 1 and est["spp_se"] is None and est["spp_range"] == [est["spp"], est["spp"]]
    short = [[p for p in exact[0] if p["spp"] <= 512]]
    est = seed_estimate(short, TARGET)
    assert est["extrapolated"] and est["spp"] == pytest.approx(3000, rel=1e-9)
    assert est["seconds"] == pytest.approx(30.0, rel=1e-9)


def test_reference_floor_counts_in_as_in_the_curves_times():
    """The relMSE measured against a noisy reference is c / N + floor: the target is reached at
    c / (target - floor), not at c / target; not at all when it is not above the floor."""
    c, floor = 3.0, 3e-4
    runs = [[{"spp": n, "seconds": 0.01 * n, "relmse": c / n + floor} for n in spp_schedule(1024)]]
    est = seed_estimate(runs, TARGET, floor)
    assert est["extrapolated"] and est["spp"] == pytest.approx(c / (TARGET - floor), rel=1e-9)
    assert est["relmse_x_spp"] == pytest.approx(c)  # the error per sample, the floor taken off
    runs = [[{"spp": n, "seconds": 0.01 * n, "relmse": c / n + floor} for n in spp_schedule(16384)]]
    measured = seed_estimate(runs, TARGET, floor)
    assert not measured["extrapolated"]
    assert measured["spp"] == pytest.approx(c / (TARGET - floor), rel=0.02)  # log-log interpolation of c/N + floor
    unreachable = seed_estimate(runs, 2e-4, floor)
    assert unreachable["spp"] is None and unreachable["seconds"] is None


@pytest.mark.parametrize("max_spp, extrapolated", [(8192, False), (1024, True)])
def test_noisy_seeds_recover_the_spp_at_the_target(max_spp, extrapolated):
    """200 synthetic experiments of 8 seeds, each seed's relMSE off by a lognormal luck of 25%
    (the spread of one render of our scenes' curves), with the reference's floor at 10% of the
    target: the mean estimate is within 3% of the true c / (target - floor) (the estimator is
    nearly unbiased), a single experiment within 35% (4 standard errors: the lognormal luck has a
    long upper tail), the bootstrap standard error (about 9% here) matches the experiments' own
    spread within a factor 1.5, and the truth lies within two standard errors of the estimate in
    at least 80% of the experiments (95% for a normal estimate with a known error; the
    bootstrap's error of 8 seeds is itself noisy and a little low, by sqrt(7/8); 88-93% here)."""
    rng = np.random.default_rng(7)
    c, floor, seeds = 3.0, 1e-4, 8
    truth = c / (TARGET - floor)
    estimates, ses, covered = [], [], 0
    for _ in range(200):
        est = seed_estimate(synthetic_runs(rng, c=c, seeds=seeds, max_spp=max_spp, floor=floor), TARGET, floor,
                            bootstrap=200)
        assert est["extrapolated"] is extrapolated and est["seeds"] == seeds
        assert abs(est["spp"] / truth - 1) < 0.35
        low, high = est["spp_range"]
        assert low <= est["spp"] <= high and len(est["per_seed"]) == seeds
        estimates.append(est["spp"])
        ses.append(est["spp_se"])
        covered += abs(est["spp"] - truth) <= 2 * est["spp_se"]
    estimates = np.array(estimates)
    assert abs(estimates.mean() / truth - 1) < 0.03
    assert 1 / 1.5 < np.mean(ses) / estimates.std(ddof=1) < 1.5
    assert covered >= 0.8 * len(estimates)


def test_more_seeds_narrow_the_standard_error():
    """The standard error falls as 1 / sqrt(seeds): 16 seeds about half that of 4."""
    rng = np.random.default_rng(3)
    se = {k: np.mean([seed_estimate(synthetic_runs(rng, c=2.0, seeds=k, max_spp=4096), TARGET,
                                    bootstrap=200)["spp_se"] for _ in range(40)]) for k in (4, 16)}
    assert 0.35 < se[16] / se[4] < 0.7


def test_bootstrap_is_deterministic_and_one_lucky_seed_shows():
    """The same runs give the same spread; a lucky seed (a third of the others' error) moves the
    estimate by a fraction of what it moves one render's and widens the range to show it."""
    runs = [[{"spp": n, "seconds": 0.01 * n, "relmse": c / n} for n in spp_schedule(8192)] for c in (3, 3, 3, 1)]
    first, again = seed_estimate(runs, TARGET), seed_estimate(runs, TARGET)
    assert first == again
    assert first["spp"] == pytest.approx(2500, rel=1e-9)  # the mean c, 2.5
    assert first["spp_range"] == [pytest.approx(1000), pytest.approx(3000)]
    assert first["spp_se"] > 0 and first["bootstrap"]["without_estimate"] == 0


def test_mean_points_over_the_spp_every_seed_reached():
    a = [{"spp": n, "seconds": 1.0 * n, "relmse": 1.0 / n, "rmse": 0.3, "mae": 0.1, "samples_per_second": 4.0}
         for n in (1, 2, 4)]
    b = [{"spp": n, "seconds": 3.0 * n, "relmse": 3.0 / n, "rmse": 0.4, "mae": 0.3, "samples_per_second": 1.0}
         for n in (1, 2)]
    points = mean_points([a, b], pixels=4)
    assert [p["spp"] for p in points] == [1, 2]
    first = points[0]
    assert first["seconds"] == pytest.approx(2.0) and first["relmse"] == pytest.approx(2.0)
    assert first["rmse"] == pytest.approx(math.sqrt((0.09 + 0.16) / 2)) and first["mae"] == pytest.approx(0.2)
    assert first["samples_per_second"] == pytest.approx(1 * 4 / 2.0)
    assert first["relmse_sd"] == pytest.approx(np.std([1.0, 3.0], ddof=1)) and first["seeds"] == 2
    assert mean_points([a], pixels=4) == a
    # a time is the median over seeds: one render that paid a compilation does not move it
    c = [{**p, "seconds": p["seconds"] + 5.0} for p in a]
    assert [p["seconds"] for p in mean_points([a, a, c], pixels=4)] == [1.0, 2.0, 4.0]
    assert seed_runs({"points": a}) == [a]  # a curve of a JSON written before seeds: one seed
    assert seed_runs({"points": points, "seed_curves": [{"seed": 1, "points": a}, {"seed": 2, "points": b}]}) == [a, b]


def test_ratio_standard_error():
    assert ratio_se(2.0, 0.2, 1.0, 0.1) == pytest.approx(2.0 * math.sqrt(0.01 + 0.01))
    assert ratio_se(2.0, None, 1.0, 0.1) is None and ratio_se(None, 0.1, 1.0, 0.1) is None


def test_reach_before_the_first_point_uses_the_model():
    est = reach([4, 8], [5e-4, 2.5e-4], [1.0, 2.0], TARGET)
    assert est["extrapolated"] and est["spp"] == pytest.approx(2.0)


# -- the seeds really differ ----------------------------------------------------------------------

def test_our_curve_over_seeds_renders_each_seed(device):
    """run_curve with three seeds: a film per seed, their errors differ at every spp, the curve's
    points are their mean; and a reseeded engine renders what a fresh one of that seed does."""
    from pyopencl_rt import load_scene
    from pyopencl_rt.bench.convergence import run_curve
    from pyopencl_rt.render.api import render_full
    from pyopencl_rt.render.film import Film
    from pyopencl_rt.render.wavefront import Wavefront

    scene = load_scene("scenes/cornell-box.toml")
    reference = render_full(scene, spp=64, device=device, seed=99, width=8, height=8, max_depth=3).image
    curve = run_curve(scene, device=device, integrator="path", intersector="opencl", width=8, height=8, max_depth=3,
                      rr_depth=scene.settings.rr_depth, reference=reference, seconds=2.0, seeds=[1, 2, 3], echo=print)
    runs = curve["seed_curves"]
    assert [r["seed"] for r in runs] == [1, 2, 3] and curve["seeds"] == [1, 2, 3]
    spp = [p["spp"] for p in curve["points"]]
    assert spp and all([p["spp"] for p in r["points"]][:len(spp)] == spp for r in runs)
    for i in range(len(spp)):
        errors = [r["points"][i]["relmse"] for r in runs]
        assert len(set(errors)) == 3, (spp[i], errors)
        assert curve["points"][i]["relmse"] == pytest.approx(np.mean(errors))
    wavefront = Wavefront(scene, device, width=8, height=8, max_depth=3, seed=1)
    wavefront.reseed(2)
    film = Film.new(8, 8)
    wavefront.run(film, passes=4)
    fresh = render_full(scene, spp=4, device=device, seed=2, width=8, height=8, max_depth=3).image
    assert np.array_equal(film.image(), fresh)
