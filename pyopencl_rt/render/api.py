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
from ..scene.model import Scene
from .film import Film, RunStats
from .settings import ImageSettings, check_run
from .wavefront import Wavefront


@dataclass
class RenderResult:
    image: np.ndarray  # H x W x 3 float32, linear radiance
    stats: RunStats
    info: dict  # everything the JSON sidecar records
    film: Film  # sums behind the image (variance_of_mean() gives each pixel's standard error^2)


def render_full(scene: Scene, *, spp=None, time_limit=None, device=None, seed=None, width=None, height=None,
                max_depth=None, rr_depth=None, integrator=None, wave_size=None, intersector="opencl", progress=None,
                profile=False, wavefront: Wavefront | None = None, scheduler=None, checkpoint=None, resume=False,
                checkpoint_every=None, handle_signals=False, settings: ImageSettings | None = None) -> RenderResult:
    """Render and return the image with statistics (see :func:`render`).

    Several devices (``device="all"``, a list or a comma list) render one image together
    (:mod:`pyopencl_rt.render.multidevice`); ``scheduler`` (a ``tcp://`` address, ``"local"`` or a
    ``dask.distributed.Client``) renders on a Dask cluster (:mod:`pyopencl_rt.render.distributed`).
    ``intersector`` ("opencl" or "embree", :mod:`pyopencl_rt.render.intersectors`) traces the
    extend and shadow rays.  ``wavefront``: a :class:`Wavefront` prepared earlier (benchmarks reuse
    one across renders); its settings are the image's.  ``checkpoint`` is a file
    (:mod:`pyopencl_rt.render.checkpoint`): written when the render is interrupted, every
    ``checkpoint_every`` seconds, and at the end when either option is used; ``resume=True``
    continues from it up to ``spp``.  ``handle_signals`` (the CLI): SIGINT and SIGTERM stop the
    render at a safe point instead of killing it.  ``settings``: an :class:`ImageSettings`
    resolved by the caller, instead of width, height, max_depth, rr_depth, integrator and seed.
    """
    from . import checkpoint as checkpoints

    check_run(spp, time_limit)
    overrides = dict(width=width, height=height, max_depth=max_depth, rr_depth=rr_depth, integrator=integrator,
                     seed=seed)
    given = {k: v for k, v in overrides.items() if v is not None}
    if wavefront is not None or settings is not None:  # settings made earlier; arguments may only repeat them
        if wavefront is not None and settings is not None and settings != wavefront.settings:
            raise UserError("the prepared wavefront was made with other settings "
                            f"({settings.differences(wavefront.settings.as_dict())})")
        settings = settings or wavefront.settings
        other = {k: v for k, v in given.items() if v != getattr(settings, k)}
        if other:
            raise UserError(f"the prepared settings differ from the arguments ({settings.differences(other)})")
    else:
        settings = ImageSettings.resolve(scene, **given)
    if spp is None and time_limit is None:
        spp = scene.settings.spp
    if resume and checkpoint is None:
        raise UserError("resume needs a checkpoint file")
    film = checkpoints.load(checkpoint, scene, settings)[0] if resume else Film(settings.width, settings.height)
    resumed = film.passes
    todo = None if spp is None else max(0, int(spp) - film.passes)
    saver = checkpoints.Checkpointer(checkpoint, scene, settings, checkpoint_every)
    if progress is not None and hasattr(progress, "base"):
        progress.base = film.passes  # passes before a resume: the bar shows the total
    job = _Job(scene, settings, film, todo, time_limit, device, wave_size, intersector, progress, profile, saver)
    with checkpoints.stop_on_signals(handle_signals) as stop:
        job.cancel = stop.is_set
        if wavefront is not None:
            run = _render_prepared(job, wavefront)
        elif scheduler is not None:
            run = _render_dask(job, scheduler)
        else:
            run = _render_local(job)
    extra = dict(run.extra)
    if checkpoint is not None and (run.stats.interrupted or checkpoint_every is not None or resume):
        saver.save(film)
        extra["checkpoint"] = str(checkpoint)
    if resume:
        extra["resumed_from_spp"] = resumed
    info = sidecar(scene, settings, film, run, spp=spp, time_limit=time_limit, intersector=intersector,
                   profile=profile)
    info.update(extra)
    return RenderResult(film.image(), run.stats, info, film)


@dataclass
class _Job:
    """What every way of rendering (one device, several, Dask) is given."""
    scene: Scene
    settings: ImageSettings
    film: Film
    passes: int | None
    time_limit: float | None
    device: object
    wave_size: int | None
    intersector: object
    progress: object
    profile: bool
    saver: object
    cancel: object = None


@dataclass
class _Run:
    """What a way of rendering reports: its statistics, the device(s) it ran on, and one
    :meth:`Wavefront.description` of the engines that rendered."""
    stats: RunStats
    label: str
    engine: dict
    setup_seconds: float
    extra: dict


