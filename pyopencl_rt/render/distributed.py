"""Rendering on a Dask cluster: ``pyopencl-rt render SCENE --scheduler tcp://host:8786``.

The scene is scattered to every worker once.  The client then submits chunks of passes
[first, first + k); a worker renders a chunk on its own devices (all of those its ``--device``
spec selects, with :mod:`pyopencl_rt.multidevice` when there are several), keeping the
Wavefronts built for the scene between chunks, and returns the chunk's film (float64 sums).  The
client adds the chunk films to its film in pass order, so it always holds a prefix of the passes
(as checkpoints need).  Adding chunk sums instead of single passes changes the float64 rounding
of the sums (relative 1e-16), so the image equals the single-process one within float tolerance
(in practice the float32 image is nearly always identical).  Dask retries a chunk whose worker
died; a chunk that still fails is an error.

``--scheduler local`` (or ``local:N``) starts a LocalCluster of N (default 2) single-threaded
worker processes on this machine, for testing.  Dask is optional: ``pip install
'pyopencl-rt[distributed]'``.
"""
from __future__ import annotations

import math
import threading
import time

from ..errors import UserError
from .film import Film, RunStats
from .settings import ImageSettings

INSTALL = "--scheduler needs Dask: pip install 'pyopencl-rt[distributed]' (or pip install 'dask[distributed]')"


def _import():
    try:
        import distributed  # noqa: F401
    except ImportError:
        raise UserError(INSTALL) from None
    return distributed


def connect(scheduler):
    """(client, cluster or None, owned) for a Client, an address, or 'local[:N]'."""
    distributed = _import()
    if isinstance(scheduler, distributed.Client):
        return scheduler, None, False
    text = str(scheduler).strip()
    if text == "local" or text.startswith("local:"):
        n = int(text.split(":", 1)[1]) if ":" in text else 2
        cluster = distributed.LocalCluster(n_workers=n, threads_per_worker=1, processes=True, host="127.0.0.1",
                                           dashboard_address=None, silence_logs=40)
        return distributed.Client(cluster), cluster, True
    _probe(text)
    try:
        return distributed.Client(text, timeout=CONNECT_SECONDS), None, True
    except Exception as exc:
        raise UserError(f"cannot reach the Dask scheduler {text}: {exc}") from None


CONNECT_SECONDS = 10  # the scheduler's handshake, once its port answers
PROBE_SECONDS = 3  # whether anything listens at host:port


def _probe(address: str) -> None:
    """Fail in seconds, not after the client's timeout, when nothing listens at a tcp:// or
    tls:// address (a typo, a scheduler that is not running, a host that does not resolve)."""
    import socket

    scheme, _, rest = address.partition("://")
    host, _, port = rest.rpartition(":")
    if scheme not in ("tcp", "tls") or not port.isdigit():
        return
    try:
        socket.create_connection((host.strip("[]"), int(port)), timeout=PROBE_SECONDS).close()
    except OSError as exc:
        why = exc.strerror or str(exc) or type(exc).__name__
        raise UserError(f"cannot reach the Dask scheduler {address}: {why}") from None


# -- worker side ---------------------------------------------------------------------------------
_WORKER_CACHE: dict = {}
_WORKER_LOCK = threading.Lock()


def _renderer(scene, job):
    """The Wavefront, or MultiDevice, of this worker for this scene and settings (built on the
    first chunk), its description for the sidecar, and a lock."""
    from distributed import get_worker

    from ..device.devices import device_label, resolve

    key = (get_worker().address, job["key"], repr(job["device"]), job["wave_size"], job["intersector"],
               job["kernel_mode"])
    with _WORKER_LOCK:
        entry = _WORKER_CACHE.get(key)
        if entry is None:
            for k in [k for k in _WORKER_CACHE if k[0] == key[0]]:
                del _WORKER_CACHE[k]  # one scene per worker at a time: free the device memory
            settings = ImageSettings.from_dict(job["settings"])
            options = dict(wave_size=job["wave_size"], intersector=job["intersector"], kernel_mode=job["kernel_mode"])
            devices = resolve(job["device"])
            t0 = time.perf_counter()
            if len(devices) == 1:
                from .wavefront import Wavefront

                renderer = first = Wavefront(scene, devices[0], settings, **options)
            else:
                from .multidevice import MultiDevice

                renderer = MultiDevice(scene, devices, settings=settings, **options)
                renderer.prepare()
                first = renderer.wavefronts[0]
            description = {"devices": [device_label(d) for d in devices], **first.description(),
                           "setup_seconds": time.perf_counter() - t0}
            entry = _WORKER_CACHE[key] = (renderer, description, threading.Lock())
    return entry


def render_chunk(scene, job: dict, first: int, count: int) -> dict:
    """Worker task: passes [first, first + count) into a fresh film; returns its sums."""
    from distributed import get_worker

    film = Film.new(job["settings"]["width"], job["settings"]["height"], aovs=job["settings"].get("film_aovs", False))
    # a time-limited render: stop at the client's deadline (whole passes), and start nothing after it
    remaining = None if job.get("deadline_epoch") is None else job["deadline_epoch"] - time.time()
    if remaining is not None and remaining <= 0:
        st, description = RunStats(), None
    else:
        renderer, description, lock = _renderer(scene, job)
        with lock:  # a worker with several threads shares one renderer
            st = renderer.run(film, passes=count, first_pass=first, time_limit=remaining,
                              profile=job.get("profile", False))
    return {
        "first": first, "passes": film.passes, "sum": film.sum, "sum_sq": film.sum_sq, "aov_sum": film.aov_sum,
        "worker": get_worker().address, "seconds": st.seconds, "description": description,
        "stats": {"iterations": st.iterations, "rays_extend": st.rays_extend, "rays_shadow": st.rays_shadow,
                  "nonfinite": st.nonfinite, "stage_seconds": dict(st.stage_seconds)},
    }


