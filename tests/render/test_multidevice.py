"""Several devices in one render (pyopencl_rt.render.multidevice): the merged film is the single-device
film, whichever device rendered which pass, and a device that fails is dropped.

PoCL exposes one CPU device by default; ``POCL_DEVICES="pthread pthread"`` (or ``"basic
pthread"``) in a subprocess gives two devices (both share the same cores).  In-process tests
use two Wavefronts on the one device.
"""
import json
import os
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.device import devices as dv
from pyopencl_rt.render.multidevice import DeviceFailure, MultiDevice
from pyopencl_rt.render.settings import FEATURES_ENV
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.wavefront import Wavefront

from scenes_small import small_scene  # noqa: E402

REPO = Path(__file__).resolve().parents[2]

SCRIPT = """
import json, sys, numpy as np
sys.path[:0] = [{repo!r}, {tests!r}]
from scenes_small import small_scene
from pyopencl_rt.render.api import render_full
from pyopencl_rt.device import devices as dv
s = small_scene()
one = render_full(s, spp=10, device="0:0")
both = render_full(s, spp=10, device="all")
print(json.dumps({{
    "n_devices": len(dv.all_devices()),
    "bitwise": bool(np.array_equal(one.film.sum, both.film.sum) and np.array_equal(one.film.sum_sq, both.film.sum_sq)),
    "max_rel": float(np.max(np.abs(one.film.sum - both.film.sum) / np.maximum(np.abs(one.film.sum), 1e-30))),
    "passes": [one.film.passes, both.film.passes],
    "devices": both.info["devices"],
}}))
"""


