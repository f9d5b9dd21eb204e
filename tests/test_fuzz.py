"""Fuzzing the inputs (issue 13): scene files, CLI options, API arguments, ray arrays and
checkpoints, each drawn by hypothesis.  The property is the same everywhere: **a clean error or
a finite image** -- a UserError whose message is one line (the CLI: exit 1 or 2 with one
``pyopencl-rt: error:`` line), or a result whose image is finite; never another exception, never
a numpy RuntimeWarning on the way, never a crash.

Sizes: the quick variant runs in ``make test`` (a few seconds once the kernels are cached), the
long one (marked ``stress``) in ``make stress``.  Each test reports its outcome counts through
the ``measured`` fixture (docs/ROBUSTNESS.md lists them).  Examples are derandomized: the same
inputs every run.
"""
import json
import math
import os
import warnings
from collections import Counter
from pathlib import Path

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import pyopencl_rt as rt
from pyopencl_rt.cli import main
from pyopencl_rt.errors import UserError
from pyopencl_rt.imageio import read_exr
from pyopencl_rt.render import checkpoint as checkpoints
from pyopencl_rt.render.checkpoint_schema import CheckpointError
from pyopencl_rt.render.film import Film
from pyopencl_rt.render.settings import ImageSettings

REPO = Path(__file__).resolve().parents[1]
CORNELL = str(REPO / "scenes" / "cornell-box.toml")
SIZES = {  # examples per test
    "quick": dict(scene=20, cli=20, api=20, rays=60, checkpoint=80),
    "long": dict(scene=400, cli=300, api=300, rays=1500, checkpoint=2000),
}


def sized():
    return [pytest.param("quick", id="quick"), pytest.param("long", id="long", marks=pytest.mark.stress)]


def fuzz_settings(n):
    return settings(max_examples=n, deadline=None, derandomize=True, database=None,
                    suppress_health_check=list(HealthCheck))


def numpy_warnings(caught):
    """numpy's own warnings ('overflow encountered in ...'): values that got past the checks."""
    return [str(w.message) for w in caught if "encountered in" in str(w.message)]


def clean_error(exc):
    text = str(exc)
    assert isinstance(exc, UserError), f"{type(exc).__name__}: {text}"
    assert text and "\n" not in text and "Traceback" not in text, text
    return type(exc).__name__


# -- values that break things ---------------------------------------------------------------------
EDGE_FLOATS = [0.0, -0.0, 1.0, -1.0, 0.5, 1e-50, 1e-45, 1e-30, 1e12, 1e20, 1e30, 3.4e38, 1e39, -1e39,
               math.inf, -math.inf, math.nan]
EDGE_INTS = [0, 1, -1, 2, 3, 255, 2**24 + 1, 2**31, 2**32, 2**63 - 1, -2**63]
numbers = st.one_of(st.sampled_from(EDGE_FLOATS), st.sampled_from(EDGE_INTS),
                    st.floats(allow_nan=True, allow_infinity=True), st.integers(-2**63, 2**63 - 1))
scalars = st.one_of(numbers, st.booleans(), st.sampled_from(["", "x", "path", "gold", "../etc", "é"]))
values = st.one_of(scalars, st.lists(numbers, max_size=5), st.lists(st.lists(numbers, max_size=4), max_size=5),
                   st.just({}), st.dictionaries(st.sampled_from(["axis", "angle", "x"]), numbers, max_size=2))


# -- scene files ----------------------------------------------------------------------------------
BASE_SCENE = {
    "camera": {"eye": [0, 1, 4], "look_at": [0, 1, 0], "fov": 45},
    "film": {"width": 4, "height": 4},
    "render": {"spp": 1, "max_depth": 3},
    "materials": {"white": {"albedo": [0.7, 0.7, 0.7]}, "light": {"emission": [4, 4, 4], "two_sided": True},
                  "metal": {"type": "conductor", "metal": "gold", "roughness": 0.3},
                  "glass": {"type": "dielectric", "ior": 1.5}},
    "shape": [
        {"type": "quad", "material": "light", "points": [[-1, 3, -1], [1, 3, -1], [1, 3, 1], [-1, 3, 1]]},
        {"type": "box", "material": "white", "size": 1, "center": [0, 0.5, 0], "rotate": {"axis": [0, 1, 0], "angle": 30}},
        {"type": "sphere", "material": "metal", "center": [1, 1, 0], "radius": 0.5},
        {"type": "triangle", "material": "glass", "points": [[-2, 0, -2], [2, 0, -2], [0, 0, 2]], "scale": 1,
         "translate": [0, 0, 0]},
    ],
    "light": [{"type": "point", "position": [0, 2, 0], "intensity": 5},
              {"type": "directional", "direction": [0, -1, 0], "irradiance": 1}],
}