def _render_prepared(job: _Job, wf: Wavefront) -> _Run:
    from ..device.devices import device_label

    def tick(passes, elapsed):
        job.saver.maybe(job.film)
        if job.progress is not None:
            job.progress(passes, elapsed)

    stats = wf.run(job.film, passes=job.passes, time_limit=job.time_limit, progress=tick, profile=job.profile,
                   first_pass=job.film.passes, cancel=job.cancel)
    return _Run(stats, device_label(wf.device), wf.description(), 0.0, {})


def _render_local(job: _Job) -> _Run:
    """One device (a Wavefront) or several (MultiDevice) of this process."""
    from ..device.devices import resolve

    t0 = time.perf_counter()
    devices = resolve(job.device)
    if len(devices) == 1:
        wf = Wavefront(job.scene, devices[0], job.settings, wave_size=job.wave_size, intersector=job.intersector)
        run = _render_prepared(job, wf)
        run.setup_seconds = time.perf_counter() - t0 - run.stats.seconds
        return run
    from .multidevice import MultiDevice

    md = MultiDevice(job.scene, devices, settings=job.settings, wave_size=job.wave_size, intersector=job.intersector)
    md.prepare()
    setup = time.perf_counter() - t0
    stats = md.run(job.film, passes=job.passes, time_limit=job.time_limit, progress=job.progress, profile=job.profile,
                   cancel=job.cancel, on_tick=lambda pool: job.saver.due() and job.saver.save(pool.snapshot()))
    label = "; ".join(r["device"] for r in stats.devices if r["failed"] is None or r["passes"])
    return _Run(stats, label, md.wavefronts[0].description(), setup, {"devices": stats.devices})


def _render_dask(job: _Job, scheduler) -> _Run:
    from . import distributed
    from .checkpoint import render_key

    t0 = time.perf_counter()
    stats, workers = distributed.run(
        job.scene, scheduler, job.film, settings=job.settings, key=render_key(job.scene, job.settings),
        passes=job.passes, time_limit=job.time_limit, device=job.device, wave_size=job.wave_size,
        intersector=job.intersector, progress=job.progress, profile=job.profile, cancel=job.cancel,
        on_tick=job.saver.maybe)
    address = scheduler if isinstance(scheduler, str) else getattr(getattr(scheduler, "scheduler", None), "address", None)
    engine = next(iter(workers.values()), {})
    setup = engine.get("setup_seconds", time.perf_counter() - t0 - stats.seconds)
    return _Run(stats, f"dask {address}: {len(workers)} workers", engine, setup,
                {"devices": stats.devices, "workers": workers})


def sidecar(scene: Scene, settings: ImageSettings, film: Film, run: _Run, *, spp, time_limit, intersector,
            profile) -> dict:
    """Everything the JSON sidecar records of a render, built once from what each part knows."""
    stats, engine = run.stats, run.engine
    info = {
        "scene": scene.source,
        "scene_format": getattr(scene, "format", None),
        "scene_warnings": list(getattr(scene, "warnings", None) or []),
        "device": run.label,
        **settings.as_dict(),
        "spp": film.passes,
        "spp_requested": spp,
        "time_limit": time_limit,
        "intersector": getattr(intersector, "name", intersector),
        "wave_size": engine.get("wave_size"),
        "features": engine.get("features"),
        "triangles": int(len(scene.faces)),
        "spheres": int(len(scene.spheres)),
        "lights": engine.get("lights"),
        "bvh_seconds": engine.get("bvh_seconds"),
        "kernel_build_seconds": engine.get("kernel_build_seconds"),
        "setup_seconds": run.setup_seconds,
        "render_seconds": stats.seconds,
        "samples": stats.samples,
        "samples_per_second": stats.samples / stats.seconds if stats.seconds > 0 else None,
        "rays_extend": stats.rays_extend,
        "rays_shadow": stats.rays_shadow,
        "nonfinite_samples": stats.nonfinite,
        "interrupted": stats.interrupted,
        "host": platform.node(),
    }
    if profile:  # device stages from their events, host stages (Embree) from the host clock
        info["stage_seconds"] = dict(stats.stage_seconds)
    return info


def render(scene: Scene, spp=None, device=None, seed=None, **kwargs) -> np.ndarray:
    """Render ``scene`` and return an H x W x 3 float32 array of linear radiance.

    Keyword arguments: ``width``, ``height``, ``max_depth``, ``rr_depth``, ``integrator`` ("path",
    "bsdf", "nee"), ``time_limit`` (seconds, instead of or as well as ``spp``), ``wave_size``,
    ``intersector``.  Settings not given come from the scene file.  The same seed on the same
    device gives the same image, bit for bit.
    """
    return render_full(scene, spp=spp, device=device, seed=seed, **kwargs).image
