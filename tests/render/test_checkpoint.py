"""Interrupt and resume (pyopencl_rt.render.checkpoint): a resumed render is bit for bit the
uninterrupted one on the same device; checkpoints of other scenes or settings are refused;
checkpoints are written atomically; the CLI stops cleanly on SIGTERM and resumes."""
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt.render import checkpoint as ckp
from pyopencl_rt.errors import UserError
from pyopencl_rt.render.api import render_full
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.settings import ImageSettings

from scenes_small import small_scene  # noqa: E402

REPO = Path(__file__).resolve().parents[2]
SPP = 12


def interrupt_after(n):
    def progress(passes, elapsed):
        if passes >= n:
            raise KeyboardInterrupt

    return progress


_REFERENCES: dict = {}


@pytest.fixture
def reference(device):
    """The uninterrupted render on ``device`` (once per device)."""
    if device.int_ptr not in _REFERENCES:
        _REFERENCES[device.int_ptr] = render_full(small_scene(), spp=SPP, device=device)
    return _REFERENCES[device.int_ptr]


# a spec listing the device twice selects it once (devices.resolve drops duplicates)
@pytest.mark.parametrize("devices", ["{0}", "{0},{0}"], ids=["one-device", "one-device-listed-twice"])
def test_interrupt_then_resume_is_bitwise(tmp_path, reference, device_spec, devices):
    devices = devices.format(device_spec)
    path = tmp_path / "r.ckpt.npz"
    part = render_full(small_scene(), spp=SPP, device=devices, checkpoint=path, progress=interrupt_after(5))
    assert part.stats.interrupted and part.info["interrupted"]
    assert 5 <= part.film.passes < SPP
    film, _key, meta = ckp.read(path)
    assert film.passes == part.film.passes == meta["passes"]
    assert np.array_equal(film.sum, part.film.sum)
    done = render_full(small_scene(), spp=SPP, device=devices, checkpoint=path, resume=True)
    assert not done.stats.interrupted and done.film.passes == SPP
    assert done.info["resumed_from_spp"] == part.film.passes
    assert np.array_equal(done.film.sum, reference.film.sum)
    assert np.array_equal(done.film.sum_sq, reference.film.sum_sq)
    assert np.array_equal(done.image, reference.image)


def test_resume_on_several_devices_is_bitwise(tmp_path, reference, device):
    """A checkpoint from one device, finished by the multi-device pool (two Wavefronts on it)."""
    from pyopencl_rt.render.multidevice import MultiDevice
    from pyopencl_rt.render.wavefront import Wavefront

    path = tmp_path / "r.ckpt.npz"
    render_full(small_scene(), spp=SPP, device=device, checkpoint=path, progress=interrupt_after(4))
    scene = small_scene()
    film, _ = ckp.load(path, scene, ImageSettings.resolve(scene))
    MultiDevice(scene, [Wavefront(scene, device), Wavefront(scene, device)], target_seconds=0.01).run(
        film, passes=SPP - film.passes)
    assert film.passes == SPP and np.array_equal(film.sum, reference.film.sum)


def test_checkpoint_of_other_settings_or_scene_is_refused(tmp_path, device):
    path = tmp_path / "r.ckpt.npz"
    render_full(small_scene(), spp=SPP, device=device, checkpoint=path, progress=interrupt_after(2))
    with pytest.raises(ckp.CheckpointError) as e:
        render_full(small_scene(), spp=SPP, device=device, checkpoint=path, resume=True, seed=8)
    msg = str(e.value)
    assert "\n" not in msg and "other settings" in msg and "seed 7 -> 8" in msg
    assert isinstance(e.value, UserError)
    with pytest.raises(ckp.CheckpointError, match="width 48 -> 40"):
        render_full(small_scene(), spp=SPP, device=device, checkpoint=path, resume=True, width=40)
    with pytest.raises(ckp.CheckpointError, match="another scene") as e:
        render_full(small_scene(ball=(0.9, 0.1, 0.1)), spp=SPP, device=device, checkpoint=path, resume=True)
    assert "\n" not in str(e.value)
    with pytest.raises(ckp.CheckpointError, match="no checkpoint"):
        render_full(small_scene(), spp=SPP, device=device, checkpoint=tmp_path / "none.npz", resume=True)
    (tmp_path / "junk.npz").write_bytes(b"not a zip")
    with pytest.raises(ckp.CheckpointError, match="not a readable checkpoint"):
        render_full(small_scene(), spp=SPP, device=device, checkpoint=tmp_path / "junk.npz", resume=True)