def leaves(doc, path=()):
    if isinstance(doc, dict):
        for k, v in doc.items():
            yield from leaves(v, path + (k,))
    elif isinstance(doc, list) and doc and isinstance(doc[0], dict):
        for i, v in enumerate(doc):
            yield from leaves(v, path + (i,))
    yield path


LEAVES = [p for p in leaves(BASE_SCENE) if p]


def toml_value(v):
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        return "nan" if math.isnan(v) else ("inf" if v > 0 else "-inf") if math.isinf(v) else repr(v)
    if isinstance(v, str):
        return json.dumps(v)
    if isinstance(v, dict):
        return "{" + ", ".join(f"{k} = {toml_value(x)}" for k, x in v.items()) + "}"
    return "[" + ", ".join(toml_value(x) for x in v) + "]"


def to_toml(doc) -> str:
    out = []
    for key, value in doc.items():
        if isinstance(value, dict) and key == "materials":
            for name, table in value.items():
                out.append(f"[materials.{name}]" if isinstance(table, dict) else f"materials = {toml_value(value)}")
                if isinstance(table, dict):
                    out += [f"{k} = {toml_value(v)}" for k, v in table.items()]
        elif isinstance(value, dict):
            out.append(f"[{key}]")
            out += [f"{k} = {toml_value(v)}" for k, v in value.items()]
        elif isinstance(value, list) and value and all(isinstance(t, dict) for t in value):
            for table in value:
                out.append(f"[[{key}]]")
                out += [f"{k} = {toml_value(v)}" for k, v in table.items()]
        else:
            out.insert(0, f"{key} = {toml_value(value)}")
    return "\n".join(out) + "\n"


FACTORS = [0.0, -1.0, 1e-40, 1e-20, 1e-3, 0.5, 2.0, 1e3, 1e11, 1e13, 1e30, 1e38, 1e40]


def scaled(value, factor):
    """``value`` (a number or nested lists of them) times ``factor``: the same shape, other magnitudes."""
    if isinstance(value, bool) or not isinstance(value, (int, float, list)):
        return value
    if isinstance(value, list):
        return [scaled(v, factor) for v in value]
    return value * factor


@st.composite
def scene_docs(draw):
    doc = json.loads(json.dumps(BASE_SCENE))
    for _ in range(draw(st.integers(1, 3))):
        path = draw(st.sampled_from(LEAVES))
        parent = doc
        try:
            for k in path[:-1]:
                parent = parent[k]
            action = draw(st.sampled_from(["scale", "scale", "scale", "set", "delete", "add"]))
            if action == "scale":
                parent[path[-1]] = scaled(parent[path[-1]], draw(st.sampled_from(FACTORS)))
            elif action == "set":
                parent[path[-1]] = draw(values)
            elif action == "delete":
                del parent[path[-1]]
            elif isinstance(parent, dict):
                parent[draw(st.sampled_from(["extra", "type", "file", "matrix", "flip_normals"]))] = draw(values)
        except (KeyError, IndexError, TypeError):
            pass  # an earlier mutation removed or replaced the parent
    return doc


@pytest.mark.parametrize("size", sized())
def test_fuzz_scene_files(tmp_path_factory, measured, size):
    counts = Counter()
    folder = tmp_path_factory.mktemp("scenes")

    @fuzz_settings(SIZES[size]["scene"])
    @given(doc=scene_docs())
    def check(doc):
        path = folder / "fuzz.toml"
        path.write_text(to_toml(doc))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                scene = rt.load_scene(path)
            except Exception as exc:  # noqa: BLE001 - the property: only a clean one-line UserError
                counts["refused: " + clean_error(exc)] += 1
                assert str(exc).startswith(str(path)), str(exc)
                return
            try:
                r = rt.render_full(scene, spp=1, width=4, height=4, device="cpu", seed=1)
            except Exception as exc:  # noqa: BLE001
                counts["refused at render: " + clean_error(exc)] += 1
                return
        assert not numpy_warnings(caught), numpy_warnings(caught)
        assert np.isfinite(r.image).all()
        counts["rendered"] += 1

    check()
    measured(f"fuzz scene files ({size}): {dict(sorted(counts.items()))}")
    assert counts["rendered"] > 0 and sum(counts.values()) >= SIZES[size]["scene"] // 2


