"""Denoising with Intel Open Image Denoise (OIDN), through the ``pyoidn`` binding: the optional
extra ``pip install '.[denoise]'``.

The "RT" filter runs on the linear HDR beauty with the albedo and normal AOVs as guides.  Guides
rendered at few samples per pixel are noisy themselves (depth of field, glossy and textured
surfaces), so they are prefiltered first, as OIDN's documentation recommends for low sample
counts: each guide goes alone through the RT filter, and the beauty is then filtered with
``cleanAux`` set.  Everything runs on OIDN's CPU device; the result is deterministic for a given
image and thread count.
"""
from __future__ import annotations

import numpy as np

from ..errors import UserError

INSTALL_HINT = "pip install 'pyopencl-rt[denoise]' (or pip install pyoidn==2.5.1.0)"


class DenoiserMissing(UserError):
    """--denoise without the optional extra."""


def _pyoidn():
    try:
        import pyoidn
    except ImportError:
        raise DenoiserMissing(f"--denoise needs Intel Open Image Denoise: {INSTALL_HINT}") from None
    return pyoidn


def available() -> bool:
    try:
        _pyoidn()
    except DenoiserMissing:
        return False
    return True


def _run(pyoidn, device, inputs: dict, output: np.ndarray, **flags) -> None:
    flt = pyoidn.Filter(device, pyoidn.OIDN_FILTER_TYPE_RT)
    try:
        for name, image in inputs.items():
            flt.set_image(name, image, pyoidn.OIDN_FORMAT_FLOAT3)
        flt.set_image(pyoidn.OIDN_IMAGE_OUTPUT, output, pyoidn.OIDN_FORMAT_FLOAT3)
        for name, value in flags.items():
            flt.set_bool(name, value)
        flt.set_quality(pyoidn.OIDN_QUALITY_HIGH)
        flt.commit()
        flt.execute()
        message = device.get_error()
        if message is not None:
            raise RuntimeError(f"Open Image Denoise failed: {message}")
    finally:
        flt.release()


def denoise(color: np.ndarray, albedo: np.ndarray, normal: np.ndarray,
            prefilter: bool = True) -> tuple[np.ndarray, dict]:
    """The denoised beauty (H x W x 3 float32) and what ran (for the sidecar)."""
    pyoidn = _pyoidn()

    def image(a):
        return np.ascontiguousarray(np.nan_to_num(np.asarray(a, np.float32), nan=0.0, posinf=0.0, neginf=0.0))

    color, albedo, normal = image(np.maximum(color, 0.0)), image(albedo), image(normal)
    out = np.empty_like(color)
    with pyoidn.Device(pyoidn.OIDN_DEVICE_TYPE_CPU) as device:
        device.commit()
        if prefilter:
            clean_albedo, clean_normal = np.empty_like(albedo), np.empty_like(normal)
            _run(pyoidn, device, {pyoidn.OIDN_IMAGE_ALBEDO: albedo}, clean_albedo)
            _run(pyoidn, device, {pyoidn.OIDN_IMAGE_NORMAL: normal}, clean_normal)
            albedo, normal = clean_albedo, clean_normal
        _run(pyoidn, device, {pyoidn.OIDN_IMAGE_COLOR: color, pyoidn.OIDN_IMAGE_ALBEDO: albedo,
                              pyoidn.OIDN_IMAGE_NORMAL: normal}, out, hdr=True, cleanAux=prefilter)
    from importlib.metadata import version

    info = {"denoiser": "Intel Open Image Denoise (RT filter, high quality, CPU)", "pyoidn": version("pyoidn"),
            "guides": ["albedo", "normal"], "prefiltered_guides": prefilter}
    return out, info
