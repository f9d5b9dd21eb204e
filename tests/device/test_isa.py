"""The SIMD width rule (pyopencl_rt/device/isa.py): what PoCL's compile targets is probed, not
guessed; 16 lanes only where the compile and PoCL's built-in library both have AVX-512F, 8 where
both pass 32-byte vectors in AVX registers and the compile has AVX2, else one path per work-item;
no vector of 32 bytes or more is passed from our kernels to a PoCL built-in (the Zen 4 segfaults:
a float16 passed in memory by a compile without AVX-512 to the AVX-512 library, which reads ZMM
registers); a lane kernel that fails to build falls back to one path; a PoCL cache entry that a
crash left half written is rebuilt, and the process does not abort."""
import os
import subprocess
import sys
import textwrap
import warnings
from pathlib import Path

import numpy as np
import pytest

import pyopencl_rt as rt
from pyopencl_rt.device import isa
from pyopencl_rt.device.isa import CpuISA
from pyopencl_rt.render import megakernel
from pyopencl_rt.render.wavefront import Wavefront

import harness

REPO = Path(__file__).resolve().parents[2]
AVX512 = frozenset({"sse4.2", "avx", "avx2", "fma", "avx512f", "avx512dq", "avx512vl"})
AVX2 = frozenset({"sse4.2", "avx", "avx2", "fma"})


def pocl_x86(device) -> CpuISA:
    from pyopencl_rt.device.devices import implementation

    if not harness.lane_kernels_build_on(device) or implementation(device) != "pocl":
        pytest.skip("the probe is for PoCL's CPU device on x86")
    return isa.probe(device)


# ----------------------------------------------------------------------------- the rule, case by case
# (compile target, its features, library register bytes) -> default width, forced 8 kept, forced 16 kept
CASES = {
    "Ice Lake server (AVX-512 both)": (("icelake-server", AVX512, 64), 16, True, True),
    "Zen 3 / Haswell (AVX2 both)": (("znver3", AVX2, 32), 8, True, True),
    # PoCL 3.0's LLVM 14 names Zen 4 znver3: no AVX-512 in the compile, the AVX-512 library linked;
    # 8 lanes pass their 32-byte vectors alike there, and measured 2x one path (issue 38)
    "Zen 4 under PoCL 3.0": (("znver3", AVX2, 64), 8, True, False),
    "Sandy Bridge (AVX, no AVX2)": (("sandybridge", frozenset({"sse4.2", "avx"}), 32), 0, True, True),
    "Nehalem (SSE4.2 both)": (("nehalem", frozenset({"sse4.2"}), 16), 0, True, True),
    # a CPU LLVM 14 does not know compiles as generic x86-64 against the library its flags pick
    "unknown CPU with AVX-512": (("generic", frozenset(), 64), 0, False, False),
}


@pytest.mark.parametrize("case", list(CASES))
def test_width_rule(case):
    (cpu, features, library), default, keeps_8, keeps_16 = CASES[case]
    machine = CpuISA(cpu, features, library)
    width, reason = isa.simd_width(machine)
    assert width == default
    assert reason.startswith(f"{width} lanes" if width else "one path per work-item") and cpu in reason
    for forced, kept in ((8, keeps_8), (16, keeps_16)):
        got, refusal = isa.checked_width(machine, forced)
        assert (got, refusal is None) == ((forced, True) if kept else (default, False)), forced
        # kept exactly where the vectors of that width travel alike on both sides of a call
        compile_in_register = machine.compile_vector_bytes >= 4 * forced
        library_in_register = library >= 4 * forced
        assert kept == (compile_in_register == library_in_register)


def test_zen4_reason_names_the_mismatch():
    width, reason = isa.simd_width(CpuISA("znver3", AVX2, 64))
    assert width == 8 and "512-bit built-in library" in reason and "znver3" in reason
    got, refusal = isa.checked_width(CpuISA("znver3", AVX2, 64), 16)
    assert got == 8 and "16 lanes refused" in refusal and "64-byte" in refusal


