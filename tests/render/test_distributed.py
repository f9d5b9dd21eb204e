"""Rendering on Dask (pyopencl_rt.render.distributed): a LocalCluster of two worker processes on this
machine (loopback only) gives the single-process image for the same seed."""
import os
import subprocess
import sys
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
