"""Checks of the values a user gives: CLI options, API arguments, output paths and ray arrays.

Each check returns the value converted (losslessly) to what the code below uses, or raises a
:class:`~pyopencl_rt.errors.UserError` whose message is one line naming the option as the CLI
spells it (``--spp``), so the command line and the Python API say the same thing.  They run
before anything is loaded onto a device (docs/ROBUSTNESS.md lists what each bad input gets).
"""
from __future__ import annotations

import math
import numbers
import os
import tempfile
from pathlib import Path

import numpy as np

from .errors import OutputError, UsageError, UserError, one_line

FLOAT32_MAX = float(np.finfo(np.float32).max)
SEED_LIMIT = 1 << 32  # the kernels' RNG key is 32 bits


def describe(value) -> str:
    """A wrong value as messages show it: "string '4'", 'float 2.5', 'boolean true', ..."""
    if isinstance(value, (bool, np.bool_)):
        return f"boolean {str(bool(value)).lower()}"
    if isinstance(value, str):
        shown = value if len(value) <= 40 else value[:37] + "..."
        return f"string {shown!r}"
    if isinstance(value, numbers.Number):
        return f"{type(value).__name__} {value!r}"
    return f"a {type(value).__name__}"


def integer(value, name: str, *, minimum=None, maximum=None) -> int:
    """An int (or numpy integer, or a float without a fraction); never a bool or a string."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise UsageError(f"{name} must be an integer, got {describe(value)}")
    if isinstance(value, numbers.Integral):
        v = int(value)
    else:
        f = float(value)
        if not (math.isfinite(f) and f.is_integer()):
            raise UsageError(f"{name} must be an integer, got {describe(value)}")
        v = int(f)
    if minimum is not None and v < minimum:
        raise UsageError(f"{name} must be at least {minimum} (got {v})")
    if maximum is not None and v > maximum:
        raise UsageError(f"{name} must be at most {maximum} (got {v})")
    return v


def number(value, name: str, *, positive=False, minimum=None, maximum=None) -> float:
    """A finite real number (int or float; not a bool or a string)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, numbers.Real):
        raise UsageError(f"{name} must be a number, got {describe(value)}")
    v = float(value)
    if not math.isfinite(v):
        raise UsageError(f"{name} must be finite (got {v})")
    if positive and not v > 0:
        raise UsageError(f"{name} must be positive (got {v:g})")
    if minimum is not None and v < minimum:
        raise UsageError(f"{name} must be at least {minimum:g} (got {v:g})")
    if maximum is not None and v > maximum:
        raise UsageError(f"{name} must be at most {maximum:g} (got {v:g})")
    return v


def seed(value, name: str = "--seed") -> int:
    """A 32-bit seed, 0 .. 2^32 - 1 (as scene files require): never wrapped."""
    return integer(value, name, minimum=0, maximum=SEED_LIMIT - 1)


def choice(value, name: str, options) -> str:
    if not isinstance(value, str) or value not in options:
        shown = repr(value) if isinstance(value, str) else describe(value)
        raise UsageError(f"unknown {name} {shown}: use one of {', '.join(options)}")
    return value


def flag(value, name: str) -> bool:
    if not isinstance(value, (bool, np.bool_)):
        raise UsageError(f"{name} must be True or False, got {describe(value)}")
    return bool(value)


def path_text(value, name: str) -> str:
    """A file name: a str or os.PathLike, not empty."""
    if not isinstance(value, (str, os.PathLike)) or not str(os.fspath(value)).strip():
        raise UsageError(f"{name} must be a file name, got {describe(value)}")
    return os.fspath(value)


# -- output files ---------------------------------------------------------------------------------
def _existing_ancestor(folder: Path) -> Path:
    p = folder
    while not p.exists() and p != p.parent:
        p = p.parent
    return p


def writable_file(path, what: str) -> Path:
    """``path`` can be written the way outputs are (a temporary file beside it, then renamed):
    it is not a folder, and its folder exists and takes a new file, or can be created.  Checked
    by creating (and removing) an empty file there, which permissions alone do not tell (root,
    read-only or virtual file systems such as /proc)."""
    p = Path(path_text(path, what)).expanduser()
    if p.is_dir():
        raise OutputError(f"{p}: cannot write the {what}: it is a folder")
    if p.exists() and not p.is_file():
        raise OutputError(f"{p}: cannot write the {what}: it exists and is not a regular file")
    folder = p.parent if str(p.parent) else Path(".")
    ancestor = _existing_ancestor(folder.absolute())
    if not ancestor.is_dir():
        raise OutputError(f"{p}: cannot write the {what}: {ancestor} is not a folder")
    try:
        fd, probe = tempfile.mkstemp(dir=ancestor, prefix=".pyopencl-rt-probe-")
        os.close(fd)
        os.unlink(probe)
    except OSError as exc:
        raise OutputError(f"{p}: cannot write the {what}: {ancestor} does not take new files "
                          f"({exc.strerror or exc})") from None
    return p