class FakeDevice:
    """What isa.lane_rule and devices.implementation read of a device, for implementations and
    hosts this machine lacks."""

    def __init__(self, platform, native_floats=16, kind="CPU", version="OpenCL 3.0", driver="1.0"):
        import types

        import pyopencl as cl

        self.platform = types.SimpleNamespace(name=platform)
        self.type = {"CPU": cl.device_type.CPU, "GPU": cl.device_type.GPU}[kind]
        self.version, self.driver_version, self.native_vector_width_float = version, driver, native_floats


def test_lane_rule_of_other_implementations(monkeypatch):
    """Intel's CPU runtime builds every width alike (one compiler builds the kernel and its
    built-ins) and defaults to the width measured fastest at its register width, else to a
    register of floats, saying it was not measured; another CPU implementation builds both widths
    when asked and defaults to one path per work-item; a GPU gets no lanes at all."""
    import platform

    from pyopencl_rt.accel import device_bvh
    from pyopencl_rt.device.devices import implementation

    monkeypatch.setattr(platform, "machine", lambda: "x86_64")
    monkeypatch.delenv(megakernel.LANES_ENV, raising=False)
    intel = FakeDevice("Intel(R) OpenCL", 16)
    assert implementation(intel) == "intel"
    rule = isa.lane_rule(intel)
    assert rule.widths == (8, 16) and rule.default == isa.INTEL_CPU_WIDTH[64]
    assert "measured" in rule.reason and "not measured" not in rule.reason
    assert rule.checked(8) == (8, None) and rule.checked(16) == (16, None)
    monkeypatch.setattr(isa, "INTEL_CPU_WIDTH", {})
    avx2 = isa.lane_rule(FakeDevice("Intel(R) CPU Runtime for OpenCL(TM) Applications", 8))
    assert avx2.default == 8 and "not measured" in avx2.reason and avx2.reason.startswith("8 lanes")
    other = isa.lane_rule(FakeDevice("Some CPU OpenCL", 8))
    assert implementation(FakeDevice("Some CPU OpenCL")) == "other"
    assert other.default == 0 and other.widths == (8, 16) and other.reason.startswith("one path")
    assert device_bvh.packet_choice(FakeDevice("Some CPU OpenCL", 8), "16") == (16, "16 lanes: "
                                                                                "$PYOPENCL_RT_LANES=16 (" + other.describe + ")")
    gpu = FakeDevice("Intel(R) OpenCL Graphics", 8, kind="GPU")
    assert implementation(gpu) == "other"
    assert device_bvh.packet_choice(gpu, "16")[0] == 0
    monkeypatch.setattr(platform, "machine", lambda: "aarch64")
    assert device_bvh.packet_choice(intel, "16")[0] == 0


def test_target_cpu_from_the_device_version():
    class Dev:
        version = "OpenCL 3.0 PoCL HSTR: pthread-x86_64-unknown-linux-gnu-skylake-avx512"

    assert isa.target_cpu(Dev) == "skylake-avx512"
    Dev.version = "OpenCL 3.0 CUDA"
    assert isa.target_cpu(Dev) is None


# ----------------------------------------------------------------------------- the probe
# a builtin each that clang accepts only where the compile has the feature
FEATURE_BUILTINS = {
    "avx": "const float8 v = (float8)(x); out[0] = __builtin_ia32_movmskps256(v);",
    "avx2": "const int8 v = (int8)(x); const int8 w = __builtin_ia32_psllv8si(v, v); out[0] = w.s0;",
    "avx512f": "const float16 v = (float16)(x); const float16 r = __builtin_ia32_rcp14ps512_mask(v, v, 0xffff);"
               " out[0] = (int)r.s0;",
}