def test_checkpoint_every_writes_valid_checkpoints(tmp_path, monkeypatch, reference, device):
    path = tmp_path / "r.ckpt.npz"
    saves = []
    real_save = ckp.save

    def spy(p, film, *a, **k):
        saves.append(film.passes)
        return real_save(p, film, *a, **k)

    monkeypatch.setattr(ckp, "save", spy)
    r = render_full(small_scene(), spp=SPP, device=device, checkpoint=path, checkpoint_every=1e-6)
    assert len(saves) >= SPP  # after every pass, and at the end
    assert saves == sorted(saves) and saves[-1] == SPP
    film, _key, meta = ckp.read(path)
    assert film.passes == SPP and np.array_equal(film.sum, reference.film.sum) and meta["settings"]["seed"] == 7
    assert sorted(p.name for p in tmp_path.iterdir()) == ["r.ckpt.npz"]  # no temporary file left
    assert r.info["checkpoint"] == str(path)


def test_checkpoint_write_is_atomic(tmp_path, monkeypatch):
    """A write that dies half-way leaves the previous checkpoint whole (write, then rename)."""
    scene = small_scene()
    settings = ImageSettings.resolve(scene)
    path = tmp_path / "c.npz"
    film = Film(48, 32)
    film.add_pass(np.ones((48 * 32, 3), np.float32))
    ckp.save(path, film, scene, settings)

    def dying_savez(f, **arrays):
        f.write(b"PK\x03\x04 half a file")
        raise OSError("disk full (injected)")

    monkeypatch.setattr(np, "savez", dying_savez)
    film.add_pass(np.ones((48 * 32, 3), np.float32))
    with pytest.raises(OSError):
        ckp.save(path, film, scene, settings)
    monkeypatch.undo()
    again, _ = ckp.load(path, scene, settings)
    assert again.passes == 1
    assert sorted(p.name for p in tmp_path.iterdir()) == ["c.npz"]


# -- the command line: SIGTERM, then --resume -------------------------------------------------------
def cli(*args, cwd, **kw):
    env = dict(os.environ)
    env.pop("PYOPENCL_CTX", None)
    env["PYTHONPATH"] = str(REPO) + (os.pathsep + env["PYTHONPATH"] if env.get("PYTHONPATH") else "")
    return subprocess.Popen([sys.executable, "-m", "pyopencl_rt.cli", *args], cwd=cwd, env=env,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, **kw)


def write_obj_scene(tmp_path) -> Path:
    """An OBJ + MTL (a floor and an emissive panel): the CLI renders mesh files directly."""
    (tmp_path / "s.mtl").write_text("newmtl floor\nKd 0.6 0.5 0.4\nnewmtl lamp\nKd 0 0 0\nKe 4 4 4\n")
    (tmp_path / "s.obj").write_text(
        "mtllib s.mtl\n"
        "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\n"
        "v -0.5 1.5 -0.5\nv 0.5 1.5 -0.5\nv 0.5 1.5 0.5\nv -0.5 1.5 0.5\n"
        "usemtl floor\nf 1 3 2\nf 1 4 3\nusemtl lamp\nf 5 6 7\nf 5 7 8\n")
    return tmp_path / "s.obj"


