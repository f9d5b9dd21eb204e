"""Bad input gets one clear line and the right exit code, before anything is rendered; outputs are
all-or-none; a render that cannot be written is kept in a checkpoint; checkpoints are untrusted
input (issue 13, docs/ROBUSTNESS.md).

The CLI runs in-process (``pyopencl_rt.cli.main`` raising SystemExit), except where a real
process is the point (signals).  Most cases use a scene path that does not exist: an option
refused *before* the scene is read gives its own message, where a check made later would say
"no such file" instead.
"""
import errno
import json
import os
import signal
import subprocess
import sys
import time
import zipfile
from pathlib import Path

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt import imageio
from pyopencl_rt.cli import main
from pyopencl_rt.errors import UsageError, UserError
from pyopencl_rt.render import checkpoint as checkpoints
from pyopencl_rt.render.checkpoint_schema import CheckpointError
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.settings import ImageSettings

REPO = Path(__file__).resolve().parents[1]
CORNELL = str(REPO / "scenes" / "cornell-box.toml")
TINY = ["--width", "4", "--height", "4", "--spp", "1", "-q", "--device", "cpu"]


def cli(capsys, *args):
    """(exit code, stderr lines) of ``pyopencl-rt ARGS`` run in this process."""
    capsys.readouterr()
    try:
        main([str(a) for a in args])
        code = 0
    except SystemExit as exc:
        code = exc.code
    return code, capsys.readouterr().err.strip().splitlines()


def one_error(lines):
    assert len(lines) == 1, lines
    assert lines[0].startswith("pyopencl-rt: error: "), lines
    assert "Traceback" not in lines[0]
    return lines[0]


# -- options: refused before the scene is read ---------------------------------------------------
OPTION_CASES = [
    (["--spp", "0"], 2, "--spp must be at least 1 (got 0)"),
    (["--spp", "2.5"], 2, "'2.5' is not a valid integer"),
    # the kernels number passes with a 32-bit int: a larger spp rendered (wrapping) forever
    (["--spp", "99999999999999999999"], 2, "--spp must be at most 2147483647 (got 99999999999999999999)"),
    (["--seed", "4294967296"], 2, "--seed must be at most 4294967295"),
    (["--seed", "-1"], 2, "--seed must be at least 0 (got -1)"),
    (["--wave-size", "0"], 2, "--wave-size must be at least 1 (got 0)"),
    (["--wave-size", "-1"], 2, "--wave-size must be at least 1"),
    (["--wave-size", "10000000000"], 2, "--wave-size must be at most"),
    (["--width", "0"], 2, "impossible resolution 0x1"),
    (["--height", "-3"], 2, "impossible resolution"),
    (["--time-limit", "nan"], 2, "--time-limit must be finite"),
    (["--time-limit", "0"], 2, "--time-limit must be positive"),
    (["--checkpoint-every", "inf"], 2, "--checkpoint-every must be finite"),
    (["--max-depth", "-2"], 2, "--max-depth must be at least -1"),
    (["--exposure", "inf"], 2, "--exposure must be finite"),
    (["--scheduler", "foo"], 2, "expected tcp://host:port"),
    (["--scheduler", "local:0"], 2, "number of local workers"),
    (["--device-timeout", "0"], 2, "--device-timeout must be positive"),
    (["--device", "no-such-device"], 2, "no OpenCL device matches"),
    (["--kernel-mode", "warp"], 2, "'warp' is not one of"),
    (["--light-sampler", "tree"], 2, "'tree' is not one of"),
    (["--adaptive", "--target-error", "0"], 2, "--target-error must be positive (got 0)"),
    (["--adaptive", "--target-error", "nan"], 2, "--target-error must be finite"),
    (["--no-adaptive", "--target-error", "0.1"], 2, "--target-error needs --adaptive"),
    (["--adaptive", "--scheduler", "local"], 2, "--adaptive renders on one device"),
    (["--adaptive", "--resume"], 2, "--adaptive cannot be combined with --resume"),
    (["--adaptive", "--checkpoint-every", "5"], 2, "--adaptive cannot be combined with --resume or --checkpoint-every"),
    (["-o", "out.txt"], 1, "the output must be an .exr or a .png file"),
    (["-o", "/proc/x.exr"], 1, "/proc/x.exr: cannot write the output EXR"),
    (["-o", "/sys/nope/x.exr"], 1, "/sys/nope/x.exr: cannot write the output EXR"),
    (["-o", "o.exr", "--checkpoint", "o.json"], 2, "the checkpoint and the JSON sidecar would be the same file"),
]


