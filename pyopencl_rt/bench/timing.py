"""How the benchmarks time and report.

The machine a benchmark runs on is often shared and noisy, so every figure is the median of
``repeat`` runs, and the variants being compared are timed alternately inside each repetition:
a burst of background load then hits all of them alike, and their ratio stays meaningful even
when the absolute numbers move.
"""
from __future__ import annotations

import platform
import time
from pathlib import Path


def machine_info() -> dict:
    return {"platform": platform.platform(), "processor": platform.processor(), "cpu_model": cpu_model(),
            "python": platform.python_version()}


def cpu_model() -> str | None:
    """The CPU's model name (Linux: /proc/cpuinfo), which every speed figure names."""
    try:
        with open("/proc/cpuinfo") as f:
            return next((line.split(":", 1)[1].strip() for line in f if line.startswith("model name")), None)
    except OSError:
        return None


def timed_repeats(fn, repeat: int) -> list[float]:
    """Wall seconds of ``repeat`` calls of ``fn()``."""
    seconds = []
    for _ in range(repeat):
        start = time.perf_counter()
        fn()
        seconds.append(time.perf_counter() - start)
    return seconds


def interleaved_render_rates(variants: dict, spp: int, repeat: int, profile: bool = False, others=None,
                             pause: float = 0.0):
    """Samples/s of each ``name -> (scene, wavefront)`` variant: one untimed 1-spp warm-up render
    each (kernel build, BVH upload, the first launches that make PoCL compile its work-group
    functions), then ``repeat`` rounds rendering ``spp`` with every variant in turn.  ``others``:
    ``name -> callable(spp)`` returning samples/s (another renderer, already warmed up), called in
    each round after the variants.  ``pause``: seconds of idleness before each timed render, so
    that the worker threads of the render before (ours or another renderer's) have gone to sleep.

    Returns ({name: [samples/s per round]}, {name: info dict of its last render})."""
    from ..render.api import render_full

    for scene, wavefront in variants.values():
        render_full(scene, spp=1, wavefront=wavefront)
    others = others or {}
    rates = {name: [] for name in [*variants, *others]}
    last_info = {}
    for _ in range(repeat):
        for name, (scene, wavefront) in variants.items():
            time.sleep(pause)
            result = render_full(scene, spp=spp, wavefront=wavefront, profile=profile)
            rates[name].append(result.info["samples_per_second"])
            last_info[name] = result.info
        for name, render in others.items():
            time.sleep(pause)
            rates[name].append(render(spp))
    return rates, last_info


def write_results(json_path, results: dict, echo=print) -> None:
    from ..imageio import write_json

    path = Path(json_path)
    path.parent.mkdir(parents=True, exist_ok=True)
    write_json(path, results)
    echo(f"wrote {json_path}")
