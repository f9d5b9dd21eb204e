"""Rendering a scene: the Python API behind ``pyopencl-rt render``.

    scene = pyopencl_rt.load_scene("scenes/cornell-box.toml")
    image = pyopencl_rt.render(scene, spp=64, device="cpu", seed=1)   # H x W x 3 float32
"""
from __future__ import annotations

import platform
import time
from dataclasses import dataclass, field

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
    # AOV layers (render/aovs.py) by name, H x W x C float32, and "noisy" (the raw beauty) when
    # the image was denoised: the EXR's layers beside R, G, B
    layers: dict = field(default_factory=dict)


def scene_argument(scene) -> Scene:
    """A Scene, or a scene file's path (loaded, as ``pyopencl-rt render`` loads it), checked
    (:func:`pyopencl_rt.scene.validate.check_scene`): values the kernels cannot hold are refused
    before anything is built."""
    import os

    from ..scene.validate import check_scene

    if isinstance(scene, (str, os.PathLike)):
        from ..scene.loaders import load_scene

        scene = load_scene(scene)
    elif not isinstance(scene, Scene):
        from ..errors import UsageError

        raise UsageError(f"scene must be a Scene or a scene file's path, got a {type(scene).__name__}")
    from ..host_stages import host_stage

    with host_stage("validation"):
        check_scene(scene)
    return scene