@pytest.mark.parametrize("args,code,message", OPTION_CASES, ids=[" ".join(c[0]) for c in OPTION_CASES])
def test_render_options_refused_before_the_scene_is_read(tmp_path, monkeypatch, capsys, args, code, message):
    monkeypatch.chdir(tmp_path)
    got, lines = cli(capsys, "render", "missing.toml", *args)
    line = one_error(lines)
    assert got == code, lines
    assert message in line, line
    assert list(tmp_path.iterdir()) == []  # nothing written


def test_output_folder_in_the_way_leaves_the_old_files(tmp_path, monkeypatch, capsys):
    """out.png is a folder: refused before rendering, the old out.json and out.exr untouched."""
    monkeypatch.chdir(tmp_path)
    (tmp_path / "out.png").mkdir()
    (tmp_path / "out.json").write_text("old")
    (tmp_path / "out.exr").write_text("old")
    code, lines = cli(capsys, "render", CORNELL, "-o", "out.exr", *TINY)
    assert code == 1 and "out.png: cannot write the output PNG: it is a folder" in one_error(lines)
    assert (tmp_path / "out.json").read_text() == "old" and (tmp_path / "out.exr").read_text() == "old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["out.exr", "out.json", "out.png"]


# -- outputs: all or none -------------------------------------------------------------------------
def old_outputs(folder):
    for name in ("o.exr", "o.png", "o.json"):
        (folder / name).write_text(f"old {name}")


def assert_old_outputs(folder):
    assert sorted(p.name for p in folder.iterdir()) == ["o.exr", "o.json", "o.png"]  # no temporary left
    for name in ("o.exr", "o.png", "o.json"):
        assert (folder / name).read_text() == f"old {name}"


def test_write_outputs_failing_midway_keeps_every_old_file(tmp_path, monkeypatch):
    """The PNG writer fails after the EXR was written: the old EXR, PNG and JSON stay."""
    old_outputs(tmp_path)

    def disk_full(*args, **kwargs):
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(imageio, "write_png", disk_full)
    with pytest.raises(UserError, match=r"o\.png: cannot write \(No space left on device\)"):
        imageio.write_outputs(tmp_path / "o.exr", np.ones((2, 2, 3), np.float32), {"a": 1})
    assert_old_outputs(tmp_path)


def test_write_outputs_rename_failing_midway_restores_every_old_file(tmp_path, monkeypatch):
    """The third rename into place fails: the two already placed are taken back, the old files restored."""
    old_outputs(tmp_path)
    real = os.replace
    placed = []

    def replace(src, dst):
        if ".new" in str(src):
            if len(placed) == 2:
                raise PermissionError(errno.EACCES, "Permission denied")
            placed.append(dst)
        return real(src, dst)

    monkeypatch.setattr(imageio.os, "replace", replace)
    with pytest.raises(UserError, match="Permission denied"):
        imageio.write_outputs(tmp_path / "o.exr", np.ones((2, 2, 3), np.float32), {"a": 1})
    assert len(placed) == 2
    assert_old_outputs(tmp_path)


def test_write_outputs_replaces_all_three(tmp_path):
    old_outputs(tmp_path)
    paths = imageio.write_outputs(tmp_path / "o.exr", np.full((2, 3, 3), 0.5, np.float32), {"a": 1})
    assert np.array_equal(imageio.read_exr(paths["exr"]), np.full((2, 3, 3), 0.5, np.float32))
    assert json.loads(Path(paths["json"]).read_text()) == {"a": 1}
    assert Path(paths["png"]).read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["o.exr", "o.json", "o.png"]