# -- CLI options ----------------------------------------------------------------------------------
CLI_OPTIONS = {
    "--spp": ["0", "1", "2", "-3", "2.5", "1e3", "99999999999999999999", "abc", ""],
    "--width": ["-1", "0", "1", "3", "1.5", "x", "2147483648"],
    "--height": ["-1", "0", "2", "4", "65536000"],
    "--seed": ["-1", "0", "7", "4294967295", "4294967296", "18446744073709551616"],
    "--max-depth": ["-2", "-1", "0", "1", "3", "2147483648"],
    "--time-limit": ["0", "-1", "0.05", "nan", "inf", "1e-300"],
    "--wave-size": ["0", "-1", "64", "1000", "134217728", "1099511627776"],  # valid ones not tiny: slow, not wrong
    "--integrator": ["path", "bsdf", "nee", "mis"],
    "--intersector": ["opencl", "embree", "optix"],
    "--kernel-mode": ["auto", "wavefront", "megakernel", "warp"],
    "--checkpoint-every": ["0", "0.5", "-1", "nan"],
    "--exposure": ["-100", "0", "1.5", "nan", "inf"],
    "--tonemap": ["clamp", "filmic", "agx", "reinhard"],
    "--device": ["cpu", "0:0", "9:9", "", "gpu-nope"],
    "--device-timeout": ["0", "1", "-5", "nan"],
    "--scheduler": ["foo", "local:0", "local:99", "tcp://127.0.0.1:1", "tcp://"],
    "-o": ["out.exr", "out.png", "sub/dir/out.exr", "out.txt", "/proc/x.exr", ".", "out"],
    "--checkpoint": ["c.ckpt.npz", "/proc/c.npz", "out.exr", "."],
    "--aov": ["albedo", "all", "normal,depth", "nope", ""],
    "--sampler": ["sobol", "stratified", "independent", "multijitter", ""],
    "--target-error": ["0.05", "0", "-1", "nan", "inf", "1e-30", "x"],
}
FLAGS = ["--resume", "--profile", "--quiet", "--denoise", "--no-exr", "--adaptive"]


@st.composite
def cli_args(draw):
    chosen = draw(st.lists(st.sampled_from(sorted(CLI_OPTIONS)), max_size=5, unique=True))
    args = []
    for opt in chosen:
        args += [opt, draw(st.sampled_from(CLI_OPTIONS[opt]))]
    args += draw(st.lists(st.sampled_from(FLAGS), max_size=2, unique=True))
    return args


@pytest.mark.parametrize("size", sized())
def test_fuzz_cli_options(tmp_path_factory, monkeypatch, capsys, measured, size):
    counts = Counter()
    base = ["render", CORNELL, "--width", "4", "--height", "4", "--spp", "1", "-q", "--device", "cpu", "-o", "out.exr"]

    @fuzz_settings(SIZES[size]["cli"])
    @given(args=cli_args())
    def check(args):
        folder = tmp_path_factory.mktemp("cli")
        monkeypatch.chdir(folder)
        capsys.readouterr()
        try:
            main(base + args)
            code = 0
        except SystemExit as exc:
            code = exc.code
        err = capsys.readouterr().err.strip().splitlines()
        if "--profile" not in args:  # (--profile prints its table on stderr)
            assert all(line.startswith("pyopencl-rt: ") for line in err), err
        errors = [line for line in err if line.startswith("pyopencl-rt: error: ")]
        if code:
            assert code in (1, 2) and len(errors) == 1, (code, err)
            counts[f"exit {code}"] += 1
            return
        assert not errors, err
        images = [p for p in folder.rglob("*") if p.suffix == ".exr" and not p.name.startswith(".")]
        assert images or "--no-exr" in args, list(folder.rglob("*"))
        for image in images:
            assert np.isfinite(read_exr(image)).all()
        counts["rendered"] += 1

    check()
    measured(f"fuzz CLI options ({size}): {dict(sorted(counts.items()))}")
    assert counts["rendered"] > 0 and counts["exit 2"] > 0


