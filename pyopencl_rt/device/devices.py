"""Finding and choosing OpenCL devices.

Device specifications (``--device``, ``PYOPENCL_CTX``, the ``device=`` argument of the Python API):

``cpu`` / ``gpu`` / ``accelerator``
    the first device of that type (PoCL first among CPUs);
``pocl`` / ``intel``
    the first device of that implementation (PoCL; Intel's CPU runtime, pip's ``intel`` extra);
``all``
    every device of every platform;
``P:D``
    platform P, device D, each an index or a case-insensitive substring of the name, as in
    ``PYOPENCL_CTX`` (``0:0``, ``portable:pthread``, ``nvidia:``);
``P``
    the first device of platform P (index or substring);
``name``
    a substring of a device or platform name.

Several specifications may be given as a list or separated by commas.  With no specification,
``PYOPENCL_CTX`` is read; without it the default is the first GPU, else the PoCL CPU device.
"""
from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache

from ..errors import DeviceSelectionError
from . import icd


def _cl():
    import pyopencl as cl

    return cl


@dataclass(frozen=True)
class DeviceInfo:
    index: str  # "P:D"
    platform: str
    name: str
    type: str
    compute_units: int
    global_mem_bytes: int
    max_alloc_bytes: int
    opencl_version: str
    opencl_c_version: str
    driver_version: str
    implementation: str = "other"  # "pocl", "intel" (the --device names), "other"

    def as_dict(self) -> dict:
        return dict(self.__dict__)

    def label(self) -> str:
        return f"{self.index} {self.name} ({self.platform}, {self.type})"


@lru_cache(maxsize=None)
def all_devices() -> tuple:
    """Every OpenCL device of every platform, as ``((platform_index, device_index, device), ...)``
    (the pip-installed implementations registered first, unless :func:`resolve` has skipped them)."""
    icd.register()
    cl = _cl()
    try:
        platforms = cl.get_platforms()
    except cl.LogicError:  # no ICD at all (pyopencl raises PLATFORM_NOT_FOUND_KHR)
        return ()
    found = []
    for p_index, platform in enumerate(platforms):
        try:
            devices = platform.get_devices()
        except cl.Error:
            continue
        for d_index, device in enumerate(devices):
            found.append((p_index, d_index, device))
    return tuple(found)


def device_type_name(device) -> str:
    cl = _cl()
    t = device.type
    for flag, name in ((cl.device_type.GPU, "GPU"), (cl.device_type.CPU, "CPU"), (cl.device_type.ACCELERATOR, "ACCELERATOR")):
        if t & flag:
            return name
    return "OTHER"


def describe(entry) -> DeviceInfo:
    p_index, d_index, device = entry
    return DeviceInfo(
        index=f"{p_index}:{d_index}",
        platform=device.platform.name.strip(),
        name=device.name.strip(),
        type=device_type_name(device),
        compute_units=int(device.max_compute_units),
        global_mem_bytes=int(device.global_mem_size),
        max_alloc_bytes=int(device.max_mem_alloc_size),
        opencl_version=device.version.strip(),
        opencl_c_version=device.opencl_c_version.strip(),
        driver_version=device.driver_version.strip(),
        implementation=implementation(device),
    )


def list_devices() -> list[DeviceInfo]:
    return [describe(e) for e in all_devices()]


def implementation(device) -> str:
    """Which OpenCL implementation runs ``device``: ``"pocl"`` (Portable Computing Language, the
    one ``pyopencl[pocl]`` ships), ``"intel"`` (Intel's CPU runtime: platform "Intel(R) OpenCL", or
    "Intel(R) CPU Runtime for OpenCL(TM) Applications" before 2023; its GPU driver is another
    platform and not this one), else ``"other"``."""
    cl = _cl()
    platform = device.platform.name.lower()
    if "portable computing language" in platform or "pocl" in device.version.lower():
        return "pocl"
    if "intel" in platform and device.type & cl.device_type.CPU and "graphics" not in platform:
        return "intel"
    return "other"


def _is_pocl(device) -> bool:
    return implementation(device) == "pocl"


# --device names of implementations: every device of it ("pocl", "intel")
IMPLEMENTATION_NAMES = ("pocl", "intel")


def _match_part(text: str, index: int, names: list[str]) -> list[int]:
    """Indices in ``names`` selected by one half of a ``P:D`` spec (empty text = all)."""
    text = text.strip()
    if text == "":
        return list(range(len(names)))
    if text.isdigit():
        return [int(text)] if int(text) < len(names) else []
    return [i for i, n in enumerate(names) if text.lower() in n.lower()]