def test_render_that_cannot_be_written_is_kept_in_the_checkpoint(tmp_path, monkeypatch, capsys):
    """Writing fails after the render: exit 1, one line saying where the film is; resuming from
    there with another output writes exactly that film."""
    monkeypatch.chdir(tmp_path)
    real = imageio.write_all

    def disk_full(writers):
        raise UserError("out.exr: cannot write (No space left on device)")

    monkeypatch.setattr(imageio, "write_all", disk_full)
    code, lines = cli(capsys, "render", CORNELL, "-o", "out.exr", "--spp", "2", *TINY[:4], "-q", "--device", "cpu")
    line = one_error(lines)
    assert code == 1 and "No space left on device" in line
    assert "the render (2 spp) is saved in out.ckpt.npz" in line and "--resume --checkpoint out.ckpt.npz" in line
    film, _key, meta = checkpoints.read(tmp_path / "out.ckpt.npz")
    assert film.passes == 2 and meta["settings"]["width"] == 4
    monkeypatch.setattr(imageio, "write_all", real)
    code, lines = cli(capsys, "render", CORNELL, "-o", "again.exr", "--spp", "2", *TINY[:4], "-q", "--device", "cpu",
                      "--resume", "--checkpoint", "out.ckpt.npz")
    assert code == 0, lines
    assert np.array_equal(imageio.read_exr(tmp_path / "again.exr"), film.image())


# -- checkpoints are untrusted input -------------------------------------------------------------
@pytest.fixture(scope="module")
def scene():
    return rt.load_scene(CORNELL)


def good_checkpoint(path, scene, passes=3):
    settings = ImageSettings.resolve(scene, width=4, height=3)
    rng = np.random.default_rng(0)
    s = rng.random((12, 3)) * passes
    film = Film(4, 3, sum=s, sum_sq=s * s, passes=passes)
    checkpoints.save(path, film, scene, settings)
    return settings, film


