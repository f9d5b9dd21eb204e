"""``bench rays``'s parallel Embree reference (pyopencl_rt/bench/embree_pool.py): the worker processes
trace exactly what one embreex call traces, and the command reports it beside the single-threaded
figure, with as many workers as PoCL has threads."""
import json

import numpy as np
import pytest

from meshes import incoherent_rays
from pyopencl_rt import build_bvh
from pyopencl_rt.accel.embree import embree_scene
from pyopencl_rt.bench.embree_pool import CHUNK, EmbreePool
from pyopencl_rt.bench.rays import pocl_threads, run_ray_bench
from pyopencl_rt.bench.workloads import bumpy_torus


def test_pool_traces_what_one_call_traces():
    """Three workers, rays not a multiple of the chunk: every ray is traced once, by exactly one
    worker (a ray left out keeps the shared buffer's initial value, a ray traced twice is harmless
    but a lost chunk is not), and the results equal a single embreex call's bit for bit."""
    v, f = bumpy_torus(2000)
    rng = np.random.default_rng(3)
    o, d = incoherent_rays(v, f, 5 * CHUNK + 123, rng)
    ref = embree_scene(build_bvh(v, f)).run(o, d, output=1)
    with EmbreePool(3) as pool:
        pool.load(v, f)
        pool.set_rays(o, d)
        seconds = pool.run()
        assert seconds > 0
        assert np.array_equal(pool.prim, ref["primID"])
        assert np.array_equal(pool.t, ref["tfar"])
        assert 0.05 < (pool.prim >= 0).mean() < 0.95
        # a second ray set replaces the first
        pool.set_rays(o[:100], d[:100])
        pool.run()
        assert np.array_equal(pool.prim, ref["primID"][:100])


def test_bench_reports_parallel_embree(tmp_path, device, monkeypatch):
    import os

    import pyopencl as cl

    from pyopencl_rt.bench import rays

    monkeypatch.setattr(rays, "PAUSE", 0.0)

    # PoCL's pthread device runs one thread per compute unit; without a CPU device, the host's CPUs
    threads = device.max_compute_units if device.type & cl.device_type.CPU else os.cpu_count()
    assert pocl_threads([device]) == threads
    out = tmp_path / "rays.json"
    lines = []
    data = run_ray_bench(devices=[device], sizes=(1000,), n_rays=4096, repeat=2, json_path=out, echo=lines.append,
                         layouts=("wide", "wide8"))
    assert json.loads(out.read_text())["embree_threads"] == threads
    for row in data["meshes"][0]["sets"]:
        par, one = row["embree_parallel"], row["backends"]["embree"]
        assert par["workers"] == threads
        assert par["rays_per_second"] == pytest.approx(row["rays"] / par["seconds_median"])
        assert par["speedup_over_one_thread"] == pytest.approx(one["seconds_median"] / par["seconds_median"])
        ours = [b for name, b in row["backends"].items() if name != "embree"]
        assert sorted(b["layout"] for b in ours) == ["wide", "wide8"]
        for b in ours + [one, par]:   # CPU seconds: PoCL's threads (ours) or the workers' (pool) included
            assert 0 < b["rays_per_cpu_second"] < 1e10
        for b in ours:
            assert b["ratio_to_embree_parallel"] == pytest.approx(par["seconds_median"] / b["seconds_median"])
            # per repetition: the Embree processes' time over ours, of the same repetition
            per_round = [p / o for o, p in zip(b["seconds_all"], par["seconds_all"])]
            assert len(per_round) == 2 and b["ratio_to_embree_parallel_per_round"] == pytest.approx(per_round)
            assert b["ratio_to_embree_parallel_per_round_median"] == pytest.approx(np.median(per_round))
    assert any(f"embree x{threads} (processes)" in line for line in lines)