# -- API arguments --------------------------------------------------------------------------------
API_VALUES = {
    "spp": [None, 1, 2, 0, -1, 2.5, 2.0, "4", True, np.int64(2), [], 2**63],
    "width": [4, 0, -4, 4.0, 4.5, "4", np.uint8(4), 2**40],  # (None: the scene's 512, slow not wrong)
    "height": [3, 0, 1, 8.5],
    "seed": [None, 0, 1, -1, 2**32 - 1, 2**32, 1.5, "7", np.int64(3)],
    "max_depth": [None, -1, 0, 1, 4, -7, 2.5],
    "rr_depth": [None, 0, 3, -1, "x"],
    "integrator": [None, "path", "bsdf", "nee", "x", 3],
    "time_limit": [None, 0.05, 0, -1, math.nan, math.inf, "1"],
    "wave_size": [None, 64, 1000, 0, -1, 2**40, 3.5, "64"],
    "intersector": ["opencl", "embree", "optix", None, 0],
    "device": [None, "cpu", "0:0", ["cpu"], 3, "9:9", object()],
    "kernel_mode": [None, "auto", "wavefront", "megakernel", "warp"],
    "checkpoint_every": [None, 1.0, 0, math.nan],
    "resume": [False, True, "yes"],
    "profile": [False, True, 1],
    "scheduler": [None, "foo", "local:0", "tcp://127.0.0.1:1"],
    "sampler": [None, "sobol", "independent", "multijitter", 1],
    "adaptive": [None, False, True, "yes", 1],
    "target_error": [None, 0.05, 0, -1, math.nan, math.inf, "0.1"],
}


@pytest.mark.parametrize("size", sized())
def test_fuzz_api_arguments(measured, size):
    counts = Counter()
    keys = sorted(API_VALUES)

    @fuzz_settings(SIZES[size]["api"])
    @given(data=st.data())
    def check(data):
        chosen = data.draw(st.lists(st.sampled_from(keys), max_size=5, unique=True))
        kwargs = {k: data.draw(st.sampled_from(API_VALUES[k]), label=k) for k in chosen}
        kwargs.setdefault("spp", 1)
        kwargs.setdefault("width", 4)
        kwargs.setdefault("height", 4)
        kwargs.setdefault("device", "cpu")
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                r = rt.render_full(CORNELL, **kwargs)
            except Exception as exc:  # noqa: BLE001
                counts["refused: " + clean_error(exc)] += 1
                return
        assert not numpy_warnings(caught)
        assert np.isfinite(r.image).all() and r.film.passes >= 1
        counts["rendered"] += 1

    check()
    measured(f"fuzz API arguments ({size}): {dict(sorted(counts.items()))}")
    assert counts["rendered"] > 0


# -- ray arrays -----------------------------------------------------------------------------------
SHAPES = [(3,), (1, 3), (5, 3), (3, 5), (0, 3), (5,), (5, 3, 1), (), (2, 4)]
DTYPES = [np.float32, np.float64, np.int32, np.int64, np.uint8, bool, np.complex64, object, str]


@st.composite
def arrays(draw):
    """Half plausible rays ((N, 3) or (3,) floats of ordinary sizes), half anything."""
    if draw(st.booleans()):
        shape, dtype, pool = draw(st.sampled_from([(3,), (1, 3), (5, 3)])), draw(st.sampled_from(DTYPES[:4])), \
            [0.25, -2.0, 3.0, 1.0, -0.5, 0.0, 1e-3, 7.0]
    else:
        shape, dtype, pool = draw(st.sampled_from(SHAPES)), draw(st.sampled_from(DTYPES)), EDGE_FLOATS + [0.25, -2.0]
    n = int(np.prod(shape))
    picks = draw(st.lists(st.sampled_from(pool), min_size=n, max_size=n))
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore")
        try:
            return np.array(picks, dtype=np.float64).astype(dtype).reshape(shape)
        except (ValueError, OverflowError):
            return np.array(picks, dtype=object).reshape(shape)