def rewrite(path, **changes):
    """The checkpoint's arrays with ``changes`` (None removes one), written back uncompressed."""
    with np.load(path, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    for k, v in changes.items():
        if v is None:
            arrays.pop(k)
        else:
            arrays[k] = v
    with open(path, "wb") as f:
        np.savez(f, **arrays)


def meta_with(path, **changes):
    with np.load(path, allow_pickle=False) as z:
        meta = json.loads(str(z["meta"]))
    for k, v in changes.items():
        if v is None:
            meta.pop(k)
        else:
            meta[k] = v
    return np.array(json.dumps(meta))


BAD_CHECKPOINTS = {
    "negative passes": (lambda p: rewrite(p, passes=np.int64(-5)), "pass count -5"),
    "no settings": (lambda p: rewrite(p, meta=meta_with(p, settings=None)), "no 'settings' table"),
    "NaN sums": (lambda p: rewrite(p, sum=np.full((12, 3), np.nan)), "'sum' has 36 non-finite values"),
    "negative sum_sq": (lambda p: rewrite(p, sum_sq=-np.ones((12, 3))), "'sum_sq' has negative values"),
    "wrong shape": (lambda p: rewrite(p, sum=np.zeros((13, 3))), "'sum' has shape (13, 3), expected (12, 3)"),
    "float32 sums": (lambda p: rewrite(p, sum=np.zeros((12, 3), np.float32)), "'sum' has dtype float32"),
    "object array": (lambda p: rewrite(p, key=np.array([{"x": 1}], dtype=object)), "'key' has dtype object"),
    "format 99": (lambda p: rewrite(p, meta=meta_with(p, format=99)), "format 99; this version reads format 1"),
    "bad key": (lambda p: rewrite(p, key=np.array("zz")), "not a SHA-256"),
    "width a string": (lambda p: rewrite(p, meta=meta_with(p, settings={"width": "4", "height": 3})),
                       "setting 'width' is '4', not an integer"),
    "pass counts differ": (lambda p: rewrite(p, passes=np.int64(7)), "pass count 7 but its metadata says 3"),
    "extra member": (lambda p: rewrite(p, evil=np.zeros(1)), "unexpected members evil.npy"),
    "meta not JSON": (lambda p: rewrite(p, meta=np.array("{not json")), "metadata is not JSON"),
    "random bytes": (lambda p: p.write_bytes(np.random.default_rng(1).bytes(4096)), "not an .npz archive"),
    "truncated": (lambda p: p.write_bytes(p.read_bytes()[:300]), "damaged archive"),
    "pickle": (lambda p: p.write_bytes(b"\x80\x04\x95" + bytes(64)), "not an .npz archive"),
}


@pytest.mark.parametrize("case", list(BAD_CHECKPOINTS))
def test_bad_checkpoint_is_one_clear_line(tmp_path, scene, case):
    path = tmp_path / "c.ckpt.npz"
    good_checkpoint(path, scene)
    damage, message = BAD_CHECKPOINTS[case]
    damage(path)
    with pytest.raises(CheckpointError) as info:
        checkpoints.read(path)
    text = str(info.value)
    assert "\n" not in text and text.startswith(str(path)) and message in text, text
    assert "allow_pickle" not in text and "pickle" not in text.lower()


def test_good_checkpoint_reads_back_exactly(tmp_path, scene):
    path = tmp_path / "c.ckpt.npz"
    settings, film = good_checkpoint(path, scene)
    back, meta = checkpoints.load(path, scene, settings)
    assert back.passes == 3 and np.array_equal(back.sum, film.sum) and np.array_equal(back.sum_sq, film.sum_sq)


def test_oversized_member_is_refused_unread(tmp_path, scene):
    """A member whose stored size is far beyond its shape (a zip bomb's first step) is refused
    from its header, before its data is read."""
    path = tmp_path / "c.ckpt.npz"
    good_checkpoint(path, scene)
    with zipfile.ZipFile(path, "a") as zf:
        data = zf.read("meta.npy")
    with zipfile.ZipFile(path, "w") as zf:  # a meta of 2 MiB (the schema allows 1 MiB)
        zf.writestr("meta.npy", data[:128] + b" " * (2 << 20))
    with pytest.raises(CheckpointError, match="more than its shape needs|holds"):
        checkpoints.read(path)


def test_resume_from_a_negative_pass_count_is_refused(tmp_path, monkeypatch, capsys, scene):
    """Was `malloc_consolidate(): invalid chunk size` (exit 134): now one line, exit 1."""
    monkeypatch.chdir(tmp_path)
    good_checkpoint(tmp_path / "c.ckpt.npz", scene)
    rewrite(tmp_path / "c.ckpt.npz", passes=np.int64(-5))
    code, lines = cli(capsys, "render", CORNELL, "-o", "o.exr", "--resume", "--checkpoint", "c.ckpt.npz", *TINY)
    assert code == 1 and "pass count -5" in one_error(lines)
    assert not (tmp_path / "o.exr").exists()


def test_wavefront_refuses_a_negative_first_pass(device):
    from scenes_small import small_scene
    from pyopencl_rt.render.wavefront import Wavefront

    wf = Wavefront(small_scene(8, 8), device)
    film = Film(8, 8)
    for bad in ({"first_pass": -1}, {"first_pass": 1.5}, {"passes": -2}):
        with pytest.raises(ValueError):
            wf.run(film, **{"passes": 1, **bad})
    assert film.passes == 0 and not film.sum.any()
    wf.run(film, passes=1, first_pass=3)  # the same Wavefront still renders
    assert film.passes == 1 and np.isfinite(film.sum).all() and film.sum.any()


# -- the Python API says what the CLI says -------------------------------------------------------
API_CASES = [
    (dict(spp=2.5), "--spp must be an integer, got float 2.5"),
    (dict(spp="4"), "--spp must be an integer, got string '4'"),
    (dict(spp=0), "--spp must be at least 1 (got 0)"),
    (dict(spp=2**31), "--spp must be at most 2147483647 (got 2147483648)"),
    (dict(spp=True), "--spp must be an integer, got boolean true"),
    (dict(width=0), "--width must be at least 1 (got 0)"),
    (dict(seed=2**32), "--seed must be at most 4294967295 (got 4294967296)"),
    (dict(seed=-1), "--seed must be at least 0 (got -1)"),
    (dict(wave_size=0), "--wave-size must be at least 1 (got 0)"),
    (dict(wave_size=2**40), "--wave-size must be at most"),
    (dict(time_limit=float("nan")), "--time-limit must be finite"),
    (dict(intersector="optix"), "unknown intersector 'optix'"),
    (dict(device=3), "--device must be a spec"),
    (dict(scheduler="foo"), "expected tcp://host:port"),
    (dict(checkpoint_every=1.0), "--checkpoint-every needs a checkpoint file"),
    (dict(resume=True), "--resume needs a checkpoint file"),
    (dict(checkpoint="/proc/x.ckpt.npz"), "cannot write the checkpoint"),
]


@pytest.mark.parametrize("kwargs,message", API_CASES, ids=[repr(c[0]) for c in API_CASES])
def test_api_refuses_bad_arguments_with_the_cli_message(kwargs, message):
    with pytest.raises(UserError) as info:
        rt.render(CORNELL, **kwargs)
    assert message in str(info.value) and "\n" not in str(info.value)


def test_cli_and_api_messages_are_the_same(tmp_path, monkeypatch, capsys):
    monkeypatch.chdir(tmp_path)
    for option, kwargs in ((["--spp", "0"], dict(spp=0)), (["--seed", "-1"], dict(seed=-1)),
                           (["--wave-size", "0"], dict(wave_size=0))):
        _code, lines = cli(capsys, "render", CORNELL, *option)
        with pytest.raises(UsageError) as info:
            rt.render(CORNELL, **kwargs)
        assert one_error(lines) == f"pyopencl-rt: error: {info.value}"


def test_render_accepts_a_scene_path(scene):
    by_path = rt.render(CORNELL, spp=1, width=4, height=4, device="cpu", seed=3)
    by_scene = rt.render(scene, spp=1, width=4, height=4, device="cpu", seed=3)
    assert by_path.shape == (4, 4, 3) and np.array_equal(by_path, by_scene)
    with pytest.raises(UsageError, match="scene must be a Scene or a scene file's path"):
        rt.render(42)


def test_seed_is_never_wrapped():
    """2^32 used to give the image of seed 0; -1 was recorded as 4294967295."""
    for seed in (2**32, -1, 2**64):
        with pytest.raises(UsageError):
            ImageSettings.resolve(rt.load_scene(CORNELL), seed=seed)
    assert ImageSettings.resolve(rt.load_scene(CORNELL), seed=2**32 - 1).seed == 2**32 - 1


RAY_CASES = [
    (dict(origins=np.zeros((3, 5))), "origins must have shape (N, 3) or (3,), got (3, 5)"),
    (dict(origins=np.zeros((5, 3), complex)), "origins must hold real numbers, got dtype complex128"),
    (dict(origins=[[0, 0, -1], [np.nan, 0, 0]]), "origins has 1 non-finite values"),
    (dict(origins=np.full((1, 3), 1e39)), "beyond float32's range"),
    (dict(origins="abc"), "origins must hold real numbers"),
    (dict(directions=np.zeros((2, 3), bool)), "directions must hold real numbers, got dtype bool"),
    (dict(directions=[0, 0, 0]), "directions has 1 zero vectors"),
    (dict(origins=np.zeros((4, 3)), directions=np.ones((5, 3))), "differ in length"),
    (dict(tmin=np.nan), "tmin has 1 non-finite values"),
    (dict(tmax=np.zeros(7)), "tmax must be a number or have shape (1,)"),
    (dict(origins=[[0, 0, 2**25]]), None),  # an integer float32 holds exactly
    (dict(origins=np.array([[0, 0, 2**25 + 1]])), "integers that float32 cannot hold exactly"),
]


@pytest.mark.parametrize("backend", ["embree", "opencl"])
@pytest.mark.parametrize("case,message", RAY_CASES, ids=[str(i) for i in range(len(RAY_CASES))])
def test_trace_arguments_are_never_reshaped_or_truncated(case, message, backend):
    mesh = (np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]]))
    args = dict(origins=[[0.0, 0.0, -1.0]], directions=[0.0, 0.0, 1.0], tmin=0.0, tmax=np.inf) | case
    if message is None:
        hits = rt.trace(mesh, args["origins"], args["directions"], device="cpu", backend=backend)
        assert hits["prim_id"].tolist() == [-1]  # 2^25 away along +z: behind the direction
        return
    for fn in (rt.trace, rt.occluded):
        with pytest.raises(UsageError) as info:
            fn(mesh, args["origins"], args["directions"], args["tmin"], args["tmax"], device="cpu", backend=backend)
        assert message in str(info.value)


