"""What PoCL's CPU device compiles our kernels for, and the SIMD width they may use there.

PoCL 3.0 compiles a kernel for LLVM's name of the host CPU (``-target-cpu``; the device's version
string carries it: ``HSTR: pthread-x86_64-unknown-linux-gnu-znver3``) and links one built-in library
(``kernel-x86_64-unknown-linux-gnu-{sse2,...,avx2,avx512}.bc``) chosen from the host's feature
flags.  The two can disagree: PoCL 3.0's LLVM 14 names every AMD family-19h CPU ``znver3``, so on
Zen 4 the compile has no AVX-512 while the library is the AVX-512 one; a CPU LLVM 14 does not know
at all compiles as ``generic`` x86-64 (SSE2) against whatever library its flags pick.

That matters for vectors passed to a built-in the compiler does not inline (and it cannot inline
a library function that needs features the caller lacks): a 32-byte vector (float8, double4)
travels in a YMM register only where AVX is enabled, a 64-byte one (float16) in a ZMM register
only where AVX-512F is, and in memory otherwise.  Where the two sides differ, the callee reads
garbage (the Zen 4 segfaults of the 16-lane kernels).  So:

* the compile side is probed, not guessed: a tiny kernel reports the ``__AVX512F__``,
  ``__AVX2__``, ... macros its compile defines (:func:`probe`, once per device);
* the library side is what PoCL derives it from: the host flags, which PoCL also turns into the
  device's native float vector width (4, 8 or 16 floats: SSE, AVX, AVX-512F);
* the lane and packet kernels get 16 lanes only where the compile has AVX-512F and the library
  is the AVX-512 one, 8 only where the compile has AVX2 and the library the AVX one, else one path
  per work-item (:func:`simd_width`); a width forced through ``$PYOPENCL_RT_LANES`` is refused
  where its vectors would cross the library ABI differently (:meth:`CpuISA.passes_alike`);
* the rest of our code passes no vector wider than 16 bytes to a built-in (cl/cpu_builtins.h
  spells the conversions inline), which :func:`builtin_abi_crossings` checks in a build log.

A library above the compile (Zen 4) keeps the built-ins out of line; there the 8-lane kernel
was measured slower than one path per work-item (issue 22: 1.49 against 1.71 Msamples/s), so
that case runs one path per work-item.  docs/DEVICES.md, "SIMD width on CPUs", says the same for users.
"""
from __future__ import annotations

import os
import re
from dataclasses import dataclass

# compile-side macros the probe reports, bit by bit (cl/ code tests the same macros)
PROBED_FEATURES = ("sse4.2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512vl")
_PROBE_SOURCE = "__kernel void isa_probe(__global int *out)\n{\n    int f = 0;\n" + "".join(
    f"#ifdef __{name.upper().replace('.', '_')}__\n    f |= {1 << i};\n#endif\n"
    for i, name in enumerate(PROBED_FEATURES)) + "    out[0] = f;\n}\n"

# bytes of the widest vector register each feature brings (the ABI of vector arguments)
_REGISTER_FEATURES = ((64, "avx512f"), (32, "avx"))


@dataclass(frozen=True)
class CpuISA:
    """The instruction sets of one PoCL CPU device: what its kernel compile targets
    (``target_cpu``, ``features``) and the vector registers of the built-in library it links
    (``library_vector_bytes``: 16 SSE, 32 AVX, 64 AVX-512F)."""
    target_cpu: str | None
    features: frozenset
    library_vector_bytes: int

    @property
    def compile_vector_bytes(self) -> int:
        return next((n for n, f in _REGISTER_FEATURES if f in self.features), 16)

    def passes_alike(self, nbytes: int) -> bool:
        """Whether a vector of ``nbytes`` crosses a call into the built-in library the same way
        on both sides (in a register of its size on both, or in memory on both)."""
        return (self.compile_vector_bytes >= nbytes) == (self.library_vector_bytes >= nbytes)

    def library_features(self) -> set:
        """The register features of the library (those that decide how vectors are passed)."""
        return {f for n, f in _REGISTER_FEATURES if self.library_vector_bytes >= n}

    def describe(self) -> str:
        have = next((f.upper() for f in ("avx512f", "avx2", "avx", "sse4.2") if f in self.features), "SSE2")
        return (f"PoCL compiles for {self.target_cpu or 'an unnamed CPU'} (up to {have}) and links its "
                f"{self.library_vector_bytes * 8}-bit built-in library")

    def as_dict(self) -> dict:
        return {"target_cpu": self.target_cpu, "features": sorted(self.features),
                "library_vector_bits": self.library_vector_bytes * 8}


