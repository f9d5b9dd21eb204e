"""The kernel ABI (pyopencl_rt/device/abi.py) as each device compiles it.

On every device: the size, field offsets, field sizes and field types of every shared struct,
the value of every generated #define (as the kernel headers leave it), and the parameter list of
every wavefront kernel (names, order, types, address space, const) equal the Python tables.

Both checks go through one checker each (``layout_mismatches``, ``signature_mismatches``); the
mutation tests edit one side by hand (the header text the device compiles, or a table entry) and
require the checker to report exactly that difference.
"""
import re
from pathlib import Path

import numpy as np
import pyopencl as cl
import pytest

from pyopencl_rt.device import abi
from pyopencl_rt.device.kernel_args import KernelArgs
from pyopencl_rt.device.kernels import assemble, cl_dir
from pyopencl_rt.render.wavefront import STAGES
from pyopencl_rt.render.wavefront import SOURCES

# The headers the kernels include: a hand-written copy of a generated define in one of them
# (redefining it) shows up in the probe.
KERNEL_HEADERS = ('#include "render/lights.h"\n#include "scene/textures.h"\n#include "accel/bvh_wide.h"\n'
                  '#include "accel/bvh_wide8.h"\n')
FLOAT_BITS = int(np.float32(1.5).view(np.int32))  # a float field stores 1.5 as these bits, an int one as 1


# ----------------------------------------------------------------------------- layout probe
def expected_layout(structs=None, defines=None) -> dict:
    """What the tables declare: key -> value (keys name what the probe measures)."""
    structs = abi.STRUCTS if structs is None else structs
    defines = abi.DEFINES if defines is None else defines
    out = {}
    for name, dt in structs.items():
        out[f"sizeof({name})"] = dt.itemsize
        for field in dt.names:
            ftype, offset = dt.fields[field][:2]
            base = ftype.subdtype[0] if ftype.subdtype else ftype
            out[f"offsetof({name}.{field})"] = offset
            out[f"sizeof({name}.{field})"] = ftype.itemsize
            out[f"type({name}.{field})"] = "float" if base.kind == "f" else "int"
    out.update(defines)
    return out


def _probe_source(keys) -> tuple[str, list, list]:
    """A kernel that writes the device's value of every key (ints, then floats)."""
    ints, floats, body = [], [], []
    structs = sorted({k[k.index("(") + 1:].split(".")[0].rstrip(")") for k in keys if "(" in k})
    body += [f"    {s} probe_{s};" for s in structs] + ["    const float one_and_a_half = 1.5f;"]
    for key in keys:
        m = re.fullmatch(r"(sizeof|offsetof|type)\((\w+)(?:\.(\w+))?\)", key)
        if m is None:  # a define
            if isinstance(abi.DEFINES.get(key), float):
                body.append(f"    floats[{len(floats)}] = {key};")
                floats.append(key)
                continue
            expr = f"(int)({key})"
        else:
            what, s, f = m.groups()
            var = f"probe_{s}"
            member = f"{var}.{f}" if f else var
            if what == "sizeof":
                expr = f"(int)sizeof({member})"
            elif what == "offsetof":
                expr = f"(int)((char *)&{member} - (char *)&{var})"
            else:  # store 1.5 into the field's first element (converted to its type), read the bits
                element = member + ("[0]" if abi.STRUCTS[s].fields[f][0].subdtype else "")
                body.append(f"    {element} = one_and_a_half;")
                expr = f"as_int({element})"
        body.append(f"    ints[{len(ints)}] = {expr};")
        ints.append(key)
    src = KERNEL_HEADERS + "__kernel void abi_probe(__global int *ints, __global float *floats)\n{\n"
    return src + "\n".join(body) + "\n}\n", ints, floats


def measure_layout(runtime, keys, extra: str = "") -> dict:
    """The device's value of every key, compiled with the current abi.cl_header() (through
    assemble) and the kernel headers; ``extra`` source goes between the headers and the probe."""
    src, ints, floats = _probe_source(list(keys))
    src = src.replace("__kernel", extra + "\n__kernel", 1)
    prog = cl.Program(runtime.context, assemble(extra=src)).build()
    out_i = np.zeros(max(1, len(ints)), np.int32)
    out_f = np.zeros(max(1, len(floats)), np.float32)
    bi = cl.Buffer(runtime.context, cl.mem_flags.WRITE_ONLY, out_i.nbytes)
    bf = cl.Buffer(runtime.context, cl.mem_flags.WRITE_ONLY, out_f.nbytes)
    prog.abi_probe(runtime.queue, (1,), None, bi, bf)
    cl.enqueue_copy(runtime.queue, out_i, bi)
    cl.enqueue_copy(runtime.queue, out_f, bf)
    measured = dict(zip(floats, out_f.tolist()))
    for key, v in zip(ints, out_i.tolist()):
        if key.startswith("type("):
            v = {FLOAT_BITS: "float", 1: "int"}.get(v, f"bits {v:#x}")
        measured[key] = v
    return measured