def render_full(scene: Scene, *, spp=None, time_limit=None, device=None, seed=None, width=None, height=None,
                max_depth=None, rr_depth=None, integrator=None, wave_size=None, intersector="opencl", progress=None,
                profile=False, wavefront: Wavefront | None = None, scheduler=None, checkpoint=None, resume=False,
                checkpoint_every=None, handle_signals=False, kernel_mode=None, device_timeout=None,
                settings: ImageSettings | None = None,
                aovs=None, sampler=None, adaptive=None, target_error=None,
                denoise=False, preview=None, preview_every=None) -> RenderResult:
    """Render and return the image with statistics (see :func:`render`).

    Several devices (``device="all"``, a list or a comma list) render one image together
    (:mod:`pyopencl_rt.render.multidevice`); ``scheduler`` (a ``tcp://`` address, ``"local"`` or a
    ``dask.distributed.Client``) renders on a Dask cluster (:mod:`pyopencl_rt.render.distributed`).
    ``kernel_mode`` ("auto", "wavefront" or "megakernel", :mod:`pyopencl_rt.render.megakernel`):
    how paths are scheduled; the image is the same.
    ``intersector`` ("opencl" or "embree", :mod:`pyopencl_rt.render.intersectors`) traces the
    extend and shadow rays.  ``wavefront``: a :class:`Wavefront` prepared earlier (benchmarks reuse
    one across renders); its settings are the image's.  ``checkpoint`` is a file
    (:mod:`pyopencl_rt.render.checkpoint`): written when the render is interrupted, every
    ``checkpoint_every`` seconds, and at the end when either option is used; ``resume=True``
    continues from it up to ``spp``.  ``handle_signals`` (the CLI): SIGINT and SIGTERM stop the
    render at a safe point instead of killing it.  ``settings``: an :class:`ImageSettings`
    resolved by the caller, instead of width, height, max_depth, rr_depth, integrator, seed and
    sampler ("sobol", "stratified" or "independent": cl/render/sampler.h), adaptive and
    target_error (adaptive sampling, :mod:`pyopencl_rt.render.adaptive`: ``spp`` is then each
    pixel's maximum with a target, the mean without; one device, no resume).
    ``aovs``: AOV layers (names or a comma list, :mod:`pyopencl_rt.render.aovs`; default the
    scene's ``[film] aovs``) returned in ``layers``.  ``denoise``: the image is Open Image
    Denoise's (:mod:`pyopencl_rt.render.denoise`, with the albedo and normal AOVs as guides) and
    ``layers["noisy"]`` the raw one.  ``preview(image)`` is called with the image so far every
    ``preview_every`` seconds.  ``device_timeout``: seconds without progress after which one of
    several devices is dropped as hung (default 120).  ``scene`` may be a scene file's path.
    Every argument is checked first (:mod:`pyopencl_rt.render.arguments`): a bad one is a
    UserError with the CLI's one-line message, before anything is built.
    """
    from . import checkpoint as checkpoints
    from .aovs import GUIDES, KERNEL_AOVS, aov_layers, parse_aovs

    from .arguments import check_render_arguments

    scene = scene_argument(scene)
    args = check_render_arguments(
        spp=spp, time_limit=time_limit, width=width, height=height, max_depth=max_depth, rr_depth=rr_depth,
        integrator=integrator, seed=seed, wave_size=wave_size, intersector=intersector, kernel_mode=kernel_mode,
        device=device, scheduler=scheduler if wavefront is None else None, checkpoint=checkpoint, resume=resume,
        checkpoint_every=checkpoint_every, device_timeout=device_timeout, handle_signals=handle_signals,
        profile=profile, progress=progress, adaptive=adaptive, target_error=target_error)
    spp, time_limit, wave_size, intersector = args.spp, args.time_limit, args.wave_size, args.intersector
    names = parse_aovs(scene.settings.aovs if aovs is None else aovs)
    kernel_aovs = [a for a in names if a in KERNEL_AOVS] + (list(GUIDES) if denoise else [])
    if denoise:
        from .denoise import _pyoidn

        _pyoidn()  # the error saying what to install, before rendering
    if preview_every is not None and not float(preview_every) > 0:
        raise UserError(f"--preview-every must be positive (got {preview_every})")
    overrides = dict(width=width, height=height, max_depth=max_depth, rr_depth=rr_depth, integrator=integrator,
                     seed=seed, sampler=sampler, adaptive=adaptive, target_error=target_error)
    given = {k: v for k, v in overrides.items() if v is not None}
    if wavefront is not None or settings is not None:  # settings made earlier; arguments may only repeat them
        if wavefront is not None and settings is not None and settings != wavefront.settings:
            raise UserError("the prepared wavefront was made with other settings "
                            f"({settings.differences(wavefront.settings.as_dict())})")
        settings = settings or wavefront.settings
        other = {k: v for k, v in given.items() if v != getattr(settings, k)}
        if other:
            raise UserError(f"the prepared settings differ from the arguments ({settings.differences(other)})")
        if kernel_aovs and not settings.film_aovs:
            raise UserError(f"the prepared settings have no AOVs (needed for {', '.join(dict.fromkeys(kernel_aovs))}): "
                            "resolve them with aovs=")
    else:
        settings = ImageSettings.resolve(scene, **given, aovs=kernel_aovs)
    if spp is None and time_limit is None:
        spp = scene.settings.spp
    from .arguments import check_adaptive

    check_adaptive(settings.adaptive, devices=args.devices, scheduler=scheduler if wavefront is None else None,
                   resume=resume, checkpoint_every=checkpoint_every)
    if resume and checkpoint is None:
        raise UserError("resume needs a checkpoint file")
    film = (checkpoints.load(checkpoint, scene, settings)[0] if resume
            else Film.new(settings.width, settings.height, settings.film_aovs))
    resumed = film.passes
    todo = None if spp is None else max(0, int(spp) - film.passes)
    saver = checkpoints.Checkpointer(checkpoint, scene, settings, checkpoint_every)
    if progress is not None and hasattr(progress, "base"):
        progress.base = film.passes  # passes before a resume: the bar shows the total
    periodic = [saver] + ([_Every(lambda f: preview(f.image()), preview_every)] if preview is not None else [])
    job = _Job(scene, settings, film, todo, time_limit, device if args.devices is None else args.devices, wave_size,
               intersector, kernel_mode, progress, profile, periodic, device_timeout=args.device_timeout)
    with checkpoints.stop_on_signals(handle_signals) as stop:
        job.cancel = stop.is_set
        if wavefront is not None:
            run = _render_prepared(job, wavefront)
        elif scheduler is not None:
            run = _render_dask(job, scheduler)
        else:
            run = _render_local(job)
    extra = dict(run.extra)
    if checkpoint is not None and film.passes > 0 and not settings.adaptive and (
            run.stats.interrupted or checkpoint_every is not None or resume):
        if saver.save(film) is not None:
            extra["checkpoint"] = str(checkpoint)
    if resume:
        extra["resumed_from_spp"] = resumed
    info = sidecar(scene, settings, film, run, spp=spp, time_limit=time_limit, intersector=intersector,
                   profile=profile)
    info.update(extra)
    image = color_matrixed(film.image(), getattr(scene.settings, "color_matrix", None))
    layers = aov_layers(film, names, scene.camera.eye) if film.passes else {}
    info["aovs"] = list(names)
    if denoise and film.passes:
        from .denoise import denoise as oidn

        guides = aov_layers(film, GUIDES)
        layers["noisy"] = image
        image, info["denoise"] = oidn(image, guides["albedo"], guides["normal"])
    return RenderResult(image, run.stats, info, film, layers)


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
    kernel_mode: str | None
    progress: object
    profile: bool
    periodic: list  # objects with due() and save(film): the checkpointer, the preview
    cancel: object = None
    device_timeout: float | None = None  # seconds without progress before one of several devices is dropped

    def due(self) -> bool:
        return any(p.due() for p in self.periodic)

    def tick(self, film: Film) -> None:
        """Whatever is due, with ``film`` (the image so far)."""
        for p in self.periodic:
            if p.due():
                p.save(film)


