"""Checkpoints: a film's sums saved so that a render can be interrupted and resumed.

A checkpoint is one ``.npz`` file: the film (float64 ``sum`` and ``sum_sq``, ``passes``, and
``aov_sum`` when the settings have ``film_aovs``, so that a resumed render keeps its AOVs), the
``key`` it belongs to and a JSON ``meta`` record.  The key is a SHA-256 of the scene's arrays
(geometry with its two-level instances' transforms and groups, materials, camera) and of every
setting that changes the image (width, height, max_depth, rr_depth, integrator, seed), so a
checkpoint of another scene or of other settings is refused.  Settings that do not change the
image (device, wave size, number of devices) are free to change between the interrupted render
and its resumption.

Passes are whole and keyed by (seed, pixel, pass, dimension): a film holding passes [0, n) that
is resumed with ``Wavefront.run(film, first_pass=n)`` adds passes n, n+1, ... to the very same
float64 sums, in the same order as an uninterrupted render, so the result is bit for bit equal on
the same device.

Files are written atomically (a temporary file beside the target, flushed, then renamed): a
process killed while writing leaves the previous checkpoint intact.
"""
from __future__ import annotations

import hashlib
import json
import os
import signal
import threading
import time
from contextlib import contextmanager
from pathlib import Path

import numpy as np

from ..errors import SIGINT_SEEN, UserError
from .film import Film
from .settings import ImageSettings

from .checkpoint_schema import FORMAT, CheckpointError, read_checked  # noqa: F401 (CheckpointError: public)


def scene_hash(scene) -> str:
    """SHA-256 of everything in the scene that the kernels see: every scene-sourced parameter of the
    kernel ABI, as :func:`~pyopencl_rt.render.scene_inputs.scene_inputs` gives it (arrays, not
    file names, and not the device's BVH layout)."""
    from .scene_inputs import scene_inputs

    h = hashlib.sha256()
    for name, a in scene_inputs(scene).items():
        a = np.ascontiguousarray(a)
        h.update(f"{name}:{a.dtype.str}:{a.shape}".encode())
        h.update(a.tobytes())
    return h.hexdigest()


def render_key(scene, settings: ImageSettings) -> str:
    h = hashlib.sha256(scene_hash(scene).encode())
    h.update(json.dumps(settings.as_dict(), sort_keys=True).encode())
    return h.hexdigest()


def default_path(output) -> Path:
    """``out/render.exr`` -> ``out/render.ckpt.npz``."""
    p = Path(output)
    return p.with_name(p.stem + ".ckpt.npz")


def save(path, film: Film, scene, settings: ImageSettings, meta: dict | None = None) -> Path:
    """Write ``film`` as a checkpoint of (scene, settings), atomically."""
    from ..imageio import _atomic_write

    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    record = {
        "format": FORMAT,
        "scene_hash": scene_hash(scene),
        "settings": settings.as_dict(),
        "passes": int(film.passes),
        "scene": getattr(scene, "source", None),
        "time": time.strftime("%Y-%m-%dT%H:%M:%S"),
    }
    record.update(meta or {})
    arrays = {
        "sum": np.asarray(film.sum, np.float64),
        "sum_sq": np.asarray(film.sum_sq, np.float64),
        "passes": np.int64(film.passes),
        "key": np.array(render_key(scene, settings)),
        "meta": np.array(json.dumps(record, default=str)),
    }
    if film.aov_sum is not None:
        arrays["aov_sum"] = np.asarray(film.aov_sum, np.float64)

    def writer(tmp):
        with open(tmp, "wb") as f:  # a file object: np.savez would append ".npz" to a name
            np.savez(f, **arrays)
            f.flush()
            os.fsync(f.fileno())

    _atomic_write(path, writer)
    return path


def read(path) -> tuple[Film, str, dict]:
    """The film, key and metadata stored in a checkpoint (no compatibility check), every field
    checked as untrusted input (:mod:`.checkpoint_schema`)."""
    return read_checked(path)


def load(path, scene, settings: ImageSettings) -> tuple[Film, dict]:
    """The film of a checkpoint made for (scene, settings); CheckpointError (one line) if it is not."""
    film, key, meta = read(path)
    if key == render_key(scene, settings):
        return film, meta
    if meta.get("scene_hash") != scene_hash(scene):
        stored = meta.get("scene") or "another scene"
        raise CheckpointError(f"{path}: checkpoint is for another scene ({stored}, different geometry, materials "
                              f"or camera); delete it or render without --resume")
    theirs = meta.get("settings", {})
    diff = settings.differences(theirs)
    raise CheckpointError(f"{path}: checkpoint was made with other settings ({diff or 'unknown'}); "
                          f"use the same settings to resume")


class Checkpointer:
    """Periodic checkpoints: ``maybe(film)`` saves when ``every`` seconds have passed since the last."""

    def __init__(self, path, scene, settings, every=None, meta=None):
        self.path, self.scene, self.settings, self.every, self.meta = path, scene, settings, every, meta or {}
        self.last = time.monotonic()
        self.saved = 0

    def due(self) -> bool:
        return self.path is not None and self.every is not None and time.monotonic() - self.last >= self.every

    def save(self, film: Film) -> Path | None:
        if self.path is None:
            return None
        try:
            p = save(self.path, film, self.scene, self.settings, self.meta)
        except OSError as exc:  # a full disk must not end the render that the checkpoint is for
            import warnings

            warnings.warn(f"{self.path}: cannot write the checkpoint ({exc.strerror or exc}); rendering on",
                          RuntimeWarning, stacklevel=2)
            self.last = time.monotonic()
            return None
        self.last = time.monotonic()
        self.saved += 1
        return p

    def maybe(self, film: Film) -> None:
        if self.due():
            self.save(film)


@contextmanager
def stop_on_signals(enabled: bool = True):
    """While rendering: SIGINT and SIGTERM set the yielded Event (renders stop at their next safe
    point: whole passes stay, the passes in flight are dropped); a second signal raises
    KeyboardInterrupt at once.  The previous handlers are restored afterwards.  Only in the main
    thread (elsewhere the Event is returned and no handler is installed)."""
    stop = threading.Event()
    if not enabled or threading.current_thread() is not threading.main_thread():
        yield stop
        return

    def handler(signum, frame):
        if stop.is_set():
            raise KeyboardInterrupt
        stop.set()

    saved = {}
    for sig in (signal.SIGINT, signal.SIGTERM):
        saved[sig] = signal.signal(sig, handler)
    if SIGINT_SEEN.is_set():  # a Ctrl-C during start-up whose KeyboardInterrupt was swallowed
        stop.set()
    try:
        yield stop
    finally:
        for sig, old in saved.items():
            signal.signal(sig, old)