def writable_files(named: dict) -> dict:
    """:func:`writable_file` for each ``{what: path}``; they must also be different files."""
    out = {what: writable_file(path, what) for what, path in named.items() if path is not None}
    seen = {}
    for what, p in out.items():
        key = os.path.normcase(os.path.abspath(p))
        if key in seen:
            raise UsageError(f"{p}: the {what} and the {seen[key]} would be the same file")
        seen[key] = what
    return out


def output_failure(path, exc: BaseException) -> OutputError:
    """One line for an OSError (or anything else) met while writing ``path``."""
    why = getattr(exc, "strerror", None) or one_line(exc) or type(exc).__name__
    return OutputError(f"{path}: cannot write ({why})")


# -- arrays ---------------------------------------------------------------------------------------
def _numbers(value, name):
    try:
        a = np.asarray(value)
    except Exception as exc:  # ragged lists and the like
        raise UsageError(f"{name} must be an array of numbers ({one_line(exc)})") from None
    if a.dtype.kind not in "fiu":
        raise UsageError(f"{name} must hold real numbers, got dtype {a.dtype}")
    return a


def _fits_float32(a, name, *, finite=True):
    if a.dtype.kind == "f":
        bad = ~np.isfinite(a) if finite else np.isnan(a)
        if bad.any():
            raise UsageError(f"{name} has {int(bad.sum())} {'non-finite' if finite else 'NaN'} values "
                             f"(first at index {np.argwhere(bad)[0].tolist()})")
        big = np.isfinite(a) & (np.abs(a) > FLOAT32_MAX)
        if big.any():
            raise UsageError(f"{name} has values beyond float32's range (largest {np.abs(a[big]).max():.3g})")
    elif a.size and (a.astype(np.float32).astype(np.float64) != a.astype(np.float64)).any():
        raise UsageError(f"{name} has integers that float32 cannot hold exactly (beyond 2^24)")


def float32_rows(value, name: str, width: int = 3) -> np.ndarray:
    """A ``(N, width)`` (or ``(width,)``: one row) array of real numbers that float32 holds, as
    contiguous float32.  Any other shape is refused, never reshaped: a ``(3, N)`` array is not N
    points."""
    a = _numbers(value, name)
    if a.ndim == 1 and a.shape[0] == width:
        a = a[None]
    if a.ndim != 2 or a.shape[1] != width:
        raise UsageError(f"{name} must have shape (N, {width}) or ({width},), got {tuple(a.shape)}")
    _fits_float32(a, name)
    return np.ascontiguousarray(a, np.float32)


def float32_per_row(value, name: str, n: int, *, allow_inf=False) -> np.ndarray:
    """A scalar or an ``(n,)`` array of real numbers, as ``(n,)`` float32 (``allow_inf``: +-inf
    allowed, e.g. tmax; NaN never)."""
    a = _numbers(value, name)
    if a.ndim == 0:
        a = np.broadcast_to(a, (n,))
    elif a.shape != (n,):
        raise UsageError(f"{name} must be a number or have shape ({n},), got {tuple(a.shape)}")
    _fits_float32(a, name, finite=not allow_inf)
    return np.ascontiguousarray(a, np.float32)


def index_rows(value, name: str, count: int, width: int = 3) -> np.ndarray:
    """``(N, width)`` integer indices into ``count`` items, as int64 (negative or too large
    indices, fractions and non-integer dtypes refused)."""
    a = _numbers(value, name)
    if a.ndim != 2 or a.shape[1] != width:
        raise UsageError(f"{name} must have shape (N, {width}), got {tuple(a.shape)}")
    if a.dtype.kind == "f":
        if not (np.isfinite(a).all() and (a == np.round(a)).all()):
            raise UsageError(f"{name} must hold integer indices, got fractions or non-finite values")
    if a.size and (a.min() < 0 or a.max() >= count):
        raise UsageError(f"{name} must index 0 .. {count - 1}, got {a.min():g} .. {a.max():g}")
    return np.ascontiguousarray(a, np.int64)


__all__ = ["describe", "integer", "number", "seed", "choice", "flag", "path_text", "writable_file",
           "writable_files", "output_failure", "float32_rows", "float32_per_row", "index_rows", "UserError"]
