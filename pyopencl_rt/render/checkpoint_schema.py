"""Reading a checkpoint as untrusted input: every field of its schema checked before it is used.

A checkpoint (:mod:`pyopencl_rt.render.checkpoint`) is a zip of ``.npy`` arrays.  Whatever a
file holds, :func:`read_checked` either returns a film that a render can continue, or raises
:class:`CheckpointError` with one line saying what is wrong.  It never unpickles (object arrays
are refused), reads each array's header before its data (a shape or dtype that does not match
the schema, or a member larger than the film it should hold, is refused unread), and checks:

=========  ===========================================================================
member     schema (format 1)
=========  ===========================================================================
meta       0-d unicode, a JSON object of at most 1 MiB: ``format`` (an int this version
           reads), ``settings`` (every ImageSettings field, checked as a render checks
           them), ``passes`` (an int equal to the array's), ``scene_hash`` (64 hex digits)
key        0-d unicode, 64 hex digits (SHA-256)
passes     0-d integer, 0 <= passes <= 2^40
sum        float64 (width * height, 3), finite; zero when passes is 0
sum_sq     float64 (width * height, 3), finite, >= 0
aov_sum    float64 (width * height, abi.AOV_FLOATS), finite; present exactly when the
           settings have film_aovs
=========  ===========================================================================
"""
from __future__ import annotations

import json
import re
import zipfile
from pathlib import Path

import numpy as np

from ..device import abi
from ..errors import UserError, one_line

FORMAT = 1  # the layout above; a checkpoint records the format it was written in
READABLE_FORMATS = (1,)
MAX_META_BYTES = 1 << 20
MAX_PASSES = abi.MAX_PASSES  # the kernels number passes with a 32-bit int
_HEX64 = re.compile(r"^[0-9a-f]{64}$")


class CheckpointError(UserError):
    """A checkpoint that is missing, unreadable or belongs to another scene or settings."""


def _bad(path, what) -> CheckpointError:
    return CheckpointError(one_line(f"{path}: not a readable checkpoint: {what}"))


def _member(path, zf, name, *, kinds, ndim, shape=None, required=True, max_bytes=None):
    """The array ``name``.npy of the archive, its header checked before its data is read."""
    entry = f"{name}.npy"
    if entry not in zf.namelist():
        if required:
            raise _bad(path, f"it has no '{name}' array")
        return None
    info = zf.getinfo(entry)
    with zf.open(entry) as f:
        try:
            version = np.lib.format.read_magic(f)
            header = (np.lib.format.read_array_header_1_0 if version == (1, 0)
                      else np.lib.format.read_array_header_2_0)(f)
        except ValueError as exc:
            raise _bad(path, f"'{name}' is not a .npy array ({one_line(exc)})") from None
        arr_shape, _fortran, dtype = header
        if dtype.hasobject or dtype.kind not in kinds:
            raise _bad(path, f"'{name}' has dtype {dtype}")
        if len(arr_shape) != ndim or (shape is not None and tuple(arr_shape) != tuple(shape)):
            raise _bad(path, f"'{name}' has shape {tuple(arr_shape)}"
                             + (f", expected {tuple(shape)}" if shape is not None else ""))
        limit = max_bytes if max_bytes is not None else (
            int(np.prod(arr_shape, dtype=np.int64)) * dtype.itemsize if shape is not None else None)
        if limit is not None and info.file_size > limit + 4096:
            raise _bad(path, f"'{name}' holds {info.file_size} bytes, more than its shape needs")
        f.seek(0)
        try:
            return np.lib.format.read_array(f, allow_pickle=False)
        except (ValueError, OSError, EOFError) as exc:
            raise _bad(path, f"'{name}' is truncated or corrupt ({one_line(exc)})") from None


def _text(path, zf, name, max_bytes):
    a = _member(path, zf, name, kinds="U", ndim=0, max_bytes=max_bytes)
    return str(a[()])


def _settings(path, record):
    from .settings import ImageSettings

    values = record.get("settings")
    if not isinstance(values, dict):
        raise _bad(path, "its metadata has no 'settings' table")
    for key, value in values.items():
        if key in ("width", "height", "max_depth", "rr_depth", "seed") and (
                isinstance(value, bool) or not isinstance(value, int)):
            raise _bad(path, f"setting '{key}' is {value!r}, not an integer")
    try:
        settings = ImageSettings.from_dict(values)
        settings.check()
        from ..validate import seed

        seed(settings.seed)
    except KeyError as exc:
        raise _bad(path, f"its settings lack {exc}") from None
    except (TypeError, ValueError) as exc:
        raise _bad(path, f"its settings do not fit ({one_line(exc)})") from None
    except UserError as exc:
        raise _bad(path, f"its settings are impossible ({exc})") from None
    return settings


