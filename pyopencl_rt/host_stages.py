"""Seconds spent in each host stage of a render (``--profile``; the JSON sidecar's
``host_seconds``, docs/OUTPUT.md): read the mesh files, compute normals, validate, build the
BVH, collapse it into the device's node layout, build the light tables, compile the kernels,
upload the buffers.

    with host_stage("normals"):
        ...

Stages add up over a process (a stage met twice, such as validation, is their sum); ``load``
(the scene file, in the CLI) holds ``mesh_read``, ``normals`` and a first ``validation``.
:func:`reset` starts again; :func:`snapshot` is a copy, stages in order of first use;
:func:`peak_rss` the process's peak resident memory (MB) when each stage last ended, which says
in which stage the peak was reached.
"""
from __future__ import annotations

import time
from contextlib import contextmanager

_SECONDS: dict = {}
_PEAK_MB: dict = {}


def _max_rss_mb():
    try:
        import resource

        return resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0  # KB on Linux
    except (ImportError, OSError):
        return None


@contextmanager
def host_stage(name: str):
    start = time.perf_counter()
    try:
        yield
    finally:
        _SECONDS[name] = _SECONDS.get(name, 0.0) + time.perf_counter() - start
        _PEAK_MB[name] = _max_rss_mb()


def reset() -> None:
    _SECONDS.clear()
    _PEAK_MB.clear()


def peak_rss() -> dict:
    return dict(_PEAK_MB)


def snapshot() -> dict:
    return dict(_SECONDS)
