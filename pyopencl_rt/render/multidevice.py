"""Several devices in one render: one wavefront per device, passes from a shared pool, one film.

Each device gets a host thread that owns its :class:`~pyopencl_rt.wavefront.Wavefront` (its own
context and queue) and asks the :class:`PassPool` for a contiguous range of sample passes
[first, first + k); pyopencl releases the GIL while it waits on the device, so the threads do
not hold one another up.  The range size follows the device's measured throughput (about
``target_seconds`` of work, and no more than its share of what is left), so a fast GPU takes
more passes than a CPU and the devices finish together.

Merging is exact: every finished pass's radiance goes to the pool, which adds it to the film in
pass order (passes finished ahead of a slower device's wait in a bounded buffer), so the film
holds the same float64 sums, added in the same order, as a single-device render.  On identical
devices the image is therefore bit for bit the one-device image; across different devices the
passes themselves may differ by float32 rounding.  The film always holds a prefix [0, n) of
the passes, which is what checkpoints and ``--resume`` need.

A device that raises while rendering is dropped with a warning; the passes of its batch that it
had not finished go back to the pool (lowest first) for the other devices.  The main thread only
waits on a condition (with a timeout, for the progress bar and checkpoints).
"""
from __future__ import annotations

import threading
import time
import warnings
from dataclasses import dataclass, field

import numpy as np

from ..errors import UserError
from .wavefront import Wavefront, check_pass_range
from .film import Film, RunStats

TARGET_SECONDS = 0.5  # work per batch once a device's throughput is known
BUFFER_BYTES = 512 << 20  # passes finished out of order that may wait for an earlier one
DEVICE_TIMEOUT = 120.0  # seconds without progress (a wave iteration) before a device is dropped as hung


class DeviceFailure(UserError):
    """Every device failed."""


@dataclass
class DeviceState:
    index: int
    label: str
    device: object = None
    wavefront: Wavefront | None = None
    passes: int = 0  # delivered passes
    busy_seconds: float = 0.0
    rate: float | None = None  # passes per second (not measured on the first batch: warm-up)
    batches: int = 0
    busy: bool = False
    alive: bool = True
    error: str | None = None
    stats: list = field(default_factory=list)
    beat: float = 0.0  # time.monotonic() of its last sign of progress (a wave iteration, a pass)
    hung: bool = False  # dropped for making no progress: whatever its thread still does is ignored
    batch: tuple = (0, 0)  # the range it renders now: (first, count)
    batch_done: int = 0  # passes of that range delivered

    def row(self, n_pixels: int, total: int) -> dict:
        return {
            "device": self.label,
            "passes": self.passes,
            "samples_per_second": self.passes * n_pixels / self.busy_seconds if self.busy_seconds > 0 else None,
            "share": self.passes / total if total else 0.0,
            "failed": self.error,
        }


class _PassForwarder:
    """Stands in for the film in a device's Wavefront.run (which only calls add_pass): each
    finished pass goes to the pool, numbered from ``first``."""

    def __init__(self, pool: "PassPool", dev: DeviceState, first: int):
        self.pool, self.dev, self.next = pool, dev, first
        self.count = 0

    def add_pass(self, radiance: np.ndarray, aov: np.ndarray | None = None) -> None:
        self.pool.deliver(self.dev, self.next, radiance, aov)
        self.next += 1
        self.count += 1


