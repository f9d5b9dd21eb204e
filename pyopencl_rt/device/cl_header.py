"""OpenCL C text of the kernel ABI's tables (:mod:`pyopencl_rt.device.abi`): struct typedefs from
numpy structured dtypes, #defines, a parameter-list macro; :func:`cl_header` is the header every
program build starts with (:func:`pyopencl_rt.device.abi.cl_header`)."""
from __future__ import annotations

import numpy as np

from . import sobol

_CL_SCALAR = {
    np.dtype(np.float32): "float",
    np.dtype(np.int32): "int",
    np.dtype(np.uint32): "uint",
}


def cl_struct(name: str, dtype: np.dtype) -> str:
    """Return ``typedef struct {...} name;`` for a structured dtype of 4-byte fields."""
    lines = []
    for field in dtype.names:
        ftype, offset = dtype.fields[field][:2]
        base, shape = (ftype.subdtype if ftype.subdtype else (ftype, ()))
        if base not in _CL_SCALAR:
            raise TypeError(f"{name}.{field}: unsupported base type {base}")
        count = int(np.prod(shape)) if shape else 0
        suffix = f"[{count}]" if count else ""
        lines.append(f"    {_CL_SCALAR[base]} {field}{suffix};  /* offset {offset} */")
    body = "\n".join(lines)
    return f"typedef struct {{\n{body}\n}} {name};  /* {dtype.itemsize} bytes */\n"


def cl_literal(value) -> str:
    if isinstance(value, float):
        return f"{value!r}f"
    return f"({value})" if value < 0 else str(value)


def cl_defines(defines: dict, overridable=frozenset()) -> str:
    lines = []
    for name, value in defines.items():
        line = f"#define {name} {cl_literal(value)}"
        lines.append(f"#ifndef {name}\n{line}\n#endif" if name in overridable else line)
    return "\n".join(lines) + "\n"


def cl_params(macro: str, params) -> str:
    """``#define macro`` the parameter list, one parameter a line with its doc."""
    lines = [f"    {_declaration(p)}{',' if i < len(params) - 1 else ''}" + (f" /* {p.doc} */" if p.doc else "")
             for i, p in enumerate(params)]
    width = max(map(len, lines))
    return f"#define {macro} \\\n" + " \\\n".join(line.ljust(width) for line in lines[:-1]) + f" \\\n{lines[-1]}\n"


def _declaration(p) -> str:
    """A parameter as the kernels' signature declares it."""
    if p.kind == "scalar":
        return f"const {p.ctype} {p.name}"
    return f"__global {'const ' if p.kind == 'const' else ''}{p.ctype} *{p.name}"


# The material types without a BSDF of their own: cl/render/path.h resolves a mix to one of the
# records it blends before the BSDF dispatch (cl/materials/dispatch.h).
RESOLVED_MATERIALS = ("mix",)
# The type every kernel compiles (the fallback of a type not compiled in): no HAS_MATERIAL_ switch.
ALWAYS_COMPILED_MATERIAL = "diffuse"


def bsdf_types(material_types) -> list[str]:
    """The names of the types cl/materials/dispatch.h routes to, in the enum's order."""
    return [name for name in material_types if name not in RESOLVED_MATERIALS]


def bsdf_includes(material_types) -> str:
    """The generated header "materials/bsdfs.h": each BSDF type's cl/materials/<name>.h."""
    includes = "".join(f'#include "materials/{name}.h"\n' for name in bsdf_types(material_types))
    return f"#ifndef PYOPENCL_RT_BSDFS_H\n#define PYOPENCL_RT_BSDFS_H\n{includes}#endif\n"


def light_units(light_types, delta_kinds) -> str:
    """The generated header "lights/units.h": each light type's cl/lights/<name>.h (every type but the
    surfaces', which cl/render/lights.h samples), an empty LIGHT_CASE_<NAME>(X) where its header did
    not define one (its type not compiled in), LIGHT_DELTA_<NAME> (1 for a delta light, ``delta_kinds``:
    ls->delta is set for its lanes) and LIGHT_CASES(X), their cases in the enum's order."""
    units = [name for name in light_types if name not in SURFACE_LIGHTS]
    parts = [f'#include "lights/{n}.h"\n#ifndef LIGHT_CASE_{n.upper()}\n#define LIGHT_CASE_{n.upper()}(X)\n#endif\n'
             f"#define LIGHT_DELTA_{n.upper()} {int(light_types[n] in delta_kinds)}\n" for n in units]
    cases = " ".join(f"LIGHT_CASE_{name.upper()}(X)" for name in units)
    return (f"#ifndef PYOPENCL_RT_LIGHT_UNITS_H\n#define PYOPENCL_RT_LIGHT_UNITS_H\n{''.join(parts)}"
            f"#define LIGHT_CASES(X) {cases}\n#endif\n")


SURFACE_LIGHTS = ("triangle", "shape")  # the emissive surfaces, sampled by cl/render/lights.h itself


def shape_units(shape_types) -> str:
    """The generated header "shapes/units.h": each analytic shape type's cl/shapes/<name>.h, empty
    SHAPE_CASE_<NAME>(X) and SHAPE_PDF_CASE_<NAME>(X) where its header did not define them (its type
    not compiled in, or sampled by the area density), and SHAPE_CASES(X) / SHAPE_PDF_CASES(X), their
    cases in the enum's order (cl/scene/shapes.h dispatches through them)."""
    parts, cases, pdf_cases = [], [], []
    for name in shape_types:
        n = name.upper()
        parts.append(f'#include "shapes/{name}.h"\n'
                     + "".join(f"#ifndef SHAPE_{k}CASE_{n}\n#define SHAPE_{k}CASE_{n}(X)\n#endif\n" for k in ("", "PDF_")))
        cases.append(f"SHAPE_CASE_{n}(X)")
        pdf_cases.append(f"SHAPE_PDF_CASE_{n}(X)")
    return (f"#ifndef PYOPENCL_RT_SHAPE_UNITS_H\n#define PYOPENCL_RT_SHAPE_UNITS_H\n{''.join(parts)}"
            f"#define SHAPE_CASES(X) {' '.join(cases)}\n#define SHAPE_PDF_CASES(X) {' '.join(pdf_cases)}\n#endif\n")


def material_cases(material_types) -> str:
    """MATERIAL_CASES(X), every BSDF type's case (cl/materials/dispatch.h), and the switch of every
    type but the one always compiled, all on where a scene does not select them (MATERIALS_SELECTED)."""
    cases = " ".join(f"MATERIAL_CASE_{name.upper()}(X)" for name in bsdf_types(material_types))
    switches = "".join(f"#define HAS_MATERIAL_{name.upper()}\n" for name in material_types
                       if name != ALWAYS_COMPILED_MATERIAL)
    return f"#define MATERIAL_CASES(X) {cases}\n#ifndef MATERIALS_SELECTED\n{switches}#endif\n"


def cl_header(structs: dict, defines: dict, overridable, wave_params, material_types) -> str:
    """The header of :mod:`.abi`'s tables: struct typedefs, #defines, the material types' cases and
    switches, the WAVE_PARAMS macro and the Sobol matrices."""
    return "\n".join([
        "/* generated from pyopencl_rt/device/abi.py: do not edit */",
        *(cl_struct(name, dt) for name, dt in structs.items()),
        cl_defines(defines, overridable),
        material_cases(material_types),
        cl_params("WAVE_PARAMS", wave_params),
        sobol.cl_table(),
    ])
