"""Locating, assembling and building the OpenCL C sources in ``cl/``.

Sources are assembled on the host: ``#include "x.h"`` lines are expanded here (each file once, but
for a template, ``*.tpl.h``, which is expanded at every include: cl/accel/bvh_wide.tpl.h is the
wide traversal written once over the node width, included once per width),
and the header generated from :mod:`pyopencl_rt.device.abi` (structs, constants, WAVE_PARAMS) is prepended.  The program
text handed to the driver is therefore self-contained, so the driver's binary cache (and
pyopencl's) can never serve a stale binary after a header changed.  Feature switches are passed
as preprocessor defines, so a scene compiles only the code it uses.
"""
from __future__ import annotations

import os
import re
import time
import threading
import warnings
from functools import lru_cache
from pathlib import Path

from . import abi

_INCLUDE = re.compile(r'^\s*#\s*include\s+"([^"]+)"\s*$', re.M)


def cl_dir() -> Path:
    """The folder holding the kernel sources: ``cl/`` in a checkout, ``pyopencl_rt/cl`` in a wheel."""
    package = Path(__file__).resolve().parent.parent
    for candidate in (package / "cl", package.parent / "cl"):
        if (candidate / "accel" / "intersect.h").is_file():
            return candidate
    raise FileNotFoundError(f"OpenCL sources not found next to {package} (looked for cl/accel/intersect.h)")


_CONDITIONAL_OPEN = re.compile(r"^\s*#\s*if(n?def)?\b")
_CONDITIONAL_CLOSE = re.compile(r"^\s*#\s*endif\b")
_GUARD = re.compile(r"\A(?:\s*(?:/\*.*?\*/|//[^\n]*))*\s*#\s*ifndef\s+(\w+)\s*\n\s*#\s*define\s+\1\b", re.S)


def _generated_headers() -> dict:
    """Headers written from the ABI's tables, not read from cl/: their include path -> text."""
    from .cl_header import bsdf_includes, light_units, shape_units

    return {"materials/bsdfs.h": bsdf_includes(abi.MATERIAL_TYPES),
            "lights/units.h": light_units(abi.LIGHT_TYPES, abi.DELTA_LIGHTS),
            "shapes/units.h": shape_units(abi.SHAPE_TYPES)}


def assemble(*names: str, extra: str = "") -> str:
    """Concatenate the named sources, then ``extra`` source text, with every ``#include "x.h"``
    expanded from ``cl/`` as the preprocessor would: a header is expanded at each include until one
    of its expansions is outside every ``#if`` (its include guard then keeps any later one out, so
    later includes are dropped); a header included first inside an ``#if`` that turns out false is
    therefore still there for a later include.  A ``*.tpl.h`` template is expanded at every include."""
    root = cl_dir()
    generated = _generated_headers()
    unconditional: set[Path] = set()  # headers expanded at least once outside every #if
    open_headers: list[Path] = []  # the headers being expanded: their guards are defined there

    def expand_text(text: str, base: Path, level: int) -> str:
        """``text`` with its includes expanded; ``level``: the #if nesting around it."""
        out = []
        for line in text.splitlines(keepends=True):
            if _CONDITIONAL_OPEN.match(line):
                level += 1
            elif _CONDITIONAL_CLOSE.match(line):
                level -= 1
            include = _INCLUDE.match(line)
            out.append(expand(include.group(1), base, max(level, 0)) + "\n" if include else line)
        return "".join(out)

    def expand(name: str, base: Path, level: int) -> str:
        # an include is looked up next to the including file first, then in cl/
        path = (base / name).resolve()
        if not path.is_file():
            path = (root / name).resolve()
        text = generated.get(name)
        template = path.name.endswith(".tpl.h")
        if not template and (path in unconditional or path in open_headers):
            return ""
        if level == 0 and not template:
            unconditional.add(path)
        text = path.read_text() if text is None else text
        guarded = _GUARD.match(text) is not None  # a header's own guard is no condition on its text
        open_headers.append(path)
        try:
            return expand_text(text, path.parent, level - 1 if guarded else level)
        finally:
            open_headers.pop()

    body = "\n".join(expand(n, root, 0) for n in names)
    if extra:
        body += "\n" + expand_text(extra, root, 0)
    return abi.cl_header() + "\n" + body


def define_options(defines: dict | None) -> list[str]:
    opts = []
    for key, value in sorted((defines or {}).items()):
        if value is True or value is None:
            opts.append(f"-D{key}")
        elif value is False:
            continue
        else:
            opts.append(f"-D{key}={value}")
    return opts


