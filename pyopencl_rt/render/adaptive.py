"""Adaptive sampling: samples go where the estimated error is, converged pixels stop.

``--adaptive`` (``ImageSettings.adaptive``) renders in batches (docs/SAMPLING.md, "Adaptive
sampling"):

* **First**: every pixel takes ``MIN_SPP`` samples, in two batches of half that.
* **The estimate**: after each batch, a pixel's relative error is estimated as
  ``sqrt(mean over RGB of var / n / (mean^2 + eps))``, with eps = 1e-2 as relMSE has it
  (:data:`pyopencl_rt.compare.REL_EPS`): the square is the pixel's expected share of the image's
  relMSE.  ``var`` and ``mean`` are those of the pixel's samples *before its last batch* (a
  snapshot taken when the batch started), ``n`` its samples now: the newest half of a pixel's
  samples never decides whether the pixel stops, so that it stays independent of that decision
  (Cycles estimates its error from a half buffer for the same reason).
* **Where samples go**: a pixel whose error is above ``target_error`` doubles its samples in the
  next batch (never beyond ``max_spp``); once below it, a pixel has stopped for good.  A pixel's
  error is the largest of its 3 x 3 neighbourhood's (:func:`neighbourhood_max`): a pixel whose
  first samples all missed its rare bright paths looks converged on its own, and stopping it
  would bias the image dark; its neighbours have usually seen such paths.  When no target is
  given, or every pixel has reached it and time is left (``time_limit``), the next batch refines
  the pixels where a sample removes the most error: the largest ``err^2 / n`` (a pixel's error
  falls as 1/n), those that together hold half of the sum, each doubling its samples.
* **How long**: until every pixel reaches the target or ``max_spp``, or ``time_limit`` is up.
  Without a target ``max_spp`` is a budget instead: the render stops after ``max_spp`` samples
  per pixel *on average* (no pixel is capped), as a non-adaptive render of that spp takes.
* **Lockstep passes**: a batch starts at the film's pass count ``p``; a pixel that takes ``m``
  samples in it takes passes ``p .. p + m - 1`` (each pass a run of :meth:`Wavefront.run` over the
  pixels still going, ``pixel_list`` in the kernels), so a pixel's sample index is the pass index
  and the samplers need nothing per pixel.  Until a pixel stops its passes are 0 .. n - 1, so a
  pixel that stops on the target holds 32 x 2^k consecutive passes: a Sobol net.  A pixel refined
  later (time left) takes its runs where the pass count is, nets only when they are aligned.

The same seed, ``max_spp`` and target give the same image on one device (the decisions are made
on the film's float64 sums, which do not depend on the order of the atomics).
"""
from __future__ import annotations

import time

import numpy as np

from ..compare import REL_EPS
from .film import Film, RunStats

MIN_SPP = 32  # the first samples of every pixel (two batches of 16) before any pixel may stop
NEIGHBOURHOOD = 1  # a pixel's error is the largest of its 3 x 3 neighbourhood (neighbourhood_max)
REFINE_SHARE = 0.5  # a refining batch takes the pixels that hold this share of err^2 / n


def relative_error(sum, sum_sq, n_est, n_now) -> np.ndarray:
    """Per pixel: sqrt(mean over RGB of var / n_now / (mean^2 + eps)), mean and var of the n_est
    samples whose sums are given; +inf for a pixel of fewer than 2."""
    n = np.asarray(n_est, np.float64)[:, None]
    with np.errstate(divide="ignore", invalid="ignore"):
        mean = sum / n
        var = np.maximum(sum_sq / n - mean * mean, 0.0) * n / (n - 1)
        rel2 = (var / np.asarray(n_now, np.float64)[:, None] / (mean * mean + REL_EPS)).mean(axis=1)
    return np.where(n[:, 0] >= 2, np.sqrt(rel2), np.inf)