# -- scene values beyond what float32 holds ------------------------------------------------------
BIG_SCENES = {
    "box x1e38": ('[[shape]]\ntype = "box"\nscale = 1e38\n', "[[shape]] #2 (box): its vertices reach 5e+37"),
    "sphere r 1e39": ('[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1e39\n', "it reaches 1e+39"),
    "emitter r 1e30": ('[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1e30\nmaterial = "light"\n',
                       "it reaches 1e+30"),
    "sphere r 1e-50": ('[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1e-50\n', "'radius' 1e-50 is 0 in float32"),
    "triangle 1e20": ('[[shape]]\ntype = "triangle"\npoints = [[0, 0, 0], [1e20, 0, 0], [0, 1, 0]]\n',
                      "its vertices reach 1e+20"),
    "camera 1e39": ('[camera]\neye = [0, 0, 1e39]\nlook_at = [0, 0, 0]\n', "camera eye"),
}


@pytest.mark.parametrize("case", list(BIG_SCENES))
def test_values_that_overflow_float32_are_refused_when_loaded(tmp_path, case):
    extra, message = BIG_SCENES[case]
    path = tmp_path / "big.toml"
    path.write_text('[materials.light]\nemission = 1\n[[shape]]\ntype = "quad"\nmaterial = "light"\n'
                    'points = [[0, 2, 0], [1, 2, 0], [1, 2, 1], [0, 2, 1]]\n' + extra)
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("error")  # no numpy RuntimeWarning on the way
        with pytest.raises(UserError) as info:
            rt.load_scene(path)
    assert str(info.value).startswith(str(path)) and message in str(info.value), str(info.value)


