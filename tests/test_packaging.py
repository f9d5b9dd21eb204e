"""The kernel sources are found in a checkout and in an installed wheel."""
import json
import os
import shutil
import subprocess
import sys
import textwrap
import zipfile
from pathlib import Path

from pyopencl_rt.device import kernels

REPO = Path(__file__).resolve().parents[1]


def test_cl_dir_in_checkout():
    assert kernels.cl_dir() == REPO / "cl"
    assert (kernels.cl_dir() / "accel" / "trace.cl").is_file()


def _copy_sources(dst: Path):
    """Tracked and untracked-but-not-ignored files, as they are in the working tree."""
    try:
        listed = subprocess.run(
            ["git", "ls-files", "-co", "--exclude-standard", "-z"], cwd=REPO, check=True,
            capture_output=True,
        ).stdout.decode().split("\0")
        for rel in filter(None, listed):
            src = REPO / rel
            if src.is_file():  # tracked files deleted in the working tree are skipped
                (dst / rel).parent.mkdir(parents=True, exist_ok=True)
                shutil.copy2(src, dst / rel)
    except (OSError, subprocess.CalledProcessError):  # not a git checkout (an sdist, say)
        shutil.copytree(REPO, dst, dirs_exist_ok=True, ignore=shutil.ignore_patterns(
            ".git", ".venv", "build", "dist", "*.egg-info", "__pycache__", ".pytest_cache", ".hypothesis", "out"))


# The probe runs in a fresh environment holding only the built wheel and its dependencies, on the
# PoCL CPU those dependencies ship (pocl-binary-distribution): it checks that the installed package
# finds and builds its kernels, which no particular device adds to.
PROBE = textwrap.dedent("""
    import json, sys
    import numpy as np
    import pyopencl_rt
    from pyopencl_rt.device import kernels
    hit = pyopencl_rt.trace(
        (np.array([[0, 0, 0], [1, 0, 0], [0, 1, 0]], np.float32), np.array([[0, 1, 2]], np.int32)),
        [[0.25, 0.25, 2.5]], [[0, 0, -1]], device="cpu")
    print(json.dumps({"package": pyopencl_rt.__file__, "cl_dir": str(kernels.cl_dir()),
                      "t": float(hit["t"][0]), "prim_id": int(hit["prim_id"][0]),
                      "u": float(hit["u"][0]), "v": float(hit["v"][0])}))
""")


def test_wheel_ships_and_finds_the_kernels(tmp_path):
    clutter_before = {p.name for p in REPO.iterdir() if p.name == "build" or p.name.endswith(".egg-info")}
    src, dist, site, elsewhere = (tmp_path / n for n in ("src", "dist", "site", "elsewhere"))
    for d in (src, dist, elsewhere):
        d.mkdir()
    _copy_sources(src)
    env = dict(os.environ, PIP_DISABLE_PIP_VERSION_CHECK="1", PIP_NO_INPUT="1")
    env.pop("PYTHONPATH", None)
    subprocess.run([sys.executable, "-m", "pip", "wheel", "--no-deps", "--no-build-isolation", "-q",
                    "-w", str(dist), str(src)], check=True, env=env, cwd=tmp_path, capture_output=True)
    (wheel,) = dist.glob("pyopencl_rt-*.whl")

    names = set(zipfile.ZipFile(wheel).namelist())
    expected = {f"pyopencl_rt/cl/{p.relative_to(REPO / 'cl').as_posix()}"
                for p in (REPO / "cl").rglob("*") if p.suffix in (".h", ".cl")}
    assert {"pyopencl_rt/cl/accel/intersect.h", "pyopencl_rt/cl/accel/bvh.h", "pyopencl_rt/cl/accel/trace.cl"} <= expected
    assert expected <= names, f"missing from the wheel: {sorted(expected - names)}"
    assert not any(n.startswith(("tests/", "cl/")) for n in names)

    subprocess.run([sys.executable, "-m", "pip", "install", "--no-deps", "-q", "--target", str(site), str(wheel)],
                   check=True, env=env, cwd=tmp_path, capture_output=True)
    run_env = dict(env, PYTHONPATH=str(site))
    run_env.pop("PYOPENCL_CTX", None)
    r = subprocess.run([sys.executable, "-c", PROBE], cwd=elsewhere, env=run_env, capture_output=True, text=True,
                       timeout=300)
    assert r.returncode == 0, r.stderr
    got = json.loads(r.stdout.strip().splitlines()[-1])
    assert Path(got["package"]).resolve().is_relative_to(site.resolve())
    assert Path(got["cl_dir"]).resolve() == (site / "pyopencl_rt" / "cl").resolve()
    assert got["prim_id"] == 0
    assert abs(got["t"] - 2.5) < 1e-6
    assert abs(got["u"] - 0.25) < 1e-6 and abs(got["v"] - 0.25) < 1e-6

    clutter_after = {p.name for p in REPO.iterdir() if p.name == "build" or p.name.endswith(".egg-info")}
    assert clutter_after == clutter_before, "the wheel build left build/ or *.egg-info in the checkout"