def target_cpu(device) -> str | None:
    """LLVM's CPU name that PoCL compiles for, from the device version's ``HSTR:`` field
    (``pthread-x86_64-unknown-linux-gnu-znver3`` -> ``znver3``); None where it is not given."""
    # "<device kind>-<4-part triple>-<cpu>"; the cpu name may hold hyphens (skylake-avx512)
    match = re.search(r"HSTR:\s*[\w]+-[\w.]+-[\w.]+-[\w.]+-[\w.]+-(\S+)", getattr(device, "version", "") or "")
    return match.group(1) if match else None


_PROBES: dict = {}


def probe(device) -> CpuISA:
    """The :class:`CpuISA` of a PoCL CPU device, measured once per device and PoCL version (a
    kernel that reports its compile's macros; the library width from the device's native float
    vector width, which PoCL sets from the same host flags it picks the library by)."""
    import numpy as np
    import pyopencl as cl

    key = (device.platform.name, device.platform.version, device.name, device.version, device.driver_version)
    isa = _PROBES.get(key)
    if isa is None:
        from .kernels import runtime

        rt = runtime(device)
        out = np.zeros(1, np.int32)
        buf = cl.Buffer(rt.context, cl.mem_flags.WRITE_ONLY, 4)
        with rt.lock:  # the probe has its own program: not worth a place in the runtime's cache
            kernel = cl.Program(rt.context, _PROBE_SOURCE).build().isa_probe
            kernel(rt.queue, (1,), None, buf)
            cl.enqueue_copy(rt.queue, out, buf)
        bits = int(out[0])
        features = frozenset(name for i, name in enumerate(PROBED_FEATURES) if bits >> i & 1)
        library = 4 * int(device.native_vector_width_float or 4)
        isa = _PROBES[key] = CpuISA(target_cpu(device), features, library)
    return isa


def simd_width(isa: CpuISA) -> tuple[int, str]:
    """Lanes of the packet kernels for ``isa`` (a PoCL CPU device) and why (see the module docstring)."""
    lib = isa.library_vector_bytes
    if "avx512f" in isa.features and lib == 64:
        return 16, f"16 lanes: {isa.describe()}"
    if "avx2" in isa.features and isa.passes_alike(32):
        # Zen 4 under PoCL 3.0 (AVX2 compile, AVX-512 library) too: 8 lanes measured 2x one path
        # there once no wide vector crossed a built-in (docs/DEVICES.md)
        return 8, f"8 lanes: {isa.describe()}"
    return 0, f"one path per work-item: {isa.describe()} (no AVX2)"


def checked_width(isa: CpuISA, requested: int) -> tuple[int, str | None]:
    """``requested`` lanes (8 or 16) where their vectors cross the library ABI alike, else the
    rule's width and a one-line reason for the refusal (:meth:`LaneRule.checked`)."""
    return pocl_rule(isa).checked(requested)


# clang's warning at a call (or definition) whose vector argument or result is passed by a feature
# the compile lacks; `<Spelling=...>` is where the callee's name was spelled, when a macro wrote it
_ABI_WARNING = re.compile(r"(?P<file>[^\s<>]+?):(?P<line>\d+):(?P<col>\d+)"
                          r"(?: <Spelling=(?P<sfile>[^<>]+?):(?P<sline>\d+):(?P<scol>\d+)>)?"
                          r": AVX vector (?:argument|return) of type '(?P<type>[^']*)'.*?"
                          r"without '(?P<feature>[\w.]+)' enabled changes the ABI")
_NAME = re.compile(r"[A-Za-z_]\w*")


def builtin_abi_crossings(log: str, source: str) -> list[tuple[str, str, str]]:
    """(built-in, vector type, missing feature) of each call into PoCL's built-in library, in the
    build log of ``source``, whose vector is passed differently with and without that feature.
    PoCL's headers rename every built-in to ``_cl_<name>``: a call counts when the name spelled
    where clang points (through any macro, ours or PoCL's) is such a name.  Calls between our
    own functions do not count: both sides are compiled alike."""
    files = {}

    def name_at(path, line, col):
        if path not in files:
            try:  # PoCL compiles a temporary copy of the program source; its headers stay on disk
                text = source if os.path.basename(path).startswith("tempfile") else open(path).read()
            except OSError:
                text = ""
            files[path] = text.splitlines()
        lines = files[path]
        m = _NAME.match(lines[line - 1], col - 1) if 0 < line <= len(lines) else None
        return m.group(0) if m else ""

    found = []
    for chunk in (log or "").split("warning: ")[1:]:
        m = _ABI_WARNING.match(chunk)
        if not m:
            continue
        if m.group("sfile"):
            name = name_at(m.group("sfile"), int(m.group("sline")), int(m.group("scol")))
        else:
            name = name_at(m.group("file"), int(m.group("line")), int(m.group("col")))
        if name.startswith("_cl_"):
            found.append((name, m.group("type").replace("__private ", ""), m.group("feature")))
    return found