def test_scene_made_in_python_is_checked_too():
    from scenes_small import small_scene

    for change, message in ((lambda s: setattr(s, "vertices", s.vertices * np.float32(1e13)), "beyond 1.1e+12"),
                            (lambda s: setattr(s, "faces", s.faces + 10), "face vertex indices"),
                            (lambda s: setattr(s.materials[2], "emission", (np.nan, 0, 0)), "emission must be >= 0"),
                            (lambda s: setattr(s.settings, "spp", 0), "settings: spp must be at least 1"),
                            (lambda s: setattr(s.settings, "spp", 2**31), "settings: spp must be at most 2147483647")):
        s = small_scene(8, 8)
        change(s)
        with pytest.raises(UserError, match=message.replace("+", r"\+").replace("(", r"\(")):
            rt.render(s, device="cpu")


# -- one way to report -----------------------------------------------------------------------------
def test_warnings_are_one_line_through_one_logger(tmp_path):
    """A real process (pytest records warnings itself): the warning is one line, not Python's
    format with the source path and a line of code."""
    scene = tmp_path / "dark.toml"
    scene.write_text('[film]\nwidth = 4\nheight = 4\n[[shape]]\ntype = "sphere"\ncenter = [0, 0, 0]\nradius = 1\n')
    env = dict(os.environ, PYTHONPATH=str(REPO))
    r = subprocess.run([sys.executable, "-c", "from pyopencl_rt.cli import main; main()", "render", str(scene),
                        "-o", "o.exr", "--spp", "1", "-q", "--device", "cpu"],
                       cwd=tmp_path, env=env, capture_output=True, text=True, timeout=300)
    assert r.returncode == 0, r.stderr
    assert r.stderr.splitlines() == ["pyopencl-rt: warning: scene has no lights: the image will be black"]


def test_click_usage_errors_are_one_line_too(capsys):
    code, lines = cli(capsys, "render", "x.toml", "--no-such-option")
    assert code == 2 and "No such option '--no-such-option'" in one_error(lines) and "--help" in lines[0]


# -- bench options ---------------------------------------------------------------------------------
@pytest.mark.parametrize("args,code,message", [
    (["bench", "rays", "--sizes", "abc"], 2, "'abc' is not a size"),
    (["bench", "rays", "--sizes", ","], 2, "no size given"),
    (["bench", "rays", "--repeat", "0"], 2, "'--repeat': 0 is not in the range x>=1"),
    (["bench", "render", "--width", "0"], 2, "'--width': 0 is not in the range x>=1"),
    (["bench", "bvh", "--sweep-size", "-1"], 2, "--sweep-size"),
    (["bench", "mitsuba-cornell-box", "--spp", "0"], 2, "positive integers"),
])
def test_bench_options(capsys, args, code, message):
    got, lines = cli(capsys, *args)
    assert got == code and message in one_error(lines)


def test_bench_json_is_checked_before_running(monkeypatch, capsys):
    import pyopencl_rt.bench.rays as rays

    monkeypatch.setattr(rays, "run_ray_bench", lambda **kw: pytest.fail("the benchmark ran"))
    code, lines = cli(capsys, "bench", "rays", "--sizes", "1k", "--json", "/proc/x.json")
    assert code == 1 and "/proc/x.json: cannot write the JSON file" in one_error(lines)


