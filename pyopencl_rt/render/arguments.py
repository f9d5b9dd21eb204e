"""Every argument of a render checked in one place, before a scene is loaded or a kernel built.

:func:`check_render_arguments` is what :func:`~pyopencl_rt.render.api.render_full` runs first and
what ``pyopencl-rt render`` runs on its options before it reads the scene; :func:`check_outputs`
checks the files a render will write.  Messages are one line and name the option as the CLI
spells it, so the command line and the Python API say the same thing (docs/ROBUSTNESS.md).
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass

from .. import validate
from ..device import abi
from ..errors import UsageError, UserError
from ..scene.model import INTEGRATORS
from .intersectors import INTERSECTORS, Intersector
from .multidevice import DEVICE_TIMEOUT
from .wavefront import MAX_WAVE_SIZE, check_wave_memory

MAX_LOCAL_WORKERS = 64  # --scheduler local:N


@dataclass
class RenderArguments:
    """The checked, converted arguments (None: not given)."""
    spp: int | None
    time_limit: float | None
    wave_size: int | None
    intersector: object
    devices: list | None  # pyopencl devices of a local render (None for a Dask render)
    checkpoint_every: float | None
    device_timeout: float


def check_render_arguments(*, spp=None, time_limit=None, width=None, height=None, max_depth=None, rr_depth=None,
                           integrator=None, seed=None, wave_size=None, intersector="opencl", kernel_mode=None,
                           device=None, scheduler=None, checkpoint=None, resume=False, checkpoint_every=None,
                           device_timeout=None, handle_signals=False, profile=False,
                           progress=None, adaptive=None, target_error=None) -> RenderArguments:
    """Types, ranges and combinations of a render's arguments; a UserError (one line) otherwise.
    Local devices are resolved (listing them builds nothing) so that an unknown one is refused
    here; a Dask render's device spec is resolved by each worker."""
    if spp is not None:
        spp = validate.integer(spp, "--spp", minimum=1, maximum=abi.MAX_PASSES)  # the kernels' int pass index
    if time_limit is not None:
        time_limit = validate.number(time_limit, "--time-limit", positive=True)
    if width is not None:
        validate.integer(width, "--width", minimum=1)
    if height is not None:
        validate.integer(height, "--height", minimum=1)
    if max_depth is not None:
        validate.integer(max_depth, "--max-depth", minimum=-1)
    if rr_depth is not None:
        validate.integer(rr_depth, "--rr-depth", minimum=0)
    if integrator is not None:
        validate.choice(integrator, "integrator", INTEGRATORS)
    if seed is not None:
        validate.seed(seed)
    if wave_size is not None:
        wave_size = validate.integer(wave_size, "--wave-size", minimum=1, maximum=MAX_WAVE_SIZE)
    if not isinstance(intersector, Intersector):
        validate.choice(intersector, "intersector", INTERSECTORS)
    if kernel_mode is not None:
        from .megakernel import KERNEL_MODES

        validate.choice(kernel_mode, "kernel mode", ("auto",) + KERNEL_MODES)
    for name, value in (("profile", profile), ("resume", resume), ("handle_signals", handle_signals)):
        validate.flag(value, name if name != "resume" else "--resume")
    if progress is not None and not callable(progress):
        raise UsageError(f"progress must be a callable (passes, seconds), got {validate.describe(progress)}")
    if checkpoint is not None:
        validate.writable_file(checkpoint, "checkpoint")  # written at the end, on Ctrl-C, periodically
    if resume and checkpoint is None:
        raise UsageError("--resume needs a checkpoint file (--checkpoint)")
    if checkpoint_every is not None:
        checkpoint_every = validate.number(checkpoint_every, "--checkpoint-every", positive=True)
        if checkpoint is None:
            raise UsageError("--checkpoint-every needs a checkpoint file (--checkpoint)")
    device_timeout = DEVICE_TIMEOUT if device_timeout is None else validate.number(
        device_timeout, "--device-timeout", positive=True)
    _check_device_spec(device)
    devices = None
    if scheduler is not None:
        check_scheduler(scheduler)
    else:
        from ..device.devices import resolve

        devices = resolve(device)
    shared = scheduler is not None or len(devices) > 1
    if shared and isinstance(intersector, Intersector) and intersector.name not in INTERSECTORS:
        raise UsageError(f"intersector {intersector.name!r}: several devices or a cluster need an intersector "
                         f"given by name ({', '.join(INTERSECTORS)}), one per device")
    if adaptive is not None:
        validate.flag(adaptive, "--adaptive")
    if target_error is not None:
        from .settings import check_target_error

        check_target_error(target_error)
        if adaptive is False:
            raise UsageError("--target-error needs --adaptive")
    check_adaptive(adaptive, devices=devices, scheduler=scheduler, resume=resume, checkpoint_every=checkpoint_every)
    if shared and isinstance(intersector, Intersector):
        intersector = intersector.name  # one instance per device (an instance holds one wavefront's state)
    if devices is not None and wave_size is not None:
        for d in devices:
            check_wave_memory(d, wave_size)
    return RenderArguments(spp, time_limit, wave_size, intersector, devices, checkpoint_every, device_timeout)


