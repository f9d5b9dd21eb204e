"""Writing images: linear OpenEXR, sRGB PNG from the same buffer, and a JSON sidecar (all or none of
them, :func:`write_all`)."""
from __future__ import annotations

import contextlib
import json
import os
from pathlib import Path

import numpy as np

from .display import to_8bit
from .errors import UserError


def _atomic_write(path: Path, writer) -> None:
    """Write to a temporary file beside ``path``, then rename: a reader never sees half a file."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        writer(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_exr(path, image: np.ndarray, layers: dict | None = None) -> None:
    """The beauty as R, G, B; ``layers``: more channels, {"albedo.R": H x W array, ...}."""
    import OpenEXR

    img = np.ascontiguousarray(image, dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}
    channels = {"RGB": img, **{k: np.ascontiguousarray(v, np.float32) for k, v in (layers or {}).items()}}

    def writer(tmp):
        with OpenEXR.File(header, channels) as f:
            f.write(str(tmp))

    _atomic_write(Path(path), writer)


def read_exr(path) -> np.ndarray:
    import OpenEXR

    if not Path(path).is_file():
        raise UserError(f"{path}: no such file")
    try:
        with OpenEXR.File(str(path)) as f:
            ch = f.channels()
            if "RGB" in ch:
                return np.asarray(ch["RGB"].pixels, dtype=np.float32)
            return np.stack([np.asarray(ch[c].pixels, dtype=np.float32) for c in "RGB"], -1)
    except UserError:
        raise
    except Exception as exc:
        raise UserError(f"{path}: cannot read OpenEXR ({exc})") from None


def read_exr_channels(path) -> dict[str, np.ndarray]:
    """Every channel of an OpenEXR file by its full name ("R", "albedo.R", ...), H x W float32."""
    import OpenEXR

    if not Path(path).is_file():
        raise UserError(f"{path}: no such file")
    try:
        with OpenEXR.File(str(path), separate_channels=True) as f:
            return {name: np.asarray(c.pixels, dtype=np.float32) for name, c in f.channels().items()}
    except Exception as exc:
        raise UserError(f"{path}: cannot read OpenEXR ({exc})") from None


def write_png(path, image: np.ndarray, exposure: float = 0.0, tonemap: str = "clamp") -> None:
    """8-bit sRGB of linear ``image`` through the display transform (pyopencl_rt/display.py)."""
    from PIL import Image


    data = to_8bit(image, exposure, tonemap)
    _atomic_write(Path(path), lambda tmp: Image.fromarray(data, "RGB").save(tmp, format="PNG"))


def write_json(path, data: dict) -> None:
    text = json.dumps(data, indent=2, default=_json_default)
    _atomic_write(Path(path), lambda tmp: Path(tmp).write_text(text + "\n"))


def _json_default(o):
    if isinstance(o, np.generic):
        return o.item()
    if isinstance(o, np.ndarray):
        return o.tolist()
    raise TypeError(type(o).__name__)


OUTPUT_SUFFIXES = (".exr", ".png")


def check_output(path, exr: bool = True) -> Path:
    """An output path the render can write: .exr, or .png (with the EXR beside it unless not ``exr``)."""
    path = Path(path)
    suffix = path.suffix.lower()
    if suffix not in OUTPUT_SUFFIXES:
        raise UserError(f"{path}: the output must be an .exr or a .png file (the other and a .json are written "
                        "beside it)")
    if not exr and suffix == ".exr":
        raise UserError(f"{path}: --no-exr needs a .png output")
    return path


def write_outputs(exr_path, image: np.ndarray, sidecar: dict, *, layers: dict | None = None, exposure: float = 0.0,
                  tonemap: str = "clamp", exr: bool = True) -> dict:
    """``out.exr`` (or ``out.png``) plus the other and ``out.json`` beside it (no EXR when not
    ``exr``); ``layers``: more EXR channels (write_exr); the PNG goes through the display transform
    (``exposure``, ``tonemap``: pyopencl_rt/display.py).  Returns the paths written."""
    paths = output_paths(exr_path, exr)
    writers = {"exr": lambda tmp: write_exr(tmp, image, layers),
               "png": lambda tmp: write_png(tmp, image, exposure, tonemap),
               "json": lambda tmp: write_json(tmp, sidecar)}
    write_all({Path(path): writers[kind] for kind, path in paths.items()})
    return paths


def output_paths(path, exr: bool = True) -> dict:
    """{"exr", "png", "json"} (no "exr" when not ``exr``): the files a render to ``path`` writes."""
    path = check_output(path, exr)
    is_exr = path.suffix.lower() == ".exr"
    paths = {"exr": str(path if is_exr else path.with_suffix(".exr"))} if exr else {}
    return {**paths, "png": str(path.with_suffix(".png") if is_exr else path), "json": str(path.with_suffix(".json"))}


def write_all(writers: dict) -> None:
    """Write every ``{path: writer(tmp)}`` or none: each is written to a temporary file beside
    it first, and only when all are written are they renamed into place (the files they replace
    are kept aside until then and put back if a rename fails).  An OutputError (one line) says
    which file could not be written; the files that were there before are left as they were."""
    from .validate import output_failure

    staged, backups, placed = {}, {}, []
    current = None
    try:
        for path, writer in writers.items():
            current = path
            if path.is_dir():
                raise IsADirectoryError(21, "it is a folder")
            path.parent.mkdir(parents=True, exist_ok=True)
            staged[path] = path.with_name(f".{path.name}.new{os.getpid()}")
            writer(staged[path])
        for path in writers:
            current = path
            if path.exists():
                backups[path] = path.with_name(f".{path.name}.old{os.getpid()}")
                os.replace(path, backups[path])
        for path, tmp in staged.items():
            current = path
            os.replace(tmp, path)
            placed.append(path)
    except (OSError, RuntimeError) as exc:  # OpenEXR reports I/O errors as RuntimeError
        with contextlib.suppress(OSError):
            for path in placed:
                path.unlink(missing_ok=True)
            for path, old in backups.items():
                os.replace(old, path)
            for tmp in staged.values():
                tmp.unlink(missing_ok=True)
        raise output_failure(current, exc) from None
    for old in backups.values():
        old.unlink(missing_ok=True)