def test_cli_sigterm_writes_outputs_and_resume_matches(tmp_path):
    scene = write_obj_scene(tmp_path)
    common = ["--width", "40", "--height", "30", "--seed", "3", "--max-depth", "3"]
    ckpt = tmp_path / "part.ckpt.npz"
    p = cli("render", str(scene), "-o", str(tmp_path / "part.exr"), "--spp", "100000",
            "--checkpoint-every", "0.2", *common, cwd=tmp_path)
    deadline = time.time() + 120
    while not ckpt.exists() and p.poll() is None and time.time() < deadline:
        time.sleep(0.05)
    assert ckpt.exists(), p.communicate()[1] if p.poll() is not None else "no checkpoint written"
    time.sleep(0.3)
    p.send_signal(signal.SIGTERM)
    out, err = p.communicate(timeout=60)
    assert p.returncode == 130, err
    assert "interrupted" in out and "--resume" in out
    info = json.loads((tmp_path / "part.json").read_text())
    assert info["interrupted"] is True and info["spp"] >= 1
    assert (tmp_path / "part.exr").exists() and (tmp_path / "part.png").exists()
    film, _key, meta = ckp.read(ckpt)
    assert film.passes == info["spp"] == meta["passes"]
    n = info["spp"] + 3
    r = cli("render", str(scene), "-o", str(tmp_path / "part.exr"), "--spp", str(n), "--resume", "-q", *common,
            cwd=tmp_path)
    out, err = r.communicate(timeout=120)
    assert r.returncode == 0, err
    resumed = json.loads((tmp_path / "part.json").read_text())
    assert resumed["spp"] == n and resumed["resumed_from_spp"] == info["spp"] and not resumed["interrupted"]
    u = cli("render", str(scene), "-o", str(tmp_path / "full.exr"), "--spp", str(n), "-q", *common, cwd=tmp_path)
    out, err = u.communicate(timeout=120)
    assert u.returncode == 0, err
    from pyopencl_rt.imageio import read_exr

    assert np.array_equal(read_exr(tmp_path / "part.exr"), read_exr(tmp_path / "full.exr"))
    # a resume with other settings is one line, exit code 1
    bad = cli("render", str(scene), "-o", str(tmp_path / "part.exr"), "--spp", str(n), "--resume",
              "--width", "41", "--height", "30", "--seed", "3", "--max-depth", "3", cwd=tmp_path)
    out, err = bad.communicate(timeout=120)
    assert bad.returncode == 1
    assert err.strip().count("\n") == 0 and "other settings" in err and "width 40 -> 41" in err


def two_level_scene(moves, groups=(0, 0)):
    """Two one-triangle shape groups (the second turned) and an instance of group ``groups[k]``
    moved by x = ``moves[k]``, drawn through the two-level BVH: no array of vertices or faces
    changes with the instances."""
    from pyopencl_rt.scene.model import BlasGroup, Instance, Material, Scene

    v = np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0], [0, 0, 0], [0, 1, 0], [0, 0, 1]], np.float32)
    scene = Scene(vertices=v, faces=np.arange(6, dtype=np.int32).reshape(2, 3), face_materials=np.zeros(2, np.int32),
                  materials=[Material()])
    scene.blas_groups = [BlasGroup("a", 0, 1), BlasGroup("b", 1, 1)]
    m = [np.eye(4) for _ in moves]
    for mk, x in zip(m, moves):
        mk[0, 3] = x
    scene.instances = [Instance("ab"[g], mk, blas=g) for mk, g in zip(m, groups)]
    return scene


def test_checkpoint_key_covers_two_level_instances(tmp_path):
    """Scenes that differ only in an instance's transform (by 1e-6) or in the group an instance
    draws never share a key (their arrays are the same), so a checkpoint of one is refused for the
    other; the same instances give the same key (the key is not merely new each time)."""
    settings = ImageSettings(width=4, height=4, max_depth=3, rr_depth=3, integrator="path", seed=1)
    base = two_level_scene([0.0, 2.0])
    assert ckp.scene_hash(two_level_scene([0.0, 2.0])) == ckp.scene_hash(base)
    others = [two_level_scene([0.0, 2.0 + 1e-6]), two_level_scene([0.0, 2.0], groups=(0, 1)),
              two_level_scene([0.0])]
    keys = {ckp.render_key(s, settings) for s in [base] + others}
    assert len(keys) == 4
    path = ckp.save(tmp_path / "r.ckpt.npz", Film.new(4, 4), base, settings)
    assert ckp.load(path, two_level_scene([0.0, 2.0]), settings)[0].passes == 0
    for other in others:
        with pytest.raises(ckp.CheckpointError, match="another scene"):
            ckp.load(path, other, settings)
