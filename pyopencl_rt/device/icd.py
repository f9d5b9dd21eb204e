"""OpenCL implementations installed by pip, made visible to pyopencl without root.

pyopencl's wheel loads OpenCL through ocl-icd, which reads the ICD files of one folder
(``$OCL_ICD_VENDORS``, else ``/etc/OpenCL/vendors``) and the PoCL that ``pyopencl[pocl]`` ships.
Intel's CPU runtime from PyPI (``intel-opencl-rt``, the ``intel`` extra) puts ``libintelocl.so``
into the environment's ``lib/`` with an ICD file that names a path of Intel's build machine, so
pyopencl never sees it.  :func:`register` makes a folder holding every ICD file of the folder the
loader would have read, plus one naming the installed library, and points ``$OCL_ICD_VENDORS`` at
it: system drivers (a GPU's) stay visible, and a runtime already registered on the system is used
as it is.  The loader reads the variable on its first call, so this runs before
:func:`pyopencl_rt.device.devices.all_devices` asks for platforms (it calls :func:`register`);
a device choice that cannot pick a packaged runtime (the default: the first GPU, else PoCL;
``gpu``; ``pocl``) skips them (:func:`pyopencl_rt.device.devices.resolve`).

``$PYOPENCL_RT_PACKAGED_ICDS=0`` leaves the environment alone.
"""
from __future__ import annotations

import hashlib
import os
import sys
from pathlib import Path

ENV = "OCL_ICD_VENDORS"
SWITCH_ENV = "PYOPENCL_RT_PACKAGED_ICDS"
SYSTEM_VENDORS = "/etc/OpenCL/vendors"
# (library file name, ICD file name) of each implementation pip can install
PACKAGED = (("libintelocl.so", "pyopencl-rt-intel-cpu.icd"),)


def _library_dirs() -> list[Path]:
    """Where pip puts a wheel's ``data/lib`` files: this environment's prefix, the user base."""
    import site

    dirs = [Path(sys.prefix) / "lib"]
    user_base = getattr(site, "USER_BASE", None)
    if user_base:
        dirs.append(Path(user_base) / "lib")
    return dirs


def packaged_libraries() -> list[Path]:
    """The pip-installed OpenCL implementations' libraries found (absolute paths)."""
    found = []
    for name, _ in PACKAGED:
        for folder in _library_dirs():
            path = folder / name
            if path.is_file():
                found.append(path.resolve())
                break
    return found


def _icd_files(source: str) -> list[Path]:
    path = Path(source)
    if path.is_file():
        return [path]
    if path.is_dir():
        return sorted(p for p in path.iterdir() if p.suffix == ".icd" and p.is_file())
    return []


def _names_library(icd: Path, library: str) -> bool:
    try:
        return library in icd.read_text(errors="replace")
    except OSError:
        return False


def icd_folder(environ=os.environ) -> Path:
    base = environ.get("PYOPENCL_RT_CACHE") or os.path.join(os.path.expanduser("~"), ".cache", "pyopencl_rt")
    return Path(base) / "icd"


def register(environ=None, packaged: bool = True) -> str | None:
    """Point ``$OCL_ICD_VENDORS`` (of ``environ``, default this process's, where it is done once)
    at a folder with the loader's own ICD files and the packaged runtimes'; returns the folder,
    or None where nothing was added.  ``packaged`` False (this process's only): the packaged
    runtimes stay unregistered for the rest of the process, whose device choice cannot pick
    them: the loader opens every registered implementation on its first call, and Intel's CPU
    runtime costs about 100 MB of memory and 0.3 s in every process that opens it."""
    global _registered, _skipped
    if environ is None:
        if _registered is _UNSET:
            _registered = _register(os.environ) if packaged else None
            _skipped = not packaged and bool(packaged_libraries())
        return _registered
    return _register(environ)


def skipped_packaged() -> bool:
    """This process left installed packaged runtimes unregistered (register(packaged=False))."""
    return _skipped


_UNSET = object()
_registered = _UNSET
_skipped = False


def _register(environ) -> str | None:
    if environ.get(SWITCH_ENV, "").strip() == "0":
        return None
    existing = _icd_files(environ.get(ENV) or SYSTEM_VENDORS)
    wanted = [(icd_name, f"{library}\n") for library in packaged_libraries()
              for lib_name, icd_name in PACKAGED if library.name == lib_name
              and not any(_names_library(icd, lib_name) for icd in existing)]
    if not wanted:
        return None
    files = [(p.name, p.read_text(errors="replace")) for p in existing] + wanted
    folder = icd_folder(environ) / hashlib.sha256(repr(files).encode()).hexdigest()[:16]
    try:
        folder.mkdir(parents=True, exist_ok=True)
        for name, text in files:
            target = folder / name
            if not target.is_file() or target.read_text(errors="replace") != text:
                tmp = folder / f".{name}.{os.getpid()}"
                tmp.write_text(text)
                os.replace(tmp, target)
    except OSError:  # a read-only home: the packaged runtime stays invisible, nothing else changes
        return None
    environ[ENV] = str(folder)
    return str(folder)