def layout_mismatches(measured: dict, expected: dict) -> list[str]:
    """Every key whose device value differs from the table's (floats compared in float32)."""
    out = []
    for key in sorted(expected.keys() | measured.keys()):
        if key not in measured or key not in expected:
            out.append(f"{key}: only {'in the table' if key in expected else 'on the device'}")
            continue
        m, e = measured[key], expected[key]
        same = np.float32(m) == np.float32(e) if isinstance(e, float) else m == e
        if not same:
            out.append(f"{key}: device {m}, table {e}")
    return out


# ----------------------------------------------------------------------------- signatures
_ADDRESS = {cl.kernel_arg_address_qualifier.GLOBAL: "global", cl.kernel_arg_address_qualifier.PRIVATE: "private",
            cl.kernel_arg_address_qualifier.CONSTANT: "constant", cl.kernel_arg_address_qualifier.LOCAL: "local"}


def with_arg_info(context, source):
    """``source`` built from source with -cl-kernel-arg-info: not through pyopencl's binary cache,
    which serves the implementations without a cache of their own (Intel's CPU runtime) a program
    made from a binary, and such a program has no argument information.  Unoptimised: the
    signatures do not depend on it, and the whole wavefront took 14-19 s to build optimised with
    Intel's runtime."""
    return cl.Program(cl._cl._Program(context, source)).build(options=["-cl-kernel-arg-info", "-cl-opt-disable"])


def kernel_signature(kernel) -> list[tuple]:
    """(name, type, address space, const pointee) of each argument (needs -cl-kernel-arg-info)."""
    info = cl.kernel_arg_info
    sig = []
    for i in range(kernel.num_args):
        type_name = re.sub(r"\s+|\bstruct\b", "", kernel.get_arg_info(i, info.TYPE_NAME))
        address = _ADDRESS.get(kernel.get_arg_info(i, info.ADDRESS_QUALIFIER), "?")
        const = bool(kernel.get_arg_info(i, info.TYPE_QUALIFIER) & cl.kernel_arg_type_qualifier.CONST)
        sig.append((kernel.get_arg_info(i, info.NAME), type_name, address, const and address != "private"))
    return sig


def expected_signature(params) -> list[tuple]:
    return [(p.name, p.ctype if p.kind == "scalar" else p.ctype + "*",
             "private" if p.kind == "scalar" else "global", p.kind == "const") for p in params]


def signature_mismatches(measured: list, expected: list) -> list[str]:
    out = [f"argument {i}: device {m}, table {e}" for i, (m, e) in enumerate(zip(measured, expected)) if m != e]
    if len(measured) != len(expected):
        out.append(f"{len(measured)} arguments on the device, {len(expected)} in the table")
    return out


def probe_signature(runtime) -> list[tuple]:
    """The signature of a kernel declared with the generated WAVE_PARAMS (quick to build)."""
    src = assemble(extra="__kernel void wave_probe(WAVE_PARAMS) {}\n")
    return kernel_signature(with_arg_info(runtime.context, src).wave_probe)


# ----------------------------------------------------------------------------- the checks
def test_layout_and_defines_match_tables(runtime):
    expected = expected_layout()
    assert layout_mismatches(measure_layout(runtime, expected), expected) == []


def test_wavefront_kernels_take_the_table(runtime):
    """Every stage, built as the renderer builds it, takes exactly abi.WAVE_PARAMS, in order."""
    prog = with_arg_info(runtime.context, assemble(*SOURCES))
    expected = expected_signature(abi.WAVE_PARAMS)
    for stage in STAGES:
        assert signature_mismatches(kernel_signature(getattr(prog, f"wf_{stage}")), expected) == [], stage


def test_python_constants_are_the_defines():
    # named by the enums (below), not each a constant
    types = {f"MATERIAL_{k.upper()}" for k in abi.MATERIAL_TYPES} | {f"SHAPE_{k.upper()}" for k in abi.SHAPE_TYPES}
    for name, value in abi.DEFINES.items():
        assert name in types and not hasattr(abi, name) or getattr(abi, name) == value, name
    assert all(abi.DEFINES[f"COUNTER_{k.upper()}"] == v for k, v in abi.COUNTERS.items())
    assert all(abi.DEFINES[f"MATERIAL_{k.upper()}"] == v for k, v in abi.MATERIAL_TYPES.items())
    assert all(abi.DEFINES[f"SHAPE_{k.upper()}"] == v for k, v in abi.SHAPE_TYPES.items())


