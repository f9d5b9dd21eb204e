"""Rendering a scene: the Python API behind ``pyopencl-rt render``.

    scene = pyopencl_rt.load_scene("scenes/cornell-box.toml")
    image = pyopencl_rt.render(scene, spp=64, device="cpu", seed=1)   # H x W x 3 float32
"""
from __future__ import annotations

import platform
import time
from dataclasses import dataclass

import numpy as np

from .errors import UserError
from .scene import INTEGRATORS, Scene
from .wavefront import Film, RunStats, Wavefront

MAX_PIXELS = 1 << 26  # 8192 x 8192


@dataclass
class RenderResult:
    image: np.ndarray  # H x W x 3 float32, linear radiance
    stats: RunStats
    info: dict  # everything the JSON sidecar records
    film: Film  # sums behind the image (variance_of_mean() gives each pixel's standard error^2)


def check_settings(width, height, spp, max_depth, integrator, time_limit):
    if width is not None and (int(width) < 1 or int(height) < 1 or int(width) * int(height) > MAX_PIXELS):
        raise UserError(f"impossible resolution {width}x{height}: each side must be >= 1 and at most {MAX_PIXELS} pixels in all")
    if spp is not None and int(spp) < 1:
        raise UserError(f"--spp must be at least 1 (got {spp})")
    if time_limit is not None and not (float(time_limit) > 0):
        raise UserError(f"--time-limit must be positive (got {time_limit})")
    if max_depth is not None and int(max_depth) == 0:
        raise UserError("--max-depth 0 renders nothing: use 1 for emitters only, -1 for no limit")
    if integrator is not None and integrator not in INTEGRATORS:
        raise UserError(f"unknown integrator {integrator!r}: use one of {', '.join(INTEGRATORS)}")


def render_full(scene: Scene, *, spp=None, time_limit=None, device=None, seed=None, width=None, height=None,
                max_depth=None, integrator=None, wave_size=None, progress=None, profile=False,
                wavefront: Wavefront | None = None) -> RenderResult:
    """Render and return the image with statistics (see :func:`render`)."""
    from .devices import device_label, select_device

    st = scene.settings
    width = int(width or st.width)
    height = int(height or st.height)
    check_settings(width, height, spp, max_depth, integrator, time_limit)
    if spp is None and time_limit is None:
        spp = st.spp
    dev = select_device(device) if wavefront is None else wavefront.device
    t0 = time.perf_counter()
    wf = wavefront or Wavefront(scene, dev, width=width, height=height, integrator=integrator,
                                max_depth=max_depth, seed=seed, wave_size=wave_size)
    setup = time.perf_counter() - t0
    film = Film(wf.width, wf.height)
    stats = wf.run(film, passes=spp, time_limit=time_limit, progress=progress, profile=profile)
    info = {
        "scene": scene.source,
        "device": device_label(dev),
        "width": wf.width,
        "height": wf.height,
        "spp": film.passes,
        "spp_requested": spp,
        "time_limit": time_limit,
        "max_depth": wf.max_depth,
        "rr_depth": wf.rr_depth,
        "integrator": wf.integrator,
        "seed": wf.seed,
        "wave_size": wf.wave_size,
        "features": sorted(k if v is True else f"{k}={v}" for k, v in wf.features.items()),
        "triangles": int(len(scene.faces)),
        "spheres": int(len(scene.spheres)),
        "lights": wf.n_lights,
        "bvh_seconds": wf.timings.get("bvh_seconds"),
        "kernel_build_seconds": wf.timings.get("build_seconds"),
        "setup_seconds": setup,
        "render_seconds": stats.seconds,
        "samples": stats.samples,
        "samples_per_second": stats.samples / stats.seconds if stats.seconds > 0 else None,
        "rays_extend": stats.rays_extend,
        "rays_shadow": stats.rays_shadow,
        "nonfinite_samples": stats.nonfinite,
        "interrupted": stats.interrupted,
        "host": platform.node(),
    }
    if profile:
        info["stage_seconds"] = dict(stats.stage_seconds)
    return RenderResult(film.image(), stats, info, film)


def render(scene: Scene, spp=None, device=None, seed=None, **kwargs) -> np.ndarray:
    """Render ``scene`` and return an H x W x 3 float32 array of linear radiance.

    Keyword arguments: ``width``, ``height``, ``max_depth``, ``integrator`` ("path", "bsdf",
    "nee"), ``time_limit`` (seconds, instead of or as well as ``spp``), ``wave_size``.
    Settings not given come from the scene file.  The same seed on the same device gives the
    same image, bit for bit.
    """
    return render_full(scene, spp=spp, device=device, seed=seed, **kwargs).image