def _resolve_one(spec: str, entries) -> list:
    spec = spec.strip()
    low = spec.lower()
    cl = _cl()
    if low == "all":
        return list(entries)
    if low in IMPLEMENTATION_NAMES:
        return [e for e in entries if implementation(e[2]) == low][:1]
    if low in ("cpu", "gpu", "accelerator"):
        flag = {"cpu": cl.device_type.CPU, "gpu": cl.device_type.GPU, "accelerator": cl.device_type.ACCELERATOR}[low]
        typed = [e for e in entries if e[2].type & flag]
        if low == "cpu":  # PoCL first: it is the CPU device we ship and test
            typed.sort(key=lambda e: not _is_pocl(e[2]))
        return typed[:1]
    platforms = sorted({e[0] for e in entries})
    platform_names = {e[0]: e[2].platform.name for e in entries}
    if ":" in spec:
        p_text, d_text = spec.split(":", 1)
        chosen = []
        p_names = [platform_names.get(p, "") for p in range(max(platforms) + 1)] if platforms else []
        for p in _match_part(p_text, 0, p_names):
            devs = [e for e in entries if e[0] == p]
            d_names = [e[2].name for e in devs]
            picked = [devs[i] for i in _match_part(d_text, 0, d_names)]
            # "P:" or "name:" alone means every device of the matched platforms
            chosen.extend(picked)
        return chosen
    if spec.isdigit():  # a platform index alone: its first device
        devs = [e for e in entries if e[0] == int(spec)]
        return devs[:1]
    return [e for e in entries if low in e[2].name.lower() or low in e[2].platform.name.lower()][:1]


# device choices that never pick a pip-installed runtime (Intel's CPU one): a GPU, PoCL
_WITHOUT_PACKAGED = ("gpu", "pocl")


def _specs(spec) -> list[str]:
    """The specifications of ``spec`` (a string, a list of them, or None: $PYOPENCL_CTX, or none
    for the default choice)."""
    specs: list[str] = []
    if spec is None or spec == "" or (isinstance(spec, (list, tuple)) and not spec):
        env = os.environ.get("PYOPENCL_CTX", "").strip()
        if env:
            specs = [env]
    elif isinstance(spec, str):
        specs = [s for s in spec.split(",") if s.strip()]
    else:
        for s in spec:
            specs.extend(x for x in str(s).split(",") if x.strip())
    return specs


def resolve(spec=None, *, allow_many: bool = True) -> list:
    """Return the list of ``pyopencl.Device`` selected by ``spec`` (str, list of str, a Device or None).

    Raises :class:`DeviceSelectionError` with one line that names the available devices.
    """
    cl = _cl()
    if isinstance(spec, cl.Device):
        return [spec]
    if isinstance(spec, (list, tuple)) and spec and all(isinstance(s, cl.Device) for s in spec):
        return list(spec)
    specs = _specs(spec)
    if all(s.strip().lower() in _WITHOUT_PACKAGED for s in specs):
        icd.register(packaged=False)  # this choice cannot pick a pip-installed runtime: not opened
    entries = all_devices()
    if not entries:
        raise DeviceSelectionError(
            "no OpenCL device found: install PoCL with `pip install pyopencl[pocl]` or a GPU driver's ICD"
        )
    if not specs:
        gpus = [e for e in entries if e[2].type & cl.device_type.GPU]
        if gpus:
            chosen = gpus[:1]
        else:
            cpus = sorted(entries, key=lambda e: not _is_pocl(e[2]))
            chosen = cpus[:1]
    else:
        chosen = []
        for s in specs:
            matched = _resolve_one(s, entries)
            if not matched:
                available = "; ".join(describe(e).label() for e in entries)
                skipped = (" (this process's first device choice left the pip-installed runtimes unopened)"
                           if icd.skipped_packaged() else "")
                raise DeviceSelectionError(f"no OpenCL device matches {s!r}; available: {available}{skipped}")
            for m in matched:
                if m not in chosen:
                    chosen.append(m)
    if not allow_many:
        chosen = chosen[:1]
    return [e[2] for e in chosen]


def select_device(spec=None):
    """The single device selected by ``spec`` (the first one when the spec names several)."""
    return resolve(spec, allow_many=False)[0]


def device_label(device) -> str:
    for e in all_devices():
        if e[2] == device:
            return describe(e).label()
    return f"{device.name.strip()} ({device.platform.name.strip()})"


def device_test_specs() -> list[str]:
    """Devices the test-suite runs on: ``PYOPENCL_TEST`` (comma list of specs) or every device."""
    env = os.environ.get("PYOPENCL_TEST", "").strip()
    if not env:
        return [describe(e).index for e in all_devices()]
    chosen = resolve([s for s in env.split(",") if s.strip()])  # "all", "cpu,gpu", ... -> devices
    return [describe(e).index for e in all_devices() if e[2] in chosen]