# -- signals ---------------------------------------------------------------------------------------
@pytest.mark.parametrize("delay", [1.0, 2.5], ids=["while-starting", "before-first-pass"])
def test_sigint_before_the_first_pass_exits_cleanly(tmp_path, delay):
    """Ctrl-C while starting or before the first pass completes: exit 130, one line, no output
    and no 0-pass checkpoint.  (A 2048x2048 first pass in waves of 4096 paths takes seconds on
    the CPU device; the wavefront stops between waves, the megakernel only between passes.)"""
    env = dict(os.environ, PYTHONPATH=str(REPO))
    env.pop("PYOPENCL_CTX", None)
    p = subprocess.Popen([sys.executable, "-c", "from pyopencl_rt.cli import main; main()", "render", CORNELL,
                          "-o", "o.exr", "--width", "2048", "--height", "2048", "--spp", "4", "--wave-size", "4096", "-q",
                          "--device", "cpu", "--kernel-mode", "wavefront"],
                         cwd=tmp_path, env=env, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    time.sleep(delay)
    p.send_signal(signal.SIGINT)
    out, err = p.communicate(timeout=120)
    assert p.returncode == 130, err
    assert "Traceback" not in err and err.strip().count("\n") == 0 and "interrupted" in err, err
    assert list(tmp_path.iterdir()) == []


# -- adaptive sampling: what it cannot be combined with, from the scene file and the API -----------
def test_adaptive_from_the_scene_file_refused_where_it_cannot_run(tmp_path, monkeypatch, capsys):
    """[render] adaptive = true decides only once the scene is read: still one line, nothing
    rendered or written; the API says the same."""
    monkeypatch.chdir(tmp_path)
    scene = tmp_path / "adaptive.toml"
    scene.write_text(Path(CORNELL).read_text().replace("[render]", "[render]\nadaptive = true", 1))
    code, lines = cli(capsys, "render", scene, "--scheduler", "local:1", *TINY[:-2])
    assert code == 2 and "--adaptive renders on one device: it cannot be combined with --scheduler" in one_error(lines)
    code, lines = cli(capsys, "render", CORNELL, "--target-error", "0.1", *TINY)
    assert code == 2 and "--target-error needs --adaptive" in one_error(lines)
    assert sorted(p.name for p in tmp_path.iterdir()) == ["adaptive.toml"]
    import pyopencl as cl

    cpu = [d for p in cl.get_platforms() for d in p.get_devices() if d.type & cl.device_type.CPU][0]
    with pytest.raises(UserError, match="--adaptive renders on one device, not 2: choose one with --device"):
        rt.render_full(str(scene), spp=1, width=4, height=4, device=[cpu, cpu])
    with pytest.raises(UserError, match="--adaptive renders on one device"):
        rt.render_full(str(scene), spp=1, width=4, height=4, scheduler="local:1")
    with pytest.raises(UserError, match="cannot be combined with --resume"):
        rt.render_full(str(scene), spp=1, width=4, height=4, checkpoint=str(tmp_path / "c.npz"), resume=True)


def test_a_ctrl_c_python_had_to_ignore_still_stops_the_render():
    """A SIGINT whose KeyboardInterrupt lands in a callback Python ignores (seen during start-up under
    load: an import's module-lock callback; the render then went on to the end and exited 0) is still
    recorded: the render's signal watch starts stopped, and the ignored exception prints nothing."""
    import pyopencl_rt.errors as errors
    from pyopencl_rt.render.checkpoint import stop_on_signals

    saved = signal.getsignal(signal.SIGINT), sys.unraisablehook
    try:
        errors.watch_sigint()
        with stop_on_signals() as stop:
            assert not stop.is_set()
        with pytest.raises(KeyboardInterrupt):
            signal.raise_signal(signal.SIGINT)
        assert errors.SIGINT_SEEN.is_set()
        with stop_on_signals() as stop:
            assert stop.is_set()
        printed = []
        sys.stderr, real = type("W", (), {"write": lambda self, s: printed.append(s), "flush": lambda self: None})(), \
            sys.stderr
        try:
            sys.unraisablehook(type("U", (), {"exc_type": KeyboardInterrupt, "exc_value": KeyboardInterrupt(),
                                              "exc_traceback": None, "err_msg": None, "object": None})())
        finally:
            sys.stderr = real
        assert printed == []
    finally:
        errors.SIGINT_SEEN.clear()
        signal.signal(signal.SIGINT, saved[0])
        sys.unraisablehook = saved[1]
