"""High-dynamic-range images that Mitsuba and pbrt scenes name (environment maps, float
textures): OpenEXR and PFM as linear RGB, 8- and 16-bit images through Pillow (sRGB-decoded)."""
from __future__ import annotations

from pathlib import Path

import numpy as np

from ...errors import UserError
from .builder import error_at


def read_pfm(path: Path) -> np.ndarray:
    """A Portable Float Map ('PF' colour or 'Pf' grey; the scale's sign gives the byte order;
    rows are stored bottom to top) as (H, W, 3) float32, row 0 at the top."""
    data = path.read_bytes()
    tokens, pos = [], 0
    while len(tokens) < 4:  # PF|Pf, width, height, scale; the data follow one whitespace byte
        while pos < len(data) and data[pos:pos + 1].isspace():
            pos += 1
        end = pos
        while end < len(data) and not data[end:end + 1].isspace():
            end += 1
        if end == pos:
            raise ValueError("truncated PFM header")
        tokens.append(data[pos:end].decode("ascii", "replace"))
        pos = end
    rest = data[pos + 1:]
    kind, w, h, scale = tokens[0], int(tokens[1]), int(tokens[2]), float(tokens[3])
    if kind not in ("PF", "Pf"):
        raise ValueError("not a PFM file (no PF/Pf header)")
    channels = 3 if kind == "PF" else 1
    dtype = "<f4" if scale < 0 else ">f4"
    pixels = np.frombuffer(rest[:w * h * channels * 4], dtype).reshape(h, w, channels)[::-1]
    if channels == 1:
        pixels = np.repeat(pixels, 3, axis=2)
    return np.ascontiguousarray(pixels, np.float32)


def read_hdr_image(path, where: str) -> np.ndarray:
    """(H, W, 3) float32 linear RGB, row 0 at the top; errors name ``where``."""
    path = Path(path)
    suffix = path.suffix.lower()
    try:
        if suffix == ".exr":
            from ...imageio import read_exr

            image = read_exr(path)
        elif suffix == ".pfm":
            image = read_pfm(path)
        else:
            from ..textures import texture_from_image

            image = texture_from_image(path, srgb=True).texels[..., :3]
    except UserError as exc:
        raise error_at(where, str(exc)) from None
    except Exception as exc:
        hint = " (use OpenEXR or PFM)" if suffix == ".hdr" else ""
        raise error_at(where, f"cannot read '{path.name}' ({type(exc).__name__}: {exc}){hint}") from None
    image = np.asarray(image, np.float32)
    if image.ndim != 3 or image.shape[2] < 3:
        raise error_at(where, f"'{path.name}' must be an RGB image, got shape {image.shape}")
    return np.ascontiguousarray(image[..., :3])
