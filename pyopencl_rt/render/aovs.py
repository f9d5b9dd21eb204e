"""AOVs: the layers written beside the beauty in the one OpenEXR file.

==========  ==========  ================================================================
layer       channels    what each pixel holds (the mean over its samples, box filter)
==========  ==========  ================================================================
albedo      R, G, B     reflectance of the first hit with a non-delta lobe; mirrors and
                        glass pass on what is seen through them, weighted by their
                        Fresnel and tint (cl/render/aov.h), as Open Image Denoise asks
normal      X, Y, Z     world-space normal of that hit, on the viewer's side (not
                        renormalised: an edge pixel averages its surfaces)
depth       Z           distance from the camera to the first hit, averaged over the
                        samples that hit something; +inf where none did
position    X, Y, Z     world-space first hit, averaged the same way; +inf where none did
variance    R, G, B     variance of the pixel's mean (Film.variance_of_mean: the sample
                        variance over passes / passes; +inf below 2 passes)
spp         Y           samples of the pixel (they vary with adaptive sampling)
==========  ==========  ================================================================

albedo, normal, depth and position are computed by the kernels (built with ``HAS_AOVS`` when
``ImageSettings.film_aovs``), one value per sample written into a per-pass ring beside the
radiance and summed by the film in pass order, so they are as deterministic as the beauty;
variance and spp come from the film alone and cost nothing.
"""
from __future__ import annotations

import numpy as np

from ..device import abi
from ..errors import UserError
from ..scene.model import AOVS

KERNEL_AOVS = ("albedo", "normal", "depth", "position")  # need HAS_AOVS
GUIDES = ("albedo", "normal")  # what the denoiser reads
CHANNELS = {"albedo": "RGB", "normal": "XYZ", "depth": "Z", "position": "XYZ", "variance": "RGB", "spp": "Y"}
assert set(CHANNELS) == set(AOVS) and set(KERNEL_AOVS) <= set(AOVS)


def parse_aovs(names) -> tuple[str, ...]:
    """AOV names (a comma list or an iterable; "all" for every one) in the canonical order, checked."""
    if names is None:
        return ()
    if isinstance(names, str):
        names = names.split(",")
    wanted = set()
    for name in names:
        name = str(name).strip().lower()
        if not name:
            continue
        if name == "all":
            wanted.update(AOVS)
        elif name not in AOVS:
            raise UserError(f"unknown AOV {name!r}: use one or more of {', '.join(AOVS)} (or all)")
        else:
            wanted.add(name)
    return tuple(a for a in AOVS if a in wanted)


def needs_kernel_aovs(names) -> bool:
    return any(a in KERNEL_AOVS for a in names)


def aov_layers(film, names, origin=(0.0, 0.0, 0.0)) -> dict[str, np.ndarray]:
    """{name: H x W x C float32} of the AOVs ``names`` from ``film``; ``origin``: the camera's
    position (the kernels record positions relative to it)."""
    h, w = film.height, film.width
    layers = {}
    n = np.maximum(film.pixel_counts(), 1).astype(np.float64)[:, None]  # per pixel: adaptive sampling
    kernel = [a for a in names if a in KERNEL_AOVS]
    if kernel and film.aov_sum is None:
        raise ValueError(f"the film holds no kernel AOVs (for {', '.join(kernel)}): render with film_aovs")
    s = film.aov_sum
    with np.errstate(divide="ignore", invalid="ignore"):
        for name in names:
            if name == "albedo":
                v = s[:, abi.AOV_ALBEDO:abi.AOV_ALBEDO + 3] / n
            elif name == "normal":
                v = s[:, abi.AOV_NORMAL:abi.AOV_NORMAL + 3] / n
            elif name in ("depth", "position"):
                hits = s[:, abi.AOV_HIT:abi.AOV_HIT + 1]
                if name == "depth":
                    v = s[:, abi.AOV_DEPTH:abi.AOV_DEPTH + 1] / hits
                else:
                    v = s[:, abi.AOV_POSITION:abi.AOV_POSITION + 3] / hits + np.asarray(origin, np.float64)
                v = np.where(hits > 0, v, np.inf)
            elif name == "variance":
                v = film.variance_of_mean().reshape(-1, 3)
            elif name == "spp":
                v = film.pixel_counts().astype(np.float64)[:, None]
            else:
                raise ValueError(f"unknown AOV {name!r}")
            layers[name] = v.astype(np.float32).reshape(h, w, -1)
    return layers


def exr_channels(layers: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """The layers as EXR channels: {"albedo.R": H x W, ...}."""
    out = {}
    for name, image in layers.items():
        for k, c in enumerate(CHANNELS.get(name, "RGB")[: image.shape[-1]]):
            out[f"{name}.{c}"] = np.ascontiguousarray(image[..., k], np.float32)
    return out