class _Every:
    """``save(film)`` calls ``fn(film)``; ``due()`` once ``seconds`` have passed since the last call."""

    def __init__(self, fn, seconds):
        self.fn, self.every, self.last = fn, seconds, time.monotonic()

    def due(self) -> bool:
        return self.every is not None and time.monotonic() - self.last >= self.every

    def save(self, film: Film) -> None:
        if film.passes:
            self.fn(film)
        self.last = time.monotonic()


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
        job.tick(job.film)
        if job.progress is not None:
            if job.settings.adaptive and hasattr(job.progress, "samples"):  # the CLI's bar: samples, not passes
                job.progress.samples = int(job.film.pixel_counts().sum())
            job.progress(passes, elapsed)

    if job.settings.adaptive:
        from . import adaptive

        stats, record = adaptive.run(wf, job.film, target_error=job.settings.target_error, max_spp=job.passes,
                                     time_limit=job.time_limit, progress=tick, profile=job.profile, cancel=job.cancel)
        return _Run(stats, device_label(wf.device), wf.description(), 0.0, {"adaptive_sampling": record})
    stats = wf.run(job.film, passes=job.passes, time_limit=job.time_limit, progress=tick, profile=job.profile,
                   first_pass=job.film.passes, cancel=job.cancel)
    return _Run(stats, device_label(wf.device), wf.description(), 0.0, {})


def _render_local(job: _Job) -> _Run:
    """One device (a Wavefront) or several (MultiDevice) of this process."""
    from ..device.devices import resolve

    t0 = time.perf_counter()
    devices = resolve(job.device)
    if len(devices) == 1:
        wf = Wavefront(job.scene, devices[0], job.settings, wave_size=job.wave_size, intersector=job.intersector,
                       kernel_mode=job.kernel_mode)
        run = _render_prepared(job, wf)
        run.setup_seconds = time.perf_counter() - t0 - run.stats.seconds
        return run
    from .multidevice import MultiDevice

    md = MultiDevice(job.scene, devices, settings=job.settings, wave_size=job.wave_size, intersector=job.intersector,
                     kernel_mode=job.kernel_mode, device_timeout=job.device_timeout)
    md.prepare()
    setup = time.perf_counter() - t0
    stats = md.run(job.film, passes=job.passes, time_limit=job.time_limit, progress=job.progress, profile=job.profile,
                   cancel=job.cancel, on_tick=lambda pool: job.due() and job.tick(pool.snapshot()))
    label = "; ".join(r["device"] for r in stats.devices if r["failed"] is None or r["passes"])
    return _Run(stats, label, md.wavefronts[0].description(), setup, {"devices": stats.devices})


def _render_dask(job: _Job, scheduler) -> _Run:
    from . import distributed
    from .checkpoint import render_key

    t0 = time.perf_counter()
    stats, workers = distributed.run(
        job.scene, scheduler, job.film, settings=job.settings, key=render_key(job.scene, job.settings),
        passes=job.passes, time_limit=job.time_limit, device=job.device, wave_size=job.wave_size,
        intersector=job.intersector, kernel_mode=job.kernel_mode, progress=job.progress, profile=job.profile, cancel=job.cancel,
        on_tick=job.tick)
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
        "spp": film.passes if film.counts is None else int(film.counts.max()),  # adaptive: the largest
        "spp_requested": spp,
        "time_limit": time_limit,
        "intersector": engine.get("intersector") or getattr(intersector, "name", intersector),  # what ran
        "kernel_mode": engine.get("kernel_mode"),
        "lanes": engine.get("lanes"),  # paths per work-item of the lane megakernel (0: one path)
        "lanes_reason": engine.get("lanes_reason"),  # why that width (pyopencl_rt/device/isa.py)
        "wave_size": engine.get("wave_size"),
        "features": engine.get("features"),
        "triangles": int(len(scene.faces)),
        "shapes": int(len(scene.shapes)),  # the analytic ones (spheres, disks, tubes)
        "lights": engine.get("lights"),
        "light_tree": engine.get("light_tree"),
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
    from ..host_stages import peak_rss, snapshot

    info["host_seconds"] = snapshot()  # load, mesh_read, normals, validation, bvh, ... (host_stages.py)
    info["host_peak_rss_mb"] = peak_rss()  # the process's peak resident memory as each stage ended
    if profile:  # device stages from their events, host stages (Embree) from the host clock
        info["stage_seconds"] = dict(stats.stage_seconds)
    return info


def render(scene: Scene, spp=None, device=None, seed=None, **kwargs) -> np.ndarray:
    """Render ``scene`` and return an H x W x 3 float32 array of linear radiance.

    Keyword arguments: ``width``, ``height``, ``max_depth``, ``rr_depth``, ``integrator`` ("path",
    "bsdf", "nee"), ``time_limit`` (seconds, instead of or as well as ``spp``), ``wave_size``,
    ``intersector``, ``sampler``, ``adaptive`` and ``target_error``.  Settings not given come from
    the scene file.  The same seed on the same device gives the same image, bit for bit.
    """
    return render_full(scene, spp=spp, device=device, seed=seed, **kwargs).image


def color_matrixed(image, matrix):
    """The image with the scene's colour matrix applied to each pixel (rgb -> M . rgb; pbrt-v4's
    white balance: RenderSettings.color_matrix), or itself without one."""
    if matrix is None:
        return image
    m = np.asarray(matrix, np.float64).reshape(3, 3)
    return (np.asarray(image, np.float64) @ m.T).astype(np.float32)