@pytest.mark.parametrize("feature", list(FEATURE_BUILTINS))
def test_probe_says_what_the_compile_has(device, feature):
    """The probe reports a feature exactly where a kernel using an instruction of it builds."""
    import pyopencl as cl

    machine = pocl_x86(device)
    source = f"__kernel void k(__global int *out, int x)\n{{\n    {FEATURE_BUILTINS[feature]}\n}}\n"
    ctx = cl.Context([device])
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            cl.Program(ctx, source).build()
        builds = True
    except cl.RuntimeError:
        builds = False
    assert builds == (feature in machine.features), machine
    assert machine.target_cpu and machine.target_cpu in device.version
    assert machine.library_vector_bytes == 4 * device.native_vector_width_float


# ----------------------------------------------------------------------------- no wide vector into the library
def crossings(runtime, names, defines, machine=None):
    """The built-in ABI crossings of a program (against ``machine``'s library: the unsafe ones)."""
    return isa.program_crossings(runtime.program(names, defines), runtime.device, machine)


def kernel_builds(device, width):
    """(sources, defines) of what the CPU renders and trace() build, the lanes at ``width``."""
    scene = rt.load_scene(REPO / "scenes" / "mitsuba-cbox.toml")
    wf = Wavefront(scene, device, width=8, height=8, kernel_mode="megakernel")
    base = {k: v for k, v in wf.features.items() if k not in megakernel.lane_features(16)}
    builds = {"one path": (megakernel.SOURCES, base), "trace": (("accel/trace.cl",), {"BVH_WIDE8": True}),
              "trace binary layout": (("accel/trace.cl",), {})}
    if width:
        builds["lanes"] = (megakernel.SOURCES, {**base, **megakernel.lane_features(width)})
        builds["trace packets"] = (("accel/trace.cl",), {"BVH_WIDE8": True, "PACKET_WIDTH": width})
    return builds


def test_no_wide_vector_is_passed_to_a_builtin(device, runtime):
    """clang warns at each call whose vector argument or result the compile passes differently
    than a caller with more features would; at calls into PoCL's built-ins those are the ABI
    crossings.  The kernels a render and trace() build have none, at the width the rule picks and
    at 16 lanes: a library of any width reads what they pass."""
    machine = pocl_x86(device)
    width = isa.simd_width(machine)[0]
    builds = kernel_builds(device, width)
    builds["lanes at 16"] = (megakernel.SOURCES, {**builds["one path"][1], **megakernel.lane_features(16)})
    for name, (names, defines) in builds.items():
        assert crossings(runtime, names, defines) == [], name


def test_the_crossing_check_sees_a_crossing(device, runtime):
    """The control: a float16 and a double4 passed to built-ins (sin, exp) are reported, by the
    feature the compile lacks, and as unsafe only against a library that has it."""
    machine = pocl_x86(device)
    source = textwrap.dedent("""
        __kernel void k(__global float *out, __global double *dout, float x)
        {
            const float16 v = sin((float16)(x));
            out[0] = v.s0;
        #ifdef cl_khr_fp64
            const double4 w = exp((double4)(x));
            dout[0] = w.x;
        #endif
        }""")
    import pyopencl as cl

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        prog = cl.Program(runtime.context, source).build(options=["-DRT_CROSSING_CONTROL"])
    found = {(name, kind) for name, kind, _ in isa.program_crossings(prog, device)}
    expected = set()
    if "avx512f" not in machine.features:
        expected.add(("_cl_sin", "float16"))
    if "avx" not in machine.features and runtime.has_fp64:
        expected.add(("_cl_exp", "double4"))
    assert found == expected
    wide = CpuISA(machine.target_cpu, machine.features, 64)
    assert {(n, k) for n, k, _ in isa.program_crossings(prog, device, wide)} == expected
    same = CpuISA(machine.target_cpu, machine.features, machine.compile_vector_bytes)
    assert isa.program_crossings(prog, device, same) == []


