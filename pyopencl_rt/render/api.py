"""Rendering a scene: the Python API behind ``pyopencl-rt render``.

    scene = pyopencl_rt.load_scene("scenes/cornell-box.toml")
    image = pyopencl_rt.render(scene, spp=64, device="cpu", seed=1)   # H x W x 3 float32
"""
from __future__ import annotations

import platform
import time
from dataclasses import dataclass

import numpy as np

from ..errors import UserError
from ..scene.model import INTEGRATORS, Scene
from .film import Film, RunStats
from .wavefront import Wavefront

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
                wavefront: Wavefront | None = None, scheduler=None, checkpoint=None, resume=False,
                checkpoint_every=None, handle_signals=False) -> RenderResult:
    """Render and return the image with statistics (see :func:`render`).

    Several devices (``device="all"``, a list or a comma list) render one image together
    (:mod:`pyopencl_rt.multidevice`); ``scheduler`` (a ``tcp://`` address, ``"local"`` or a
    ``dask.distributed.Client``) renders on a Dask cluster (:mod:`pyopencl_rt.distributed`).
    ``checkpoint`` is a file (:mod:`pyopencl_rt.checkpoint`): written when the render is
    interrupted, every ``checkpoint_every`` seconds, and at the end when either option is used;
    ``resume=True`` continues from it up to ``spp``.  ``handle_signals`` (the CLI): SIGINT and
    SIGTERM stop the render at a safe point instead of killing it.
    """
    from ..device.devices import device_label, select_device

    st = scene.settings
    if wavefront is not None:  # a prepared wavefront fixes the image's settings
        width, height = width or wavefront.width, height or wavefront.height
        integrator = integrator or wavefront.integrator
        max_depth = wavefront.max_depth if max_depth is None else max_depth
        seed = wavefront.seed if seed is None else seed
    width = int(width or st.width)
    height = int(height or st.height)
    check_settings(width, height, spp, max_depth, integrator, time_limit)
    if spp is None and time_limit is None:
        spp = st.spp
    from . import checkpoint as ckp

    settings = ckp.image_settings(scene, width=width, height=height, max_depth=max_depth, integrator=integrator,
                                  seed=seed)
    if resume and checkpoint is None:
        raise UserError("resume needs a checkpoint file")
    film = ckp.load(checkpoint, scene, settings)[0] if resume else Film(width, height)
    resumed = film.passes
    todo = None if spp is None else max(0, int(spp) - film.passes)
    saver = ckp.Checkpointer(checkpoint, scene, settings, checkpoint_every)
    if progress is not None and hasattr(progress, "base"):
        progress.base = film.passes  # passes before a resume: the bar shows the total
    with ckp.stop_on_signals(handle_signals) as stop:
        t0 = time.perf_counter()
        par = _render_parallel(scene, film, settings, todo, time_limit, device, wave_size, progress, profile,
                               scheduler, saver, stop) if wavefront is None else None
        if par is not None:
            wf, stats, label, extra = par
            setup = wf.timings.get("setup_seconds", time.perf_counter() - t0 - stats.seconds)
        else:
            dev = select_device(device) if wavefront is None else wavefront.device
            wf = wavefront or Wavefront(scene, dev, width=width, height=height, integrator=integrator,
                                        max_depth=max_depth, seed=seed, wave_size=wave_size)
            setup = time.perf_counter() - t0
            label, extra = device_label(dev), {}

            def tick(passes, elapsed):
                saver.maybe(film)
                if progress is not None:
                    progress(passes, elapsed)

            stats = wf.run(film, passes=todo, time_limit=time_limit, progress=tick, profile=profile,
                           first_pass=film.passes, cancel=stop.is_set)
    if checkpoint is not None and (stats.interrupted or checkpoint_every is not None or resume):
        saver.save(film)
        extra["checkpoint"] = str(checkpoint)
    if resume:
        extra["resumed_from_spp"] = resumed
    info = {
        "scene": scene.source,
        "device": label,
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
    info.update(extra)
    if profile:
        info["stage_seconds"] = dict(stats.stage_seconds)
    return RenderResult(film.image(), stats, info, film)


class _Described:
    """What the sidecar records of the Wavefronts that rendered on a Dask cluster."""

    def __init__(self, settings, desc, wave_size):
        self.width, self.height = settings["width"], settings["height"]
        self.max_depth, self.rr_depth = settings["max_depth"], settings["rr_depth"]
        self.integrator, self.seed = settings["integrator"], settings["seed"]
        first = next(iter(desc.get("workers", {}).values()), {})
        self.wave_size = first.get("wave_size", wave_size)
        self.features = {f: True for f in first.get("features", [])}
        self.n_lights = first.get("lights")
        self.timings = {"bvh_seconds": first.get("bvh_seconds"), "build_seconds": first.get("kernel_build_seconds"),
                        "setup_seconds": first.get("setup_seconds")}


def _render_parallel(scene, film, settings, todo, time_limit, device, wave_size, progress, profile, scheduler,
                     saver, stop):
    """Several devices or a Dask cluster; None when the render is for one local device."""
    from ..device.devices import resolve

    if scheduler is not None:
        from . import distributed
        from .checkpoint import render_key

        stats, desc = distributed.run(
            scene, scheduler, film, settings=settings, key=render_key(scene, settings), passes=todo,
            time_limit=time_limit, device=device, wave_size=wave_size, progress=progress, profile=profile,
            cancel=stop.is_set, on_tick=lambda f: saver.maybe(f))
        address = scheduler if isinstance(scheduler, str) else getattr(scheduler, "scheduler", None) and \
            scheduler.scheduler.address
        label = f"dask {address}: {len(desc.get('workers', {}))} workers"
        return _Described(settings, desc, wave_size), stats, label, {"devices": stats.devices,
                                                                    "workers": desc.get("workers", {})}
    devs = resolve(device)
    if len(devs) < 2:
        return None
    from .multidevice import MultiDevice

    s = settings
    t0 = time.perf_counter()
    md = MultiDevice(scene, devs, width=s["width"], height=s["height"], integrator=s["integrator"],
                     max_depth=s["max_depth"], rr_depth=s["rr_depth"], seed=s["seed"], wave_size=wave_size)
    md.prepare()
    setup = time.perf_counter() - t0
    stats = md.run(film, passes=todo, time_limit=time_limit, progress=progress, profile=profile,
                   cancel=stop.is_set, on_tick=lambda pool: saver.due() and saver.save(pool.snapshot()))
    wf = md.wavefronts[0]
    wf.timings["setup_seconds"] = setup
    label = "; ".join(r["device"] for r in stats.devices if r["failed"] is None or r["passes"])
    return wf, stats, label, {"devices": stats.devices}


def render(scene: Scene, spp=None, device=None, seed=None, **kwargs) -> np.ndarray:
    """Render ``scene`` and return an H x W x 3 float32 array of linear radiance.

    Keyword arguments: ``width``, ``height``, ``max_depth``, ``integrator`` ("path", "bsdf",
    "nee"), ``time_limit`` (seconds, instead of or as well as ``spp``), ``wave_size``.
    Settings not given come from the scene file.  The same seed on the same device gives the
    same image, bit for bit.
    """
    return render_full(scene, spp=spp, device=device, seed=seed, **kwargs).image