def _never_release(obj) -> None:
    """Keep a pyopencl object alive until the process ends.  PoCL 3.0 keeps a reference to the IR
    of a program whose kernels it could not create, and aborts the process ("still have
    references to IRs") when the last context is released; a program never released keeps its
    context, so that release never comes."""
    import ctypes

    ctypes.pythonapi.Py_IncRef(ctypes.py_object(obj))


# a define that changes nothing but the build options, hence PoCL's cache key (DeviceRuntime.new_kernels)
CACHE_RETRY_DEFINE = "RT_KERNEL_CACHE_RETRY"


def _log_build(device, names, options, seconds: float) -> None:
    """One JSON line per program build to the file ``PYOPENCL_RT_BUILD_LOG`` names (unset: nothing),
    for finding which builds a test run or a render pays for (a warm kernel cache makes them short)."""
    path = os.environ.get("PYOPENCL_RT_BUILD_LOG")
    if not path:
        return
    import json

    line = json.dumps({"seconds": round(seconds, 3), "device": device.name.strip(), "names": list(names),
                       "options": options, "test": os.environ.get("PYTEST_CURRENT_TEST", "")})
    with open(path, "a") as log:
        log.write(line + "\n")


class DeviceRuntime:
    """A context and an in-order queue for one device (profiling enabled, for per-stage timings)."""

    def __init__(self, device):
        import pyopencl as cl

        self.device = device
        self.context = cl.Context([device])
        self.queue = cl.CommandQueue(
            self.context, device, properties=cl.command_queue_properties.PROFILING_ENABLE
        )
        self.lock = threading.Lock()
        self._programs: dict = {}
        self._kernels: dict = {}

    @property
    def has_fp64(self) -> bool:
        return "cl_khr_fp64" in self.device.extensions

    @staticmethod
    def _program_key(names, defines, extra) -> tuple:
        return tuple(names), tuple(sorted((defines or {}).items())), extra

    def program(self, names: tuple[str, ...], defines: dict | None = None, extra: str = ""):
        """Build (once per runtime) the program made of ``names`` (+ ``extra`` text) with ``defines``."""
        import pyopencl as cl

        key = self._program_key(names, defines, extra)
        with self.lock:
            prog = self._programs.get(key)
            if prog is None:
                source = assemble(*names, extra=extra)
                options = []  # no fast-relaxed-math: watertightness relies on IEEE rounding
                options += define_options(defines)
                started = time.perf_counter()
                with warnings.catch_warnings():  # a compiler's remarks (Intel's runtime logs its
                    warnings.simplefilter("ignore", cl.CompilerWarning)  # vectoriser's) are not the user's
                    prog = cl.Program(self.context, source).build(options=options)
                _log_build(self.device, names, options, time.perf_counter() - started)
                self._programs[key] = prog
            return prog

    def new_kernels(self, names: tuple[str, ...], kernel_names, defines: dict | None = None, extra: str = "") -> dict:
        """New kernel objects (their own arguments) named ``kernel_names`` of the program
        :meth:`program` builds.  A program whose kernels cannot be created, as when PoCL serves a
        cache entry that a crash left half written (``INVALID_KERNEL_NAME``), is built once more
        under another cache key (:data:`CACHE_RETRY_DEFINE`), with one warning line."""
        import pyopencl as cl

        prog = self.program(names, defines, extra)
        try:
            return {name: cl.Kernel(prog, name) for name in kernel_names}
        except cl.Error as exc:
            if (defines or {}).get(CACHE_RETRY_DEFINE):
                raise
            warnings.warn(f"PoCL served a program whose kernels cannot be created ({str(exc).splitlines()[0]}; "
                          "a broken kernel-cache entry?): building it again", stacklevel=2)
            with self.lock:
                self._programs.pop(self._program_key(names, defines, extra), None)
            _never_release(prog)
            return self.new_kernels(names, kernel_names, {**(defines or {}), CACHE_RETRY_DEFINE: 1}, extra)

    def kernel(self, names: tuple[str, ...], kernel_name: str, defines: dict | None = None, extra: str = ""):
        """One kernel object per (program, name), reused across calls (kernel retrieval is costly)."""
        key = (self._program_key(names, defines, extra), kernel_name)
        with self.lock:
            k = self._kernels.get(key)
        if k is None:
            k = self.new_kernels(names, (kernel_name,), defines, extra)[kernel_name]
            with self.lock:
                k = self._kernels.setdefault(key, k)
        return k


@lru_cache(maxsize=None)
def runtime(device) -> DeviceRuntime:
    return DeviceRuntime(device)