def test_zen4_like_library_gets_no_unsafe_crossing(device, runtime):
    """As on a Zen 4 host: this compile (PoCL names Zen 4 znver3: no AVX-512) against the AVX-512
    library.  The rule's width, and every kernel built at it, passes nothing that library reads
    differently."""
    machine = pocl_x86(device)
    if "avx512f" in machine.features:
        pytest.skip("this compile has AVX-512: no wider library to link against")
    zen4 = CpuISA(machine.target_cpu, machine.features, 64)
    width, reason = isa.simd_width(zen4)
    assert width != 16 and isa.checked_width(zen4, 16)[0] != 16
    for name, (names, defines) in kernel_builds(device, width).items():
        assert crossings(runtime, names, defines, zen4) == [], name


# ----------------------------------------------------------------------------- never abort
def test_a_lane_kernel_that_fails_to_build_falls_back(device, monkeypatch):
    """A lane kernel that does not build (here: a width lanes.h rejects with #error) is one
    warning line, and the render is the one-path render, bit for bit, with the reason recorded."""
    pocl_x86(device)
    scene = rt.load_scene(REPO / "scenes" / "mitsuba-cbox.toml")
    monkeypatch.setenv(megakernel.LANES_ENV, "0")
    reference = rt.render_full(scene, device=device, kernel_mode="megakernel", spp=2, width=16, height=12)
    monkeypatch.setenv(megakernel.LANES_ENV, harness.forced_lanes(device))
    real = megakernel.lane_features
    monkeypatch.setattr(megakernel, "lane_features", lambda w: {**real(w), "PACKET_WIDTH": 12} if w else {})
    with pytest.warns(UserWarning, match="lane kernel failed.*one path per work-item"):
        result = rt.render_full(scene, device=device, kernel_mode="megakernel", spp=2, width=16, height=12)
    assert result.info["lanes"] == 0 and "failed" in result.info["lanes_reason"]
    assert np.array_equal(result.film.sum, reference.film.sum)


BROKEN_CACHE = textwrap.dedent("""
    import sys, warnings
    import numpy as np, pyopencl as cl
    from pyopencl_rt.device.devices import select_device
    from pyopencl_rt.device.kernels import runtime
    rt = runtime(select_device(sys.argv[1]))
    src = "__kernel void twice(__global float *a) { a[get_global_id(0)] *= 2.0f; }"
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        k = rt.new_kernels((), ("twice",), {"RT_CACHE_TEST": 1}, extra=src)["twice"]
    a = np.ones(4, np.float32)
    buf = cl.Buffer(rt.context, cl.mem_flags.READ_WRITE | cl.mem_flags.COPY_HOST_PTR, hostbuf=a)
    k(rt.queue, (4,), None, buf)
    cl.enqueue_copy(rt.queue, a, buf)
    print("values", a.tolist())
    print("rebuilt", any("building it again" in str(w.message) for w in said))
""")


def test_a_broken_kernel_cache_entry_is_rebuilt(device_spec, device, tmp_path):
    """PoCL's cache entry of a program, its program.bc cut in half as a crash while writing it
    leaves it: the next process gets INVALID_KERNEL_NAME from PoCL, rebuilds under another key
    with one warning, computes right, and exits 0 (PoCL 3.0 otherwise aborts at exit: "still
    have references to IRs")."""
    pocl_x86(device)
    env = {**os.environ, "POCL_CACHE_DIR": str(tmp_path / "pocl")}

    def run():
        r = subprocess.run([sys.executable, "-c", BROKEN_CACHE, device_spec], env=env, capture_output=True,
                           text=True, timeout=120, cwd=REPO)
        assert r.returncode == 0, r.stderr[-2000:]
        assert "values [2.0, 2.0, 2.0, 2.0]" in r.stdout
        return "rebuilt True" in r.stdout

    assert not run()  # a fresh cache: built once, no warning
    entries = list((tmp_path / "pocl").rglob("program.bc"))
    assert len(entries) == 1
    data = entries[0].read_bytes()
    entries[0].write_bytes(data[: len(data) // 2])
    for kernel_dir in entries[0].parent.iterdir():
        if kernel_dir.is_dir():
            import shutil

            shutil.rmtree(kernel_dir)
    assert run()  # the broken entry: rebuilt, right values, no abort
