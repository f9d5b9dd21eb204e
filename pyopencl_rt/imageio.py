"""Writing images: linear OpenEXR, sRGB PNG from the same buffer, and a JSON sidecar."""
from __future__ import annotations

import json
import os
from pathlib import Path

import numpy as np

from .errors import UserError


def linear_to_srgb(x: np.ndarray) -> np.ndarray:
    """The sRGB transfer function (IEC 61966-2-1) on values clamped to [0, 1]."""
    x = np.clip(np.nan_to_num(x, nan=0.0, posinf=1.0, neginf=0.0), 0.0, 1.0)
    return np.where(x <= 0.0031308, 12.92 * x, 1.055 * np.power(x, 1 / 2.4) - 0.055)


def _atomic_write(path: Path, writer) -> None:
    """Write to a temporary file beside ``path``, then rename: a reader never sees half a file."""
    tmp = path.with_name(f".{path.name}.tmp{os.getpid()}")
    try:
        writer(tmp)
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()


def write_exr(path, image: np.ndarray) -> None:
    import OpenEXR

    img = np.ascontiguousarray(image, dtype=np.float32)
    header = {"compression": OpenEXR.ZIP_COMPRESSION, "type": OpenEXR.scanlineimage}

    def writer(tmp):
        with OpenEXR.File(header, {"RGB": img}) as f:
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


def write_png(path, image: np.ndarray, exposure: float = 0.0) -> None:
    from PIL import Image

    rgb = linear_to_srgb(np.asarray(image, np.float64) * (2.0**exposure))
    data = (rgb * 255.0 + 0.5).astype(np.uint8)
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


def write_outputs(exr_path, image: np.ndarray, sidecar: dict) -> dict:
    """``out.exr`` plus ``out.png`` and ``out.json`` beside it; returns the paths written."""
    exr_path = Path(exr_path)
    if exr_path.suffix.lower() != ".exr":
        raise UserError(f"{exr_path}: the output must be an .exr file (a .png and a .json are written beside it)")
    if not exr_path.parent.exists():
        exr_path.parent.mkdir(parents=True, exist_ok=True)
    png, js = exr_path.with_suffix(".png"), exr_path.with_suffix(".json")
    write_exr(exr_path, image)
    write_png(png, image)
    write_json(js, sidecar)
    return {"exr": str(exr_path), "png": str(png), "json": str(js)}
