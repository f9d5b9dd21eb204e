"""Kernel sources compile in any include order (issue 36): every header has its include guard, the
host's assembly (pyopencl_rt/device/kernels.py:assemble) follows the preprocessor, so a header whose
first #include sits in an #if that is false is still there for a later include, and (the long
variant, `make stress`) every header compiles on its own: it includes what it uses."""
import re
import subprocess

import pytest

from pyopencl_rt.device.kernels import assemble, cl_dir

ROOT = cl_dir()
HEADERS = sorted(str(p.relative_to(ROOT)) for p in ROOT.rglob("*.h") if not p.name.endswith(".tpl.h"))


def _guard(path: str) -> str:
    return "PYOPENCL_RT_" + re.sub(r"\W", "_", path.rsplit("/", 1)[-1]).upper()


@pytest.mark.parametrize("header", HEADERS)
def test_every_header_has_its_include_guard(header):
    """The first directive of a header is its guard (what lets assembly expand it at every include)."""
    text = (ROOT / header).read_text()
    directives = re.findall(r"^\s*#\s*(\w+)[ \t]*(\w*)", text, re.M)
    assert directives[:2] == [("ifndef", _guard(header)), ("define", _guard(header))], header
    assert directives[-1][0] == "endif", header


def _preprocessed(source: str, *defines: str) -> str:
    """``source`` through a C preprocessor (gcc's cpp; the kernels' OpenCL preprocessor is C99's)."""
    out = subprocess.run(["cpp", "-P", "-w", "-undef", *[f"-D{d}" for d in defines]], input=source,
                         capture_output=True, text=True, check=True)
    return out.stdout


def test_a_header_first_included_in_a_false_if_is_still_there_later():
    """sampler.h's SampleKey exists after ``#if 0 / #include / #endif / #include`` (the old assembly
    kept only the first include, so the second one was empty), once only, and not at all when the
    only include is the false one."""
    text = assemble(extra='#if 0\n#include "render/sampler.h"\n#endif\n#include "render/sampler.h"\n')
    typedefs = re.findall(r"}\s*SampleKey;", _preprocessed(text))
    assert len(typedefs) == 1
    text = assemble(extra='#ifdef NOT_DEFINED\n#include "render/sampler.h"\n#endif\n')
    assert not re.findall(r"}\s*SampleKey;", _preprocessed(text))
    assert re.findall(r"}\s*SampleKey;", _preprocessed(text, "NOT_DEFINED"))


def test_assembly_expands_an_unconditional_header_once():
    """After an include outside every #if, later includes add no text (the guard would drop it)."""
    once = assemble(extra='#include "render/rng.h"\n')
    twice = assemble(extra='#include "render/rng.h"\n#include "render/rng.h"\n')
    assert len(twice) == len(once) + 1


@pytest.mark.stress
@pytest.mark.parametrize("header", HEADERS)
def test_every_header_compiles_on_its_own(header, device):
    """A program of the header alone builds (with its feature off where it needs one: the packet
    traversal at one lane, the volumetric integrator without media, compile to nothing)."""
    import pyopencl as cl

    from pyopencl_rt.device.kernels import runtime

    rt = runtime(device)
    cl.Program(rt.context, assemble(extra=f'#include "{header}"\n')).build()
