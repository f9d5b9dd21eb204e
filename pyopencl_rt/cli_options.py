"""The click options and argument checks that several ``pyopencl-rt`` commands share."""
from __future__ import annotations

import os

import click

from .errors import UsageError


def device_option(f):
    """``--device``, shared by every command (repeatable, or comma-separated)."""
    return click.option(
        "--device", "-d", "device", multiple=True, metavar="SPEC",
        help="cpu, gpu, all, P:D (index or name substring, as in PYOPENCL_CTX), or a name substring; "
        "repeatable. Default: $PYOPENCL_CTX, else the first GPU, else the PoCL CPU device.",
    )(f)


def _mitsuba_lanes(ctx, param, value):
    """--mitsuba-lanes reaches the Mitsuba processes through their environment, as our own width
    ($PYOPENCL_RT_LANES) reaches our kernels."""
    from .bench.mitsuba_runner import LANES_ENV

    if value:
        os.environ[LANES_ENV] = value
    return value


def mitsuba_options(f):
    """Where Mitsuba 3 and the libLLVM of its llvm_* variants are (nothing is guessed), the variant
    and its vector width."""
    f = click.option("--mitsuba-lanes", type=click.Choice(["4", "8", "16", "avx2"]), expose_value=False,
                     callback=_mitsuba_lanes,
                     help="Vector width of Mitsuba's llvm_* variants on the host's instruction set, or avx2: 8 lanes "
                     "compiled for Haswell [default: $PYOPENCL_RT_MITSUBA_LANES, else Dr.Jit's choice, the "
                     "widest]. With PYOPENCL_RT_LANES=8 they stand in for an AVX2 machine.")(f)
    f = click.option("--mitsuba-variant", default="llvm_ad_rgb", show_default=True)(f)
    f = click.option("--llvm-path", type=click.Path(dir_okay=False),
                     help="libLLVM shared library for the llvm_* variants [default: $DRJIT_LIBLLVM_PATH, "
                     "else Dr.Jit's own search].")(f)
    f = click.option("--mitsuba-python", type=click.Path(dir_okay=False),
                     help="Interpreter that imports mitsuba [default: $PYOPENCL_RT_MITSUBA_PYTHON, else this one].")(f)
    return f


def seed_options(default: int):
    """--seeds and --first-seed of the convergence benchmarks: each curve rendered with that many
    seeds, sharing its budget, its relMSE their mean."""
    def add(f):
        f = click.option("--first-seed", default=0, show_default=True, type=click.IntRange(0, 2**31),
                         help="Seeds from this one on (ours 1 + it + k, Mitsuba's offset it + k): another run, "
                         "other seeds.")(f)
        return click.option("--seeds", default=default, show_default=True, type=click.IntRange(min=1),
                            help="Renders of each curve, a seed each, sharing its budget: the relMSE is their "
                            "mean.")(f)
    return add


def check_json(json_path) -> None:
    """A benchmark's --json file must be writable before the benchmark runs (minutes of it)."""
    from . import validate

    if json_path is not None:
        validate.writable_file(json_path, "JSON file")


def comma_list(text, allowed, what):
    """'a,b' -> ["a", "b"], refusing a name not in ``allowed`` with one line that lists them."""
    names = [name.strip() for name in text.split(",") if name.strip()]
    for name in names:
        if name not in allowed:
            raise UsageError(f"unknown {what} {name!r}: use one or more of {', '.join(allowed)}")
    return names


def parse_intersectors(text):
    from .render.intersectors import INTERSECTORS

    return comma_list(text, INTERSECTORS, "intersector")