def check_adaptive(adaptive, *, devices=None, scheduler=None, resume=False, checkpoint_every=None) -> None:
    """Adaptive sampling (``adaptive``: the option, or ``ImageSettings.adaptive``) renders on one
    device of this process, from the start: one line for what it cannot be combined with."""
    if not adaptive:
        return
    if scheduler is not None:
        raise UsageError("--adaptive renders on one device: it cannot be combined with --scheduler (Dask)")
    if devices is not None and len(devices) > 1:
        raise UsageError(f"--adaptive renders on one device, not {len(devices)}: choose one with --device")
    if resume or checkpoint_every is not None:
        raise UsageError("--adaptive cannot be combined with --resume or --checkpoint-every: a checkpoint does not "
                         "hold the per-pixel sample counts")


def _check_device_spec(device) -> None:
    import pyopencl as cl

    ok = (str, cl.Device)
    if device is None or isinstance(device, ok):
        return
    if isinstance(device, (list, tuple)) and all(isinstance(d, ok) for d in device):
        return
    raise UsageError(f"--device must be a spec such as 'cpu', 'gpu', 'all' or '0:1', a pyopencl.Device, or a list "
                     f"of them; got {validate.describe(device)}")


_ADDRESS = re.compile(r"^(tcp|tls|ucx|inproc|ws|wss)://[^\s/]+$")


def check_scheduler(scheduler) -> None:
    """'local', 'local:N' (1 <= N <= 64), a 'tcp://host:port' address or a dask Client."""
    if not isinstance(scheduler, str):
        if type(scheduler).__name__ == "Client":
            return
        raise UsageError(f"--scheduler must be an address (tcp://host:8786), 'local[:N]' or a dask Client, "
                         f"got {validate.describe(scheduler)}")
    text = scheduler.strip()
    if text == "local":
        return
    if text.startswith("local:"):
        n = text.split(":", 1)[1]
        if not n.isdigit() or not 1 <= int(n) <= MAX_LOCAL_WORKERS:
            raise UsageError(f"--scheduler {text}: the number of local workers must be 1 .. {MAX_LOCAL_WORKERS}")
        return
    if not _ADDRESS.match(text):
        raise UsageError(f"--scheduler {text!r}: expected tcp://host:port (a Dask scheduler) or local[:N]")
    from .distributed import _probe

    _probe(text)  # nothing listening there: one line now, not after the scene is loaded


def check_outputs(output, checkpoint=None, exr=True) -> dict:
    """The image, its PNG and JSON beside it, and the checkpoint: writable files, all different
    (:func:`pyopencl_rt.imageio.output_paths`); a UserError before anything is rendered."""
    from ..imageio import output_paths

    named = {f"output {kind.upper()}" if kind != "json" else "JSON sidecar": path
             for kind, path in output_paths(validate.path_text(output, "--output"), exr).items()}
    if checkpoint is not None:
        named["checkpoint"] = checkpoint
    return validate.writable_files(named)


def rescue_path(checkpoint, output) -> str:
    """Where a film goes when its outputs cannot be written: the checkpoint's name if that can
    be written, else the same name in the current folder, else in the temporary folder."""
    import tempfile
    from pathlib import Path

    from .checkpoint import default_path

    name = Path(checkpoint) if checkpoint is not None else default_path(output)
    for candidate in (name, Path.cwd() / name.name, Path(tempfile.gettempdir()) / name.name):
        try:
            return str(validate.writable_file(candidate, "checkpoint"))
        except UserError:
            continue
    return str(Path(tempfile.gettempdir()) / f"pyopencl-rt-{os.getpid()}.ckpt.npz")


def rescued(exc, result, scene, settings, checkpoint_path, output) -> UserError:
    """The outputs could not be written after the render (``exc``, the OutputError): its film goes
    to a checkpoint (the render's own if it can be written, :func:`rescue_path`), and the error
    says where and how to write it out (``pyopencl-rt render`` raises it)."""
    from ..errors import OutputError
    from . import checkpoint as checkpoints

    where = rescue_path(checkpoint_path, output)
    try:
        checkpoints.save(where, result.film, scene, settings)
    except OSError as err:
        return OutputError(f"{exc}; saving the render to {where} failed too ({err.strerror or err}): it is lost")
    return OutputError(f"{exc}; the render ({result.film.passes} spp) is saved in {where}: write it out with "
                       f"--resume --checkpoint {where} -o ANOTHER.exr (same scene and options)")


def parse_defines(pairs) -> dict | None:
    """{name: value} of ``pyopencl-rt render``'s --define NAME=VALUE options (None without any)."""
    out = {}
    for pair in pairs:
        name, sep, value = pair.partition("=")
        if not sep or not name.strip():
            raise UserError(f"--define {pair}: expected NAME=VALUE")
        out[name.strip()] = value
    return out or None