def unsafe_crossings(log: str, source: str, isa: CpuISA) -> list[tuple[str, str, str]]:
    """The crossings of :func:`builtin_abi_crossings` that break with ``isa``'s library: those
    whose feature the library has (the compile lacks it, or clang would not have warned)."""
    have = isa.library_features()
    return [c for c in builtin_abi_crossings(log, source) if c[2] in have]


def program_crossings(program, device, isa: CpuISA | None = None) -> list[tuple[str, str, str]]:
    """:func:`builtin_abi_crossings` of a built pyopencl program (against ``isa``'s library: the
    unsafe ones, :func:`unsafe_crossings`)."""
    import pyopencl as cl

    log = program.get_build_info(device, cl.program_build_info.LOG)
    source = program.get_info(cl.program_info.SOURCE)
    return builtin_abi_crossings(log, source) if isa is None else unsafe_crossings(log, source, isa)


# ----------------------------------------------------------------------------- every implementation
def x86_cpu(device) -> bool:
    """Whether ``device`` is a CPU device of an x86-64 host (where the lane kernels are measured)."""
    import platform

    import pyopencl as cl

    return bool(device.type & cl.device_type.CPU) and platform.machine().lower() in ("x86_64", "amd64")


# Intel's CPU runtime: its compiler packs work-items into SIMD lanes itself (implicit vectorisation,
# also of the lane kernel's work-items) and builds its built-ins with the kernel, so every width
# builds alike; the default is the width tools/lane_widths.py measured fastest (docs/DEVICES.md
# records each host), by the device's vector register bytes (native float vector width x 4).
# 64: Xeon (Ice Lake, AVX-512), runtime 2026.2: 16 lanes 2.2x, 8 lanes 1.45x one path per work-item.
INTEL_CPU_WIDTH = {64: 16}


@dataclass(frozen=True)
class LaneRule:
    """What one CPU device does with lanes: the widths it builds alike (8, 16), the default width
    (0: one path per work-item), why, and a description of the implementation's target."""
    implementation: str
    widths: tuple
    default: int
    reason: str
    describe: str

    def checked(self, requested: int) -> tuple[int, str | None]:
        """``requested`` lanes where they build alike, else the default and a one-line refusal."""
        if requested in self.widths:
            return requested, None
        return self.default, (f"{requested} lanes refused: {self.describe}, which passes {4 * requested}-byte "
                              f"vectors differently; using {self.default or 'one path per work-item'}"
                              f"{' lanes' if self.default else ''}")


def pocl_rule(isa: CpuISA) -> LaneRule:
    """The :class:`LaneRule` of a PoCL CPU device whose compile and library are ``isa``."""
    default, reason = simd_width(isa)
    return LaneRule("pocl", tuple(w for w in (8, 16) if isa.passes_alike(4 * w)), default, reason, isa.describe())


def lane_rule(device) -> LaneRule:
    """The :class:`LaneRule` of an x86 CPU device, by implementation: PoCL by its probed compile
    and library (:func:`simd_width`, :meth:`CpuISA.passes_alike`); Intel's CPU runtime by
    measurement (:data:`INTEL_CPU_WIDTH`); another implementation one path per work-item by
    default, 8 and 16 lanes when asked (the lane code is portable OpenCL C)."""
    from .devices import implementation

    impl = implementation(device)
    if impl == "pocl":
        return pocl_rule(probe(device))
    register = 4 * int(device.native_vector_width_float or 4)
    name = f"{device.platform.name.strip()} {device.driver_version.strip()} ({register * 8}-bit vectors)"
    if impl == "intel" and register in INTEL_CPU_WIDTH:
        default, why = INTEL_CPU_WIDTH[register], "measured fastest there (tools/lane_widths.py)"
    elif impl == "intel":  # not measured: a register's width of floats, as PoCL's rule gives
        default = register // 4 if register // 4 in (8, 16) else 0
        why = "not measured at this register width: run tools/lane_widths.py"
    else:
        default, why = 0, "lanes not measured on this implementation"
    reason = f"{default} lanes: {name}, {why}" if default else f"one path per work-item: {name}, {why}"
    return LaneRule(impl, (8, 16), default, reason, name)