def neighbourhood_max(err, width, height, radius=1) -> np.ndarray:
    """Each pixel's largest error over the (2 radius + 1)^2 pixels around it (P,): a pixel stops
    only when its neighbours have converged too, as Cycles dilates its unconverged pixels."""
    image = err.reshape(height, width)
    padded = np.pad(image, radius, mode="edge")
    out = image.copy()
    for dy in range(2 * radius + 1):
        for dx in range(2 * radius + 1):
            np.maximum(out, padded[dy:dy + height, dx:dx + width], out=out)
    return out.ravel()


def film_error(film: Film) -> np.ndarray:
    """The relative error of each pixel's mean (H x W) from all its samples: what the target means."""
    counts = film.pixel_counts()
    return relative_error(film.sum, film.sum_sq, counts, counts).reshape(film.height, film.width)


def next_batch(err, counts, target_error, refine: bool, max_spp, stopped=None) -> np.ndarray:
    """Samples each pixel takes in the next batch (P, int64; 0: it stops): its count again (at
    most up to ``max_spp``) for a pixel above the target and not ``stopped`` (True where a pixel
    has been below it); with ``refine`` and none above it, for the pixels of largest err^2 / n
    that hold REFINE_SHARE of the sum, stopped or not."""
    room = np.full(len(counts), np.iinfo(np.int64).max // 4) if max_spp is None else np.maximum(max_spp - counts, 0)
    chosen = np.zeros(0, np.int64)
    if target_error is not None:
        going = (err > target_error) & (room > 0)
        chosen = np.flatnonzero(going if stopped is None else going & ~stopped)
    if not len(chosen) and refine:
        with np.errstate(divide="ignore", invalid="ignore"):
            unknown = np.finfo(np.float64).max / 4 / len(err)  # fewer than 2 samples: first
            gain = np.where(np.isfinite(err), err * err / np.maximum(counts, 1), unknown)
        gain[room <= 0] = 0.0
        order = np.argsort(-gain, kind="stable")
        total = np.cumsum(gain[order])
        if total[-1] > 0:
            k = int(np.searchsorted(total, REFINE_SHARE * total[-1])) + 1
            chosen = order[:k][gain[order[:k]] > 0]
    take = np.zeros(len(counts), np.int64)
    take[chosen] = np.minimum(np.maximum(counts[chosen], 1), room[chosen])  # doubling
    return take


def run(wf, film: Film, *, target_error=None, max_spp=None, time_limit=None, progress=None, profile=False,
        cancel=None, observe=None, stops=(), min_spp=MIN_SPP) -> tuple[RunStats, dict]:
    """Render ``film`` (empty) adaptively on ``wf`` (a :class:`~pyopencl_rt.render.wavefront.Wavefront`)
    until every pixel reaches ``target_error`` or ``max_spp`` samples, or ``time_limit`` seconds
    pass (then refining the worst pixels until they do); see the module docstring.

    ``progress(passes, seconds)`` as :meth:`Wavefront.run` calls it; ``observe(film, seconds)`` is
    called whenever the film's pass count reaches one of ``stops`` (and at the end), with the
    render's time so far (a convergence curve's points; its own time is not counted).  Returns
    the statistics and a record of the run for the sidecar."""
    if max_spp is None and time_limit is None:
        raise ValueError("give max_spp, time_limit or both")
    if film.passes:
        raise ValueError("adaptive sampling starts from an empty film")
    n_pixels = film.width * film.height
    stops = sorted(set(int(s) for s in stops))
    stats = RunStats()
    start = time.perf_counter()
    refine = time_limit is not None or target_error is None
    first = min_spp if max_spp is None else min(min_spp, max_spp)
    budget = None
    if target_error is None and max_spp is not None:  # a mean, not a cap
        budget, max_spp = int(max_spp) * n_pixels, None
    take = np.full(n_pixels, max(1, first // 2), np.int64)  # the first batch; then its second half
    snapshot = (film.sum.copy(), film.sum_sq.copy(), film.pixel_counts().copy())
    batches, observed, paused = [], set(), [0.0]
    stopped = np.zeros(n_pixels, bool)

    def elapsed():
        return time.perf_counter() - start - paused[0]

    def look():
        observed.add(film.passes)
        t0 = time.perf_counter()
        observe(film, elapsed())
        paused[0] += time.perf_counter() - t0

    def tick(passes, seconds, base=0, t0=0.0):
        if progress is not None:
            progress(base + passes, t0 + seconds)

    while take.any():
        p0 = film.passes
        batches.append({"first_pass": p0, "pixels": int(np.count_nonzero(take)), "samples": int(take.sum())})
        # the batch: passes p0 .. p0 + max(take) - 1, each over the pixels whose take reaches it
        for run_start, run_end, pixels in _runs(take, p0, stops):
            left = None if time_limit is None else time_limit - elapsed()
            if left is not None and left <= 0:
                break
            t0 = elapsed()
            st = wf.run(film, passes=run_end - run_start, time_limit=left, first_pass=run_start,
                        pixels=None if len(pixels) == n_pixels else pixels, profile=profile, cancel=cancel,
                        progress=lambda passes, seconds, b=run_start, t=t0: tick(passes, seconds, b, t))
            _merge(stats, st)
            if observe is not None and film.passes in stops and film.passes not in observed:
                look()
            if st.interrupted or film.passes < run_end:
                break
        else:
            counts = film.pixel_counts()
            if counts.min() < first:  # the first batch: every pixel takes its second half
                take = np.where(counts < first, first - counts, 0)
                snapshot = (film.sum.copy(), film.sum_sq.copy(), counts.copy())
                continue
            err = neighbourhood_max(relative_error(snapshot[0], snapshot[1], snapshot[2], counts), film.width,
                                    film.height, NEIGHBOURHOOD)
            if target_error is not None:  # below the target once: stopped for good (but refined with time left)
                stopped |= err <= target_error
            take = next_batch(err, counts, target_error, refine, max_spp, stopped)
            if budget is not None:
                take = _within(take, err * err / np.maximum(counts, 1), budget - int(counts.sum()))
            # the next estimate: each pixel's sums as its next batch starts
            snapshot = (film.sum.copy(), film.sum_sq.copy(), counts.copy())
            continue
        break
    stats.seconds = elapsed()
    if observe is not None and film.passes not in observed and film.passes:
        look()
    counts = film.pixel_counts()
    err = film_error(film).ravel()
    record = {
        "batches": len(batches),
        "spp_min": int(counts.min()), "spp_mean": float(counts.mean()), "spp_max": int(counts.max()),
        "converged_fraction": None if target_error is None else float(np.mean(err <= target_error)),
        "estimated_relmse": float(np.mean(np.where(np.isfinite(err), err * err, 0.0))),
    }
    return stats, record


def _within(take, gain, left) -> np.ndarray:
    """``take`` cut to ``left`` samples in all: the pixels of largest gain keep theirs."""
    if take.sum() <= left:
        return take
    take = take.copy()
    if left <= 0:
        take[:] = 0
        return take
    chosen = np.flatnonzero(take)
    chosen = chosen[np.argsort(-gain[chosen], kind="stable")]
    before = np.cumsum(take[chosen]) - take[chosen]  # samples of the pixels ahead of each
    take[chosen] = np.clip(left - before, 0, take[chosen])
    return take


def _runs(take, p0, stops):
    """(first pass, end pass, pixels) of a batch: pixels sorted by index, each run ending where
    some pixel's take ends or at one of ``stops``."""
    ends = sorted(set(int(t) for t in take[take > 0]))
    cuts = sorted(set(p0 + e for e in ends) | {s for s in stops if p0 < s < p0 + ends[-1]})
    begin = p0
    for end in cuts:
        pixels = np.flatnonzero(take >= end - p0).astype(np.int32)
        yield begin, end, pixels
        begin = end


def _merge(total: RunStats, st: RunStats) -> None:
    total.passes += st.passes
    total.samples += st.samples
    total.iterations += st.iterations
    total.rays_extend += st.rays_extend
    total.rays_shadow += st.rays_shadow
    total.nonfinite = max(total.nonfinite, st.nonfinite)  # the device counter is cumulative
    total.interrupted |= st.interrupted
    total.add_stage_seconds(st.stage_seconds)