def read_checked(path):
    """(film, key, meta) of the checkpoint at ``path``, every field checked (module docstring)."""
    from ..device import abi
    from .film import Film

    path = Path(path)
    if not path.is_file():
        raise CheckpointError(f"{path}: no checkpoint to resume from")
    try:
        with open(path, "rb") as f:
            magic = f.read(4)
    except OSError as exc:
        raise CheckpointError(f"{path}: cannot read the checkpoint ({exc.strerror or exc})") from None
    if magic != b"PK\x03\x04":
        raise _bad(path, "it is not an .npz archive")
    try:
        with zipfile.ZipFile(path) as zf:
            unknown = sorted(set(zf.namelist()) - {f"{n}.npy" for n in ("meta", "key", "passes", "sum", "sum_sq",
                                                                         "aov_sum")})
            if unknown:
                raise _bad(path, f"unexpected members {', '.join(unknown)}")
            try:
                record = json.loads(_text(path, zf, "meta", MAX_META_BYTES))
            except json.JSONDecodeError as exc:
                raise _bad(path, f"its metadata is not JSON ({exc.msg})") from None
            if not isinstance(record, dict):
                raise _bad(path, "its metadata is not a JSON object")
            fmt = record.get("format")
            if isinstance(fmt, bool) or not isinstance(fmt, int) or fmt not in READABLE_FORMATS:
                raise _bad(path, f"format {fmt!r}; this version reads format "
                                 f"{', '.join(map(str, READABLE_FORMATS))} (made by another version?)")
            settings = _settings(path, record)
            key = _text(path, zf, "key", 4096)
            if not _HEX64.match(key) or not _HEX64.match(str(record.get("scene_hash", ""))):
                raise _bad(path, "its key or scene hash is not a SHA-256")
            passes = _member(path, zf, "passes", kinds="iu", ndim=0, shape=())
            passes = int(passes[()])
            if not 0 <= passes <= MAX_PASSES:
                raise _bad(path, f"pass count {passes}")
            if record.get("passes", passes) != passes:
                raise _bad(path, f"pass count {passes} but its metadata says {record.get('passes')!r}")
            n = settings.width * settings.height
            s = _member(path, zf, "sum", kinds="f", ndim=2, shape=(n, 3))
            sq = _member(path, zf, "sum_sq", kinds="f", ndim=2, shape=(n, 3))
            aov = _member(path, zf, "aov_sum", kinds="f", ndim=2, shape=(n, abi.AOV_FLOATS),
                          required=bool(getattr(settings, "film_aovs", False)))
            if aov is not None and not getattr(settings, "film_aovs", False):
                raise _bad(path, "it has AOV sums that its settings do not ask for")
    except CheckpointError:
        raise
    except zipfile.BadZipFile as exc:
        raise _bad(path, f"a damaged archive ({one_line(exc)})") from None
    except OSError as exc:
        raise CheckpointError(f"{path}: cannot read the checkpoint ({exc.strerror or exc})") from None
    except Exception as exc:  # zlib, struct, unicode errors of a damaged zip directory: untrusted bytes
        raise _bad(path, f"a damaged archive ({type(exc).__name__}: {one_line(exc)})") from None
    for name, a in (("sum", s), ("sum_sq", sq), ("aov_sum", aov)):
        if a is not None and a.dtype != np.float64:
            raise _bad(path, f"'{name}' has dtype {a.dtype}, expected float64")
        if a is not None and not np.isfinite(a).all():
            raise _bad(path, f"'{name}' has {int((~np.isfinite(a)).sum())} non-finite values")
    if (sq < 0).any():
        raise _bad(path, "'sum_sq' has negative values")
    if passes == 0 and (s.any() or sq.any()):
        raise _bad(path, "0 passes but non-zero sums")
    film = Film(settings.width, settings.height, sum=np.ascontiguousarray(s), sum_sq=np.ascontiguousarray(sq),
                passes=passes, aov_sum=None if aov is None else np.ascontiguousarray(aov))
    return film, key, record