def test_no_hand_written_copies_in_kernel_sources():
    """The kernel sources never #define what the header generates."""
    generated = set(abi.DEFINES) | {"WAVE_PARAMS"} | set(abi.STRUCTS)
    found = []
    for path in sorted(Path(cl_dir()).rglob("*")):
        if path.suffix in (".h", ".cl"):
            for name in re.findall(r"^\s*#\s*define\s+(\w+)", path.read_text(), re.M):
                if name in generated:
                    found.append(f"{path.name}: {name}")
            for name in re.findall(r"}\s*(\w+)\s*;", path.read_text()):  # typedef struct {...} Name;
                if name in abi.STRUCTS:
                    found.append(f"{path.name}: struct {name}")
    assert found == []


# ----------------------------------------------------------------------------- the checkers catch drift
def test_layout_checker_reports_an_edited_header(runtime, monkeypatch):
    """One hand edit per kind in the header the device compiles: a define's value, a field's
    type, an array's length (which moves every later field); and a stale copy of a define
    in a kernel header."""
    expected = expected_layout()
    header = abi.cl_header()
    edited = header.replace("#define COUNTER_SHADOW 1\n", "#define COUNTER_SHADOW 2\n", 1)
    edited = edited.replace("    float alpha;", "    int alpha;", 1)
    edited = edited.replace("    int count[4];", "    int count[5];", 1)
    assert edited.count("\n") == header.count("\n") and edited != header
    monkeypatch.setattr(abi, "cl_header", lambda: edited)
    found = layout_mismatches(measure_layout(runtime, expected), expected)
    assert found == ["COUNTER_SHADOW: device 2, table 1",
                     "sizeof(WideNode): device 132, table 128",
                     "sizeof(WideNode.count): device 20, table 16",
                     "type(Material.alpha): device int, table float"]
    monkeypatch.undo()

    stale = "#undef TRI4_UNITS\n#define TRI4_UNITS 12 /* a hand-kept copy */\n"
    found = layout_mismatches(measure_layout(runtime, expected, extra=stale), expected)
    assert found == ["TRI4_UNITS: device 12, table 10"]


def test_layout_checker_reports_an_edited_table(runtime, monkeypatch):
    """The table changed by hand while the device still compiles the old header."""
    measured = measure_layout(runtime, expected_layout())
    monkeypatch.setitem(abi.DEFINES, "LIGHT_POINT", 7)
    light = [(n, abi.LIGHT.fields[n][0]) for n in abi.LIGHT.names]
    light[2], light[3] = light[3], light[2]  # pmf <-> alias_prob: same types, swapped offsets
    monkeypatch.setitem(abi.STRUCTS, "Light", np.dtype(light))
    assert layout_mismatches(measured, expected_layout()) == [
        "LIGHT_POINT: device 2, table 7",
        "offsetof(Light.alias_prob): device 12, table 8",
        "offsetof(Light.pmf): device 8, table 12",
    ]


def test_signature_checker_reports_edits(runtime, monkeypatch):
    expected = expected_signature(abi.WAVE_PARAMS)
    assert signature_mismatches(probe_signature(runtime), expected) == []
    # table side: two path-state arrays swapped, one read-only buffer made writable
    params = list(abi.WAVE_PARAMS)
    index = {p.name: i for i, p in enumerate(params)}
    o, d, m = index["ray_o"], index["ray_d"], index["materials"]
    params[o], params[d] = params[d], params[o]
    params[m] = abi.Param("materials", "global", "Material", source="scene")
    found = signature_mismatches(probe_signature(runtime), expected_signature(params))
    edited = [f"argument {i}" for i in sorted((o, d, m))]
    assert [f.split(":")[0] for f in found] == edited
    # device side: the header generated from an edited table, checked against the real one
    monkeypatch.setattr(abi, "WAVE_PARAMS", tuple(params[:-1]))
    found = signature_mismatches(probe_signature(runtime), expected)
    assert [f.split(":")[0] for f in found] == edited + [
        f"{len(expected) - 1} arguments on the device, {len(expected)} in the table"]


# ----------------------------------------------------------------------------- binding by name
class _FakeKernel:
    def __init__(self):
        self.args = {}

    def set_arg(self, i, value):
        self.args[i] = value


def test_kernel_args_bind_by_table_position():
    kernels = {"a": _FakeKernel(), "b": _FakeKernel()}
    args = KernelArgs(kernels)
    index = {p.name: i for i, p in enumerate(abi.WAVE_PARAMS)}
    args.bind(ray_d="buffer", seed=2**32 - 1)
    for k in kernels.values():
        assert k.args == {index["ray_d"]: "buffer", index["seed"]: np.uint32(2**32 - 1)}
        assert type(k.args[index["seed"]]) is np.uint32
    args.set("b", first_pixel=5)
    assert kernels["b"].args[index["first_pixel"]] == 5 and type(kernels["b"].args[index["first_pixel"]]) is np.int32
    assert index["first_pixel"] not in kernels["a"].args
    assert args["ray_d"] == "buffer" and "ray_o" in args.unbound() and "ray_d" not in args.unbound()
    with pytest.raises(KeyError, match="not a kernel parameter"):
        args.bind(a0=1)
