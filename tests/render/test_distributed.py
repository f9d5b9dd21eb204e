"""Rendering on Dask (pyopencl_rt.render.distributed): a LocalCluster of two worker processes on this
machine (loopback only) gives the single-process image for the same seed."""
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

try:
    import distributed  # noqa: F401
except ImportError:
    pytest.skip("Dask is not installed: pip install .[distributed]", allow_module_level=True)

from pyopencl_rt.render.api import render_full

from scenes_small import small_scene  # noqa: E402

REPO = Path(__file__).resolve().parents[2]


@pytest.fixture(scope="module")
def client():
    from distributed import Client, LocalCluster

    # worker processes import pyopencl_rt and the test scene from the checkout
    old = os.environ.get("PYTHONPATH")
    os.environ["PYTHONPATH"] = os.pathsep.join([str(REPO), str(REPO / "tests")] + ([old] if old else []))
    try:
        cluster = LocalCluster(n_workers=2, threads_per_worker=1, processes=True, host="127.0.0.1",
                               dashboard_address=None, silence_logs=40)
    finally:
        if old is None:
            os.environ.pop("PYTHONPATH")
        else:
            os.environ["PYTHONPATH"] = old
    c = Client(cluster)
    yield c
    c.close()
    cluster.close()


# The workers are sent the device's spec: a pyopencl.Device cannot be pickled.
def test_local_cluster_matches_single_process(client, device, device_spec):
    scene = small_scene()
    ref = render_full(scene, spp=16, device=device)
    r = render_full(scene, spp=16, device=device_spec, scheduler=client)
    assert r.film.passes == 16 and not r.stats.interrupted
    # chunk films are added in pass order; only the grouping of the float64 additions differs
    np.testing.assert_allclose(r.film.sum, ref.film.sum, rtol=1e-12, atol=0)
    np.testing.assert_allclose(r.film.sum_sq, ref.film.sum_sq, rtol=1e-12, atol=0)
    np.testing.assert_allclose(r.image, ref.image, rtol=1e-6, atol=0)
    workers = r.info["workers"]
    assert len(workers) == 2, "both workers rendered"
    assert sum(d["passes"] for d in r.info["devices"]) == 16
    assert r.info["spp"] == 16 and r.info["features"] == ref.info["features"]


def test_resume_on_the_cluster(client, tmp_path, device, device_spec):
    """A checkpoint from a local render, finished on the cluster."""
    scene = small_scene()
    ref = render_full(scene, spp=12, device=device)
    path = tmp_path / "c.npz"

    def stop_at_5(passes, elapsed):
        if passes >= 5:
            raise KeyboardInterrupt

    render_full(scene, spp=12, device=device, checkpoint=path, progress=stop_at_5)
    r = render_full(scene, spp=12, device=device_spec, scheduler=client, checkpoint=path, resume=True)
    assert r.film.passes == 12 and r.info["resumed_from_spp"] >= 5
    np.testing.assert_allclose(r.film.sum, ref.film.sum, rtol=1e-12, atol=0)


def test_cli_without_dask_says_what_to_install(tmp_path):
    """With dask hidden, --scheduler is a one-line error naming the extra."""
    code = ("import sys; sys.modules['distributed'] = None; sys.argv = ['pyopencl-rt', 'render', 'x.toml', "
            "'--scheduler', 'local']; from pyopencl_rt.cli import main; main()")
    env = dict(os.environ, PYTHONPATH=str(REPO))
    r = subprocess.run([sys.executable, "-c", code], cwd=tmp_path, env=env, capture_output=True, text=True,
                       timeout=120)
    assert r.returncode == 1
    assert r.stderr.strip().count("\n") == 0 and "pip install" in r.stderr and "distributed" in r.stderr


def test_time_limit_stops_on_time(client, device_spec, measured):
    """The time limit counts from the first pass rendered (after the workers' setup, as on one
    device), and the workers are told the deadline and stop on it: the render ends well within a
    second of it.  (Before, ~1 s chunks queued two per worker ran on: 1 s took 3.4 s.)"""
    scene = small_scene()
    # the workers build their renderers, and PoCL its code for full-wave launches (a 2-spp render
    # launches only small grids, which PoCL compiles apart; with a cold kernel cache the first
    # full wave's compile took 1.5-2 s of the timed render on a 2-core Zen 3)
    render_full(scene, time_limit=0.2, device=device_spec, scheduler=client)
    limit = 1.5
    t0 = time.perf_counter()
    r = render_full(scene, time_limit=limit, device=device_spec, scheduler=client)
    took = time.perf_counter() - t0
    measured(f"dask --time-limit {limit}: {took:.2f} s, {r.film.passes} passes")
    assert r.film.passes >= 1 and np.isfinite(r.image).all() and not r.stats.interrupted
    assert took < limit + 1.25, f"{took:.2f} s for a {limit} s limit"


def test_intersector_reaches_the_workers(client, device, device_spec):
    """--intersector embree with --scheduler: the workers trace with Embree (their engines say so)
    and the image is the local Embree render's."""
    from pyopencl_rt import load_scene

    scene = load_scene(str(REPO / "scenes" / "cornell-box.toml"))
    ref = render_full(scene, spp=4, width=8, height=8, device=device, intersector="embree")
    r = render_full(scene, spp=4, width=8, height=8, device=device_spec, scheduler=client, intersector="embree")
    assert r.info["intersector"] == ref.info["intersector"] == "embree"
    assert all(w["intersector"] == "embree" for w in r.info["workers"].values())
    np.testing.assert_allclose(r.film.sum, ref.film.sum, rtol=1e-12, atol=0)


def test_unreachable_scheduler_fails_fast():
    """Nothing listens on the port: one line in a few seconds (was the client's 30 s timeout)."""
    from pyopencl_rt.errors import UserError

    t0 = time.perf_counter()
    with pytest.raises(UserError, match="cannot reach the Dask scheduler tcp://127.0.0.1:1"):
        render_full(small_scene(), spp=1, scheduler="tcp://127.0.0.1:1")
    assert time.perf_counter() - t0 < 5