class PassPool:
    """Hands out pass ranges and folds finished passes into ``film`` in pass order."""

    def __init__(self, film: Film, first_pass: int, passes: int | None, deadline: float | None,
                 devices: list[DeviceState], target_seconds=TARGET_SECONDS, buffer_bytes=BUFFER_BYTES):
        self.film = film
        self.cond = threading.Condition()
        self.next_new = first_pass  # first pass never handed out
        self.merged = first_pass  # first pass not yet in the film
        self.end = None if passes is None else first_pass + passes
        self.deadline = deadline
        self.devices = devices
        self.returned: list[tuple[int, int]] = []  # ranges given back by failed / stopped devices
        self.buffer: dict[int, np.ndarray] = {}
        self.target = target_seconds
        pass_bytes = film.sum.shape[0] * 12 + (0 if film.aov_sum is None else film.aov_sum[0].size * 4 * film.sum.shape[0])
        self.window = max(4 * len(devices), int(buffer_bytes // max(1, pass_bytes)))
        self.stopped = False

    # -- called by device threads ---------------------------------------------------------
    def deliver(self, dev: DeviceState, index: int, radiance: np.ndarray, aov: np.ndarray | None = None) -> None:
        with self.cond:
            if dev.hung:  # its range went to the other devices
                return
            dev.passes += 1
            dev.beat = time.monotonic()
            dev.batch_done = index - dev.batch[0] + 1
            if index == self.merged:
                self.film.add_pass(radiance, aov)
                self.merged += 1
                while self.merged in self.buffer:
                    self.film.add_pass(*self.buffer.pop(self.merged))
                    self.merged += 1
            elif index > self.merged:  # the ring buffers are reused: copies
                self.buffer[index] = (np.array(radiance, copy=True), None if aov is None else np.array(aov, copy=True))
            self.cond.notify_all()

    def _size(self, dev: DeviceState, remaining: int | None) -> int:
        if dev.rate is None:
            return 1  # measure first
        k = dev.rate * self.target
        live = [d.rate for d in self.devices if d.alive and d.rate]
        if remaining is not None:
            k = min(k, remaining * dev.rate / sum(live))
        if self.deadline is not None:
            k = min(k, dev.rate * (self.deadline - time.perf_counter()))
        return max(1, int(k))

    def take(self, dev: DeviceState):
        """The next range (first, count) for ``dev``, or None when there is nothing left for it."""
        with self.cond:
            while True:
                if self.stopped or not dev.alive:
                    return None
                past_deadline = self.deadline is not None and time.perf_counter() >= self.deadline
                if self.returned and not past_deadline:
                    self.returned.sort()
                    first, count = self.returned.pop(0)
                    k = min(count, self._size(dev, None))
                    if k < count:
                        self.returned.append((first + k, count - k))
                    return self._hand_out(dev, first, k)
                remaining = None if self.end is None else self.end - self.next_new
                others_busy = any(d.busy for d in self.devices if d is not dev and d.alive)
                if past_deadline or (remaining is not None and remaining <= 0):
                    if not others_busy:
                        return None
                    self.cond.wait()  # another device may fail and give its passes back
                    continue
                allowed = self.merged + self.window - self.next_new
                if allowed <= 0 or self._slower_than_the_rest(dev, remaining):
                    # the buffer is full (pass `merged` is in flight elsewhere), or a much faster
                    # device (alive, so it will come back) should take the last passes
                    self.cond.wait()
                    continue
                k = min(self._size(dev, remaining), allowed)
                if remaining is not None:
                    k = min(k, remaining)
                first = self.next_new
                self.next_new += k
                return self._hand_out(dev, first, k)

    def _hand_out(self, dev: DeviceState, first: int, count: int) -> tuple[int, int]:
        dev.busy, dev.batch, dev.batch_done, dev.beat = True, (first, count), 0, time.monotonic()
        return first, count

    def _slower_than_the_rest(self, dev: DeviceState, remaining) -> bool:
        """Near the end, a slow device leaves the last passes to a much faster one."""
        if remaining is None or dev.rate is None:
            return False
        fastest = max((d.rate for d in self.devices if d is not dev and d.alive and d.rate), default=None)
        return fastest is not None and fastest > 2 * dev.rate and remaining / fastest < 1.0 / dev.rate

    def finish(self, dev: DeviceState, first: int, count: int, done: int, seconds: float, failed=None) -> None:
        with self.cond:
            if dev.hung:  # dropped already; its range was given back then
                return
            dev.busy = False
            dev.busy_seconds += seconds
            dev.batches += 1
            if done > 0 and seconds > 0 and dev.batches > 1:  # the first launches compile (PoCL)
                r = done / seconds
                dev.rate = r if dev.rate is None else 0.5 * dev.rate + 0.5 * r
            if done < count:
                self.returned.append((first + done, count - done))
            if failed is not None:
                dev.alive = False
                dev.error = failed
            self.cond.notify_all()

    def drop_hung(self, dev: DeviceState, seconds: float) -> tuple[int, int] | None:
        """Drop ``dev`` if it is still busy with no sign of progress for ``seconds``, as if it
        had failed: the undelivered rest of its range goes back to the pool.  Returns that range."""
        with self.cond:
            if not (dev.busy and dev.alive) or time.monotonic() - dev.beat < seconds:
                return None
            first, count = dev.batch
            rest = (first + dev.batch_done, count - dev.batch_done)
            if rest[1] > 0:
                self.returned.append(rest)
            dev.hung, dev.alive, dev.busy = True, False, False
            dev.error = f"no progress for {seconds:g} s (hung)"
            self.cond.notify_all()
            return rest

    def stop(self) -> None:
        with self.cond:
            self.stopped = True
            self.cond.notify_all()

    def snapshot(self) -> Film:
        with self.cond:
            return self.film.copy()


class MultiDevice:
    """Render passes [first_pass, first_pass + passes) of one image on several devices.

    ``devices`` are pyopencl devices (a Wavefront is built on each, in its thread) or ready
    Wavefronts (all of the same image settings).  ``wavefront_kwargs`` go to each Wavefront.
    """

    def __init__(self, scene, devices, *, bvh=None, target_seconds=TARGET_SECONDS, buffer_bytes=BUFFER_BYTES,
                 device_timeout=DEVICE_TIMEOUT, **wavefront_kwargs):
        from ..device.devices import device_label

        self.device_timeout = DEVICE_TIMEOUT if device_timeout is None else float(device_timeout)
        self.scene = scene if bvh is not None else scene.camera_relative()  # see Scene.camera_relative
        self.bvh = bvh
        self.kwargs = wavefront_kwargs
        self.target = target_seconds
        self.buffer_bytes = buffer_bytes
        self.devices = []
        for i, d in enumerate(devices):
            wf = d if isinstance(d, Wavefront) else None
            dev = wf.device if wf is not None else d
            self.devices.append(DeviceState(i, device_label(dev), device=dev, wavefront=wf))
        if self.bvh is None and any(d.wavefront is None for d in self.devices):
            from ..accel.bvh import build_bvh

            self.bvh = build_bvh(self.scene.vertices, self.scene.faces)
        self.pool = None

    def prepare(self) -> None:
        """Build the missing Wavefronts, one thread per device (kernel builds overlap)."""
        def build(d):
            try:
                d.wavefront = Wavefront(self.scene, d.device, bvh=self.bvh, **self.kwargs)
            except Exception as exc:  # a device that cannot build the kernels is left out
                d.alive, d.error = False, f"{type(exc).__name__}: {exc}"
                warnings.warn(f"device {d.label} dropped: {d.error}", RuntimeWarning, stacklevel=2)

        pending = [d for d in self.devices if d.wavefront is None and d.alive]
        threads = [threading.Thread(target=build, args=(d,), daemon=True) for d in pending]
        for t in threads:
            t.start()
        deadline = time.monotonic() + self.device_timeout
        for d, t in zip(pending, threads):
            t.join(max(0.0, deadline - time.monotonic()))
            if t.is_alive():  # a driver that never returns from the build: left behind, like a failure
                d.alive, d.hung, d.error = False, True, f"kernel build did not finish in {self.device_timeout:g} s"
                warnings.warn(f"device {d.label} dropped: {d.error}", RuntimeWarning, stacklevel=2)
        if not any(d.alive for d in self.devices):
            raise DeviceFailure("no device could build the kernels: " + "; ".join(d.error or "" for d in self.devices))

    @property
    def wavefronts(self):
        return [d.wavefront for d in self.devices if d.wavefront is not None]

    def run(self, film: Film, passes=None, time_limit=None, progress=None, profile=False, first_pass=None,
            cancel=None, on_tick=None, tick_seconds=0.25) -> RunStats:
        """Like :meth:`Wavefront.run`: passes [first_pass, first_pass + passes) (first_pass defaults
        to film.passes) or whole passes until time_limit, into ``film``.

        ``cancel`` (a callable) or KeyboardInterrupt in the calling thread stop every device; the
        passes in flight are dropped and the film keeps the prefix of complete passes.
        ``on_tick(pool)`` is called from the calling thread about every ``tick_seconds`` (checkpoints).
        """
        if passes is None and time_limit is None:
            raise ValueError("give passes, time_limit or both")
        self.prepare()
        first_pass = film.passes if first_pass is None else first_pass
        check_pass_range(first_pass, passes)
        start = time.perf_counter()
        deadline = None if time_limit is None else start + time_limit
        live = [d for d in self.devices if d.alive]
        pool = self.pool = PassPool(film, first_pass, passes, deadline, live, self.target, self.buffer_bytes)
        n_pixels = film.sum.shape[0]
        stats = RunStats()

        def loop(d: DeviceState):
            wf = d.wavefront

            def cancelled():  # called once per wave iteration: the device's heartbeat
                d.beat = time.monotonic()
                return pool.stopped or d.hung

            while True:
                batch = pool.take(d)
                if batch is None:
                    return
                first, count = batch
                forwarder = _PassForwarder(pool, d, first)
                t0 = time.perf_counter()
                try:
                    st = wf.run(forwarder, passes=count, first_pass=first, profile=profile, cancel=cancelled)
                except Exception as exc:
                    msg = f"{type(exc).__name__}: {exc}"
                    pool.finish(d, first, count, forwarder.count, time.perf_counter() - t0, failed=msg)
                    warnings.warn(f"device {d.label} failed and was dropped ({msg}); its unfinished passes "
                                  f"[{first + forwarder.count}, {first + count}) go to the other devices",
                                  RuntimeWarning, stacklevel=2)
                    return
                d.stats.append(st)
                pool.finish(d, first, count, forwarder.count, time.perf_counter() - t0)

        threads = [threading.Thread(target=loop, args=(d,), name=f"pyopencl-rt device {d.index}", daemon=True)
                   for d in live]
        for t in threads:
            t.start()
        try:
            last_report = 0.0
            while any(t.is_alive() and not d.hung for t, d in zip(threads, live)):
                with pool.cond:
                    pool.cond.wait(timeout=tick_seconds)
                if cancel is not None and cancel():
                    raise KeyboardInterrupt
                self._drop_hung(pool, live)
                now = time.perf_counter()
                if progress is not None and now - last_report >= 0.1:
                    last_report = now
                    self._report(progress, pool, n_pixels, first_pass, now - start)
                if on_tick is not None:
                    on_tick(pool)
        except KeyboardInterrupt:
            stats.interrupted = True
            pool.stop()
        for t, d in zip(threads, live):
            if not d.hung:  # a hung device's thread is left to the driver (a daemon thread)
                t.join()
        if pool.end is not None and pool.merged < pool.end and not stats.interrupted and not pool.stopped:
            if not any(d.alive for d in live):
                raise DeviceFailure("every device failed: " + "; ".join(f"{d.label}: {d.error}" for d in live))
        if progress is not None:
            self._report(progress, pool, n_pixels, first_pass, time.perf_counter() - start)
        stats.passes = pool.merged - first_pass
        stats.samples = stats.passes * n_pixels
        stats.seconds = time.perf_counter() - start
        for d in live:
            for st in d.stats:
                stats.iterations += st.iterations
                stats.rays_extend += st.rays_extend
                stats.rays_shadow += st.rays_shadow
                stats.nonfinite += st.nonfinite
                stats.add_stage_seconds(st.stage_seconds)
        stats.devices = self.rows(n_pixels)
        return stats

    def _drop_hung(self, pool: PassPool, live) -> None:
        for d in live:
            rest = pool.drop_hung(d, self.device_timeout)
            if rest is not None:
                warnings.warn(f"device {d.label} made no progress for {self.device_timeout:g} s and was dropped; its "
                              f"unfinished passes [{rest[0]}, {rest[0] + rest[1]}) go to the other devices",
                              RuntimeWarning, stacklevel=3)

    def rows(self, n_pixels: int) -> list[dict]:
        total = sum(d.passes for d in self.devices)
        return [d.row(n_pixels, total) for d in self.devices]

    def _report(self, progress, pool, n_pixels, first_pass, elapsed):
        rows = self.rows(n_pixels)
        hook = getattr(progress, "device_rows", None)
        if hook is not None:
            hook(rows)
        progress(pool.merged - first_pass, elapsed)
