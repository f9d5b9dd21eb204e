"""Embree on N processes, for timing it with as many threads as PoCL uses.

embreex's ``EmbreeScene.run`` traces its rays one ``rtcIntersect1`` at a time on the calling
thread and holds the GIL while it does (measured: two threads each running half the rays of a
1M-triangle torus took as long as one thread running them all), so a thread pool cannot run it
in parallel; processes can.  Each worker is this file run by the same Python (``--worker``: a
fresh interpreter, so neither the caller's main module nor PoCL's threads are involved); it builds
its own robust-mode scene of the mesh, once, untimed.  The rays and the results live in shared
memory.  Worker ``w`` of ``N`` traces the chunks ``w, w + N, w + 2N, ...`` of :data:`CHUNK` rays
(interleaved, so that every worker gets rays from all over the image), and reports the
monotonic clock (system-wide on Linux) at which it started and finished.  The time of a run is
the latest finish minus the earliest start: Embree's own parallel wall time, without the pipe
round trip, as the single-threaded figure is ``run()``'s time alone.
"""
from __future__ import annotations

import os
import subprocess
import sys
import time
from multiprocessing import resource_tracker, shared_memory
from multiprocessing.connection import Connection

import numpy as np

CHUNK = 4096
_FIELDS = (("origins", np.float32, 3), ("directions", np.float32, 3), ("t", np.float32, 1),
           ("prim", np.int32, 1))


def _views(buffer, n):
    """The shared arrays of n rays inside ``buffer``: name -> ndarray."""
    out, offset = {}, 0
    for name, dtype, width in _FIELDS:
        out[name] = np.ndarray((n, width) if width > 1 else (n,), dtype, buffer=buffer, offset=offset)
        offset += n * width * np.dtype(dtype).itemsize
    return out


def _bytes(n):
    return max(1, sum(n * width * np.dtype(dtype).itemsize for _name, dtype, width in _FIELDS))


def _serve(conn_in: Connection, conn_out: Connection, index: int, workers: int) -> None:
    from embreex import rtcore_scene
    from embreex.mesh_construction import TriangleMesh

    scene, shm, views, n = None, None, None, 0
    while True:
        message = conn_in.recv()
        kind = message[0]
        if kind == "mesh":
            _kind, vertices, faces = message
            scene = rtcore_scene.EmbreeScene(robust=True)
            TriangleMesh(scene, vertices, faces)
            scene.run(np.zeros((1, 3), np.float32), np.ones((1, 3), np.float32))  # commit: builds the BVH
            conn_out.send("ok")
        elif kind == "rays":
            views = None
            if shm is not None:
                shm.close()
            _kind, name, n = message
            shm = shared_memory.SharedMemory(name=name)
            # attaching registers it with this process's resource tracker, which would unlink it
            # (or report it leaked) at exit: the parent owns it
            resource_tracker.unregister(shm._name, "shared_memory")
            views = _views(shm.buf, n)
            conn_out.send("ok")
        elif kind == "run":
            start, cpu = time.perf_counter(), time.process_time()
            for first in range(index * CHUNK, n, workers * CHUNK):
                last = min(n, first + CHUNK)
                r = scene.run(views["origins"][first:last], views["directions"][first:last], output=1)
                views["t"][first:last] = r["tfar"]
                views["prim"][first:last] = r["primID"]
            conn_out.send((start, time.perf_counter(), time.process_time() - cpu))
        else:  # "stop"
            views = None
            if shm is not None:
                shm.close()
            conn_out.send("ok")
            return


class EmbreePool:
    """``workers`` processes tracing one mesh's rays with embreex together (see the module docstring).

    >>> with EmbreePool(2) as pool:
    ...     pool.load(vertices, faces)
    ...     pool.set_rays(origins, directions)
    ...     seconds = pool.run()        # then pool.t, pool.prim: the results
    """

    def __init__(self, workers: int):
        self.workers = max(1, int(workers))
        self._procs, self._send, self._recv = [], [], []
        for index in range(self.workers):
            to_child, from_parent = os.pipe()[::-1]     # (write end, read end)
            from_child, to_parent = os.pipe()
            proc = subprocess.Popen(
                [sys.executable, os.path.abspath(__file__), "--worker", str(from_parent), str(to_parent),
                 str(index), str(self.workers)],
                pass_fds=(from_parent, to_parent), stdin=subprocess.DEVNULL)
            os.close(from_parent)
            os.close(to_parent)
            self._procs.append(proc)
            self._send.append(Connection(to_child, readable=False))
            self._recv.append(Connection(from_child, writable=False))
        self._shm, self._views, self.n = None, None, 0
        self.cpu_seconds = 0.0

    def _all(self, message):
        for conn in self._send:
            conn.send(message)
        return [conn.recv() for conn in self._recv]

    def load(self, vertices, faces) -> None:
        """Every worker builds the robust-mode scene of this mesh (untimed)."""
        self._all(("mesh", np.ascontiguousarray(vertices, np.float32), np.ascontiguousarray(faces, np.int32)))

    def set_rays(self, origins, directions) -> None:
        n = len(origins)
        self._release()
        self._shm = shared_memory.SharedMemory(create=True, size=_bytes(n))
        self._views = _views(self._shm.buf, n)
        self._views["origins"][:] = origins
        self._views["directions"][:] = directions
        self.n = n
        self._all(("rays", self._shm.name, n))

    def run(self) -> float:
        """Trace the rays on every worker at once; the parallel wall time in seconds (the workers'
        CPU seconds together are left in :attr:`cpu_seconds`)."""
        spans = self._all(("run",))
        self.cpu_seconds = sum(cpu for _start, _end, cpu in spans)
        return max(end for _start, end, _cpu in spans) - min(start for start, _end, _cpu in spans)

    @property
    def t(self) -> np.ndarray:
        """tfar of the last run (Embree's value on a miss: the initial 1e37)."""
        return self._views["t"].copy()

    @property
    def prim(self) -> np.ndarray:
        """primID of the last run (-1 on a miss)."""
        return self._views["prim"].copy()

    def _release(self):
        if self._shm is not None:
            self._views = None
            self._shm.close()
            self._shm.unlink()
            self._shm = None

    def close(self) -> None:
        if self._procs:
            try:
                self._all(("stop",))
            finally:
                for conn in self._send + self._recv:
                    conn.close()
                for proc in self._procs:
                    proc.wait(timeout=30)
                self._procs, self._send, self._recv = [], [], []
        self._release()

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()


if __name__ == "__main__" and len(sys.argv) == 6 and sys.argv[1] == "--worker":
    _serve(Connection(int(sys.argv[2]), writable=False), Connection(int(sys.argv[3]), readable=False),
           int(sys.argv[4]), int(sys.argv[5]))