# PoCL by design, not the device fixture: POCL_DEVICES (in a subprocess) is how one machine gets
# two devices that must agree bit for bit.
@pytest.mark.parametrize("pocl_devices", ["pthread pthread", "basic pthread"])
def test_two_pocl_devices_merge_to_the_single_device_image(pocl_devices):
    env = dict(os.environ, POCL_DEVICES=pocl_devices, PYOPENCL_RT_PACKAGED_ICDS="0")  # PoCL's devices alone
    if "basic" in pocl_devices:  # a device no other test builds for: the small scene's own kernel, a
        env[FEATURES_ENV] = "scene"  # third of the every-feature program's build
    env.pop("PYOPENCL_CTX", None)
    env.pop("OCL_ICD_VENDORS", None)
    r = subprocess.run([sys.executable, "-c", SCRIPT.format(repo=str(REPO), tests=str(REPO / "tests"))],
                       env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    out = json.loads(r.stdout.strip().splitlines()[-1])
    if out["n_devices"] < 2:
        pytest.skip(f"POCL_DEVICES={pocl_devices!r} gave {out['n_devices']} device(s)")
    assert out["passes"] == [10, 10]
    assert len(out["devices"]) == 2 and sum(d["passes"] for d in out["devices"]) == 10
    # the pool adds passes to the film in pass order, so the sums are those of one device up to
    # the passes' own float32 rounding on different devices (PoCL's devices agree bit for bit)
    assert out["max_rel"] <= 1e-5
    assert out["bitwise"], out


def two_wavefronts(device, ref_passes=None):
    """The small scene, two Wavefronts on ``device``, and (with ``ref_passes``) the reference:
    the film of that many passes of the first one alone."""
    scene = small_scene()
    wfs = [Wavefront(scene, device) for _ in range(2)]
    ref = None
    if ref_passes is not None:
        ref = Film(48, 32)
        wfs[0].run(ref, passes=ref_passes)
    return scene, wfs, ref


def test_split_is_bitwise_on_one_device(device):
    """Two Wavefronts on one device, small batches: any split gives the single-run film."""
    scene, wfs, ref = two_wavefronts(device, 9)
    film = Film(48, 32)
    st = MultiDevice(scene, wfs, target_seconds=0.01).run(film, passes=9)
    assert film.passes == 9 and st.passes == 9 and not st.interrupted
    assert np.array_equal(film.sum, ref.sum) and np.array_equal(film.sum_sq, ref.sum_sq)
    assert sum(d["passes"] for d in st.devices) == 9


def test_failing_device_is_dropped_and_its_passes_redone(device):
    scene, wfs, ref = two_wavefronts(device, 8)
    good, bad = wfs
    calls = {"n": 0}
    real_run, real_good_run = bad.run, good.run
    bad_started = threading.Event()

    def waiting_run(film, **kw):
        # the good device holds its first batch until the bad one has one too: on a loaded
        # machine the bad device's thread could otherwise start after every pass was taken
        bad_started.wait(timeout=60)
        return real_good_run(film, **kw)

    def flaky_run(film, **kw):
        # its first batch (which batch comes later depends on the timing; a fast device could
        # take all the passes before the second one's second call, so it fails in its first)
        bad_started.set()
        calls["n"] += 1

        class Broken:  # one pass of the batch gets through, then the device "fails"
            n = 0

            def add_pass(self, radiance):
                if self.n >= 1:
                    raise RuntimeError("CL_OUT_OF_RESOURCES (injected)")
                self.n += 1
                film.add_pass(radiance)

        kw["passes"] = max(kw["passes"], 2)  # make sure the batch has passes left to hand back
        return real_run(Broken(), **kw)

    bad.run, good.run = flaky_run, waiting_run
    film = Film(48, 32)
    with pytest.warns(RuntimeWarning, match="failed and was dropped"):
        st = MultiDevice(scene, wfs, target_seconds=0.01).run(film, passes=8)
    assert calls["n"] >= 1
    assert film.passes == 8 and not st.interrupted
    assert np.array_equal(film.sum, ref.sum) and np.array_equal(film.sum_sq, ref.sum_sq)
    failed = [d for d in st.devices if d["failed"]]
    assert len(failed) == 1 and "injected" in failed[0]["failed"]


def test_every_device_failing_is_an_error(device):
    scene, wfs, _ = two_wavefronts(device)

    def broken(film, **kw):
        raise RuntimeError("injected")

    for wf in wfs:
        wf.run = broken
    with pytest.warns(RuntimeWarning), pytest.raises(DeviceFailure, match="every device failed"):
        MultiDevice(scene, wfs).run(Film(48, 32), passes=4)


def test_cancel_keeps_a_prefix_of_passes(device):
    scene, wfs, ref = two_wavefronts(device, 3)
    film = Film(48, 32)
    seen = []

    def progress(passes, elapsed):
        seen.append(passes)

    md = MultiDevice(scene, wfs, target_seconds=0.01)
    st = md.run(film, passes=10_000, progress=progress, cancel=lambda: film.passes >= 3, tick_seconds=0.01)
    assert st.interrupted and 3 <= film.passes < 10_000
    # the film holds passes [0, n) in order: its first 3 passes are the reference's
    again = Film(48, 32)
    wfs[0].run(again, passes=film.passes)
    assert np.array_equal(film.sum, again.sum)


def test_hung_device_is_dropped_and_its_passes_redone(device):
    """A device whose run stops returning (a driver that never comes back) is dropped after
    device_timeout seconds without progress, like a failing one: the others render its passes
    and the film is the single-device film, bit for bit."""
    scene, wfs, ref = two_wavefronts(device, 6)
    good, stuck = wfs
    real_run, release, calls = stuck.run, threading.Event(), {"n": 0}
    real_good_run, stuck_hangs, good_calls = good.run, threading.Event(), {"n": 0}

    def hanging_run(film, **kw):
        calls["n"] += 1
        if calls["n"] == 1:
            return real_run(film, **kw)
        stuck_hangs.set()
        release.wait(60)  # never returns on its own, never calls cancel (no heartbeat)
        return real_run(film, **kw)  # woken at the end of the test: what it renders is ignored

    def waiting_run(film, **kw):
        # the good device's second batch waits until the other one hangs in its second: on a
        # loaded machine the good device could otherwise take every pass first (nothing hangs)
        good_calls["n"] += 1
        if good_calls["n"] == 2:
            stuck_hangs.wait(timeout=60)
        return real_good_run(film, **kw)

    stuck.run, good.run = hanging_run, waiting_run
    film = Film(48, 32)
    try:
        with pytest.warns(RuntimeWarning, match=r"made no progress for 1 s and was dropped"):
            st = MultiDevice(scene, wfs, target_seconds=0.01, device_timeout=1.0).run(film, passes=6)
    finally:
        release.set()
    assert calls["n"] >= 2 and film.passes == 6 and not st.interrupted
    assert np.array_equal(film.sum, ref.sum) and np.array_equal(film.sum_sq, ref.sum_sq)
    (hung,) = [d for d in st.devices if d["failed"]]
    assert hung["failed"] == "no progress for 1 s (hung)"


def test_several_devices_use_the_intersector_given(device):
    """--intersector embree on several devices: every device's engine traces with Embree (not
    silently our traversal), and the merged film is the one-device Embree film."""
    from pyopencl_rt.render.api import render_full
    from pyopencl_rt import load_scene

    scene = load_scene(str(REPO / "scenes" / "cornell-box.toml"))
    one = render_full(scene, spp=4, width=8, height=8, device=device, intersector="embree")
    two = render_full(scene, spp=4, width=8, height=8, device=[device, device], intersector="embree")
    assert one.info["intersector"] == two.info["intersector"] == "embree"
    assert len(two.info["devices"]) == 2
    assert np.array_equal(one.film.sum, two.film.sum)


def test_two_implementations_in_one_render_equal_either_alone(monkeypatch):
    """PoCL and Intel's CPU runtime (two compilers, as a CPU and a GPU would be) render one image
    together (a Wavefront on each, small batches; each device's first batch waits until the other
    has one too, so that on a loaded machine one device cannot take every pass before the other
    starts): both take passes, and the merged image equals each implementation's own render
    statistically (8x8-pixel tiles within 4.5 standard errors, from 64 passes' per-pixel
    variances).  Where the two compile every operation alike (this scene: the same bits) the
    merged film also equals them bit for bit; that is reported, not required."""
    present = {dv.implementation(e[2]): e[2] for e in reversed(dv.all_devices())}
    if not {"pocl", "intel"} <= set(present):
        pytest.skip("needs PoCL and Intel's CPU runtime (the dev extra installs both)")
    import harness

    # the scene's own program: the only every-feature build on Intel's compiler took 31 s
    monkeypatch.setenv(FEATURES_ENV, "scene")
    scene = small_scene()
    wfs = {name: Wavefront(scene, present[name]) for name in ("pocl", "intel")}
    films = {}
    for name, wf in wfs.items():
        films[name] = Film(48, 32)
        wf.run(films[name], passes=64)
    both_started = threading.Barrier(2, timeout=120)
    for wf in wfs.values():
        real = wf.run

        def first_waits(film, _real=real, _state={"first": True}, **kw):
            if _state["first"]:
                _state["first"] = False
                both_started.wait()
            return _real(film, **kw)

        wf.run = first_waits
    merged = Film(48, 32)
    st = MultiDevice(scene, list(wfs.values()), target_seconds=0.01).run(merged, passes=64)
    assert merged.passes == 64 and len(st.devices) == 2 and all(d["passes"] > 0 for d in st.devices), st.devices

    def mean_var(film):
        mean = film.sum / film.passes
        var = np.maximum(film.sum_sq / film.passes - mean**2, 0) / film.passes
        return mean.reshape(film.height, film.width, 3), var.reshape(film.height, film.width, 3)

    m, v = mean_var(merged)
    for alone in ("pocl", "intel"):
        a, av = mean_var(films[alone])
        z = harness.tile_z(m, v, a, av)
        assert z.max() < 4.5, (alone, float(z.max()))
        print(alone, "bitwise" if np.array_equal(merged.sum, films[alone].sum) else "differs in the last bits")