# -- client side ---------------------------------------------------------------------------------
def run(scene, scheduler, film: Film, *, settings: ImageSettings, key: str, passes=None, time_limit=None,
        device=None, wave_size=None, intersector="opencl", kernel_mode=None, progress=None, profile=False, cancel=None,
        on_tick=None,
        chunk=None, tick_seconds=0.25) -> tuple[RunStats, dict]:
    """Render passes [film.passes, film.passes + passes) (or until time_limit) on the cluster into
    ``film``.  Returns (stats, {worker address: its renderer's description})."""
    distributed = _import()
    if passes is None and time_limit is None:
        raise ValueError("give passes, time_limit or both")
    client, cluster, owned = connect(scheduler)
    stats = RunStats()
    descriptions: dict = {}
    workers: dict = {}
    first_pass = film.passes
    n_pixels = film.sum.shape[0]
    try:
        n_workers = max(1, len(client.scheduler_info()["workers"]))
        job = {"key": key, "settings": settings.as_dict(), "device": device, "wave_size": wave_size,
               "intersector": getattr(intersector, "name", intersector), "kernel_mode": kernel_mode, "profile": profile}
        # the scene travels once to each worker; under a key of its own (hash=False): two renders of
        # one scene would share a content-hashed key, and the first to finish released the other's data
        scene_f = client.scatter(scene, broadcast=True, hash=False)
        if chunk is None:
            chunk = max(1, min(16, math.ceil(passes / (4 * n_workers)))) if passes is not None else 1
        end = None if passes is None else first_pass + passes
        start = time.perf_counter()
        # a time limit counts from the first pass a worker rendered (as Wavefront.run counts it,
        # after its setup); the workers are told the deadline and stop on it themselves
        deadline = None
        next_new = first_pass
        done: dict[int, dict] = {}
        in_flight: dict = {}
        last_report = 0.0

        def submit():
            nonlocal next_new
            while len(in_flight) < 2 * n_workers:
                if end is not None and next_new >= end or deadline is not None and time.perf_counter() >= deadline:
                    return
                k = chunk if end is None else min(chunk, end - next_new)
                fut = client.submit(render_chunk, scene_f, job, next_new, k, pure=False, retries=2)
                in_flight[fut] = (next_new, k)
                next_new += k

        try:
            submit()
            while in_flight:
                try:
                    distributed.wait(list(in_flight), timeout=tick_seconds, return_when="FIRST_COMPLETED")
                except TimeoutError:  # (asyncio's, the builtin since Python 3.11)
                    pass
                if cancel is not None and cancel():
                    raise KeyboardInterrupt
                for fut in [f for f in in_flight if f.done()]:
                    first, k = in_flight.pop(fut)
                    r = fut.result()  # re-raises a chunk that failed after its retries
                    done[first] = r
                    if time_limit is not None and deadline is None and r["passes"]:
                        deadline = time.perf_counter() - r["seconds"] + time_limit
                        job = {**job, "deadline_epoch": time.time() - r["seconds"] + time_limit}
                    if r["description"] is not None:
                        descriptions[r["worker"]] = r["description"]
                    w = workers.setdefault(r["worker"], {"passes": 0, "seconds": 0.0})
                    w["passes"] += r["passes"]
                    w["seconds"] += r["seconds"]
                    for name in ("iterations", "rays_extend", "rays_shadow", "nonfinite"):
                        setattr(stats, name, getattr(stats, name) + r["stats"][name])
                    stats.add_stage_seconds(r["stats"]["stage_seconds"])
                    if chunk and passes is None and r["seconds"] > 0:  # time-limited: ~1 s chunks
                        chunk = max(1, int(r["passes"] / r["seconds"]))
                _fold(done, film)
                if on_tick is not None:
                    on_tick(film)
                now = time.perf_counter()
                if progress is not None and now - last_report >= 0.1:
                    last_report = now
                    _report(progress, workers, n_pixels, film.passes - first_pass, now - start)
                submit()
        except KeyboardInterrupt:
            stats.interrupted = True
            client.cancel(list(in_flight))
        _fold(done, film)
        stats.passes = film.passes - first_pass
        stats.samples = stats.passes * n_pixels
        stats.seconds = time.perf_counter() - start
        total = sum(w["passes"] for w in workers.values())
        stats.devices = [
            {"device": f"{addr} " + ", ".join(descriptions.get(addr, {}).get("devices", [])),
             "passes": w["passes"],
             "samples_per_second": w["passes"] * n_pixels / w["seconds"] if w["seconds"] > 0 else None,
             "share": w["passes"] / total if total else 0.0, "failed": None}
            for addr, w in workers.items()
        ]
        if progress is not None:
            _report(progress, workers, n_pixels, stats.passes, stats.seconds)
    finally:
        if owned:
            client.close()
            if cluster is not None:
                cluster.close()
    return stats, descriptions


def _fold(done: dict, film: Film) -> None:
    """Add the chunk films that continue the film's prefix, in pass order."""
    while film.passes in done:
        r = done.pop(film.passes)
        film.add(r["sum"], r["sum_sq"], r["passes"], r.get("aov_sum"))
        if r["passes"] == 0:
            break


def _report(progress, workers, n_pixels, passes, elapsed):
    hook = getattr(progress, "device_rows", None)
    if hook is not None:
        total = sum(w["passes"] for w in workers.values())
        hook([{"device": addr, "passes": w["passes"],
               "samples_per_second": w["passes"] * n_pixels / w["seconds"] if w["seconds"] > 0 else None,
               "share": w["passes"] / total if total else 0.0, "failed": None} for addr, w in workers.items()])
    progress(passes, elapsed)