@pytest.mark.parametrize("size", sized())
def test_fuzz_ray_arrays(measured, size):
    counts = Counter()
    mesh = (np.array([[-1, -1, 0], [1, -1, 0], [0, 1, 0], [2, 2, 1]], np.float32), np.array([[0, 1, 2], [1, 3, 2]]))
    bvh = rt.build_bvh(*mesh)

    @fuzz_settings(SIZES[size]["rays"])
    @given(o=arrays(), d=arrays(), tmin=st.one_of(st.just(0.0), st.sampled_from(EDGE_FLOATS), arrays()),
           tmax=st.one_of(st.just(np.inf), st.sampled_from(EDGE_FLOATS), arrays()),
           backend=st.sampled_from(["embree", "opencl"]),
           any_hit=st.booleans())
    def check(o, d, tmin, tmax, backend, any_hit):
        fn = rt.occluded if any_hit else rt.trace
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            try:
                out = fn(bvh, o, d, tmin, tmax, device="cpu", backend=backend)
            except Exception as exc:  # noqa: BLE001
                counts["refused: " + clean_error(exc)] += 1
                return
        assert not numpy_warnings(caught)
        # one row of either is used for every ray of the other (numpy's broadcasting: 1 and 0 give 0)
        n = np.broadcast_shapes((np.asarray(o).reshape(-1, 3).shape[0],), (np.asarray(d).reshape(-1, 3).shape[0],))[0]
        if any_hit:
            assert out.shape == (n,) and out.dtype == bool
        else:
            assert out["t"].shape == (n,) and set(np.unique(out["prim_id"])) <= {-1, 0, 1}
            hit = out["prim_id"] >= 0
            assert np.isfinite(out["t"][hit]).all() and np.isinf(out["t"][~hit]).all()
        counts["traced"] += 1

    check()
    measured(f"fuzz ray arrays ({size}): {dict(sorted(counts.items()))}")
    assert counts["traced"] > 0


# -- checkpoints ----------------------------------------------------------------------------------
@pytest.mark.parametrize("size", sized())
def test_fuzz_checkpoints(tmp_path_factory, measured, size):
    """Byte flips, truncations and splices of a valid checkpoint: CheckpointError, or a film that a
    render can continue (finite sums of the right shape, passes >= 0)."""
    counts = Counter()
    folder = tmp_path_factory.mktemp("ckpt")
    scene = rt.load_scene(CORNELL)
    settings_ = ImageSettings.resolve(scene, width=4, height=3)
    s = np.random.default_rng(0).random((12, 3))
    good = folder / "good.npz"
    checkpoints.save(good, Film(4, 3, sum=s, sum_sq=s * s, passes=2), scene, settings_)
    data = good.read_bytes()

    @fuzz_settings(SIZES[size]["checkpoint"])
    @given(cut=st.integers(0, len(data)), flips=st.lists(st.tuples(st.integers(0, len(data) - 1), st.integers(1, 255)),
                                                         max_size=8),
           splice=st.binary(max_size=64), mode=st.sampled_from(["flip", "truncate", "splice"]))
    def check(cut, flips, splice, mode):
        b = bytearray(data)
        if mode == "flip":
            for i, x in flips:
                b[i] ^= x
        elif mode == "truncate":
            b = b[:cut]
        else:
            b[cut:cut] = splice
        path = folder / "fuzz.npz"
        path.write_bytes(bytes(b))
        try:
            film, key, meta = checkpoints.read(path)
        except Exception as exc:  # noqa: BLE001
            assert isinstance(exc, CheckpointError), f"{type(exc).__name__}: {exc}"
            clean_error(exc)
            counts["refused"] += 1
            return
        assert film.passes >= 0 and film.sum.shape == (film.width * film.height, 3)
        assert np.isfinite(film.sum).all() and np.isfinite(film.sum_sq).all() and (film.sum_sq >= 0).all()
        counts["read"] += 1

    check()
    measured(f"fuzz checkpoints ({size}): {dict(sorted(counts.items()))}")
    assert counts["refused"] > 0 and counts["read"] > 0
