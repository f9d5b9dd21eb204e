"""The material registry (pyopencl_rt/scene/materials/): one Python module per type, paired by
name with the kernel's type enum and with the BSDF header that implements it, and each type's
TOML keys landing in the MATERIAL record fields its documentation names.  Host-only."""
import importlib
import pkgutil
import re
from pathlib import Path

import numpy as np
import pytest

from pyopencl_rt import load_scene
from pyopencl_rt.device import abi
from pyopencl_rt.scene import materials
from pyopencl_rt.scene.loaders.toml import MATERIAL_COMMON_KEYS
from pyopencl_rt.scene.materials import REGISTRY
from pyopencl_rt.scene.materials.conductor import METALS
from pyopencl_rt.scene.materials.plastic import fresnel_diffuse_reflectance
from pyopencl_rt.scene.materials.principled import eta_from_specular
from pyopencl_rt.scene.materials.roughplastic import rough_tables
from pyopencl_rt.scene.model import Material

REPO = Path(__file__).resolve().parents[2]
CL_MATERIALS = REPO / "cl" / "materials"


def bsdf_headers() -> set:
    """The headers of cl/materials/ that implement a BSDF: ``<name>.h`` defines both
    ``<name>_eval(`` and ``<name>_sample(`` (helpers such as microfacet.h define neither)."""
    names = set()
    for header in CL_MATERIALS.glob("*.h"):
        text = header.read_text()
        if all(re.search(rf"\b{header.stem}_{fn}\s*\(", text) for fn in ("eval", "sample")):
            names.add(header.stem)
    return names


def type_modules() -> set:
    """The modules of the materials package that define a type (those with a ``pack``)."""
    return {info.name for info in pkgutil.iter_modules(materials.__path__)
            if hasattr(importlib.import_module(f"{materials.__name__}.{info.name}"), "pack")}


def test_registry_enum_headers_and_modules_agree():
    assert set(REGISTRY) == set(abi.MATERIAL_TYPES) == bsdf_headers() == type_modules()
    assert {name: t.type_id for name, t in REGISTRY.items()} == abi.MATERIAL_TYPES


def test_kernel_defines_exist_in_the_kernels():
    """Each type's define gates its code: an #ifdef, or its row in cl/materials/dispatch.h's cases,
    MATERIAL_CASE_<NAME>(X) of its own header, compiled under RT_WHEN(HAS_MATERIAL_<row>)."""
    sources = "\n".join(p.read_text() for p in (REPO / "cl").rglob("*.[hc]*"))
    dispatch = (CL_MATERIALS / "dispatch.h").read_text()
    assert "RT_WHEN(HAS_MATERIAL_##T)" in dispatch
    for name, material_type in REGISTRY.items():
        if material_type.kernel_define is not None:
            assert material_type.kernel_define == f"HAS_MATERIAL_{name.upper()}"
            row = re.search(rf"#define MATERIAL_CASE_{name.upper()}\(X\)\s*\\?\s*X\({name.upper()},",
                            (CL_MATERIALS / f"{name}.h").read_text())
            assert f"#ifdef {material_type.kernel_define}" in sources or row, name


def test_generated_cases_and_switches_are_the_registry():
    """The generated header's MATERIAL_CASES names one case per BSDF type, in the enum's order, each
    defined by the type's own header (as X(NAME, name, ...), or empty for diffuse, shaded before the
    frame), "materials/bsdfs.h" includes those headers, and the switches on by default are the
    registry's kernel defines: adding a type needs no edit of dispatch.h."""
    from pyopencl_rt.device import cl_header, kernels

    header = abi.cl_header()
    cases = re.search(r"#define MATERIAL_CASES\(X\) (.*)", header).group(1).split()
    bsdfs = [name for name in abi.MATERIAL_TYPES if name not in cl_header.RESOLVED_MATERIALS]
    assert cases == [f"MATERIAL_CASE_{name.upper()}(X)" for name in bsdfs]
    for name in bsdfs:
        text = (CL_MATERIALS / f"{name}.h").read_text()
        case = re.search(rf"#define MATERIAL_CASE_{name.upper()}\(X\)(.*)", text)
        assert case, f"cl/materials/{name}.h defines no MATERIAL_CASE_{name.upper()}(X)"
        assert REGISTRY[name].kernel_define is None or re.search(rf"X\({name.upper()}, {name},", text), name
    switches = set(re.findall(r"#define (HAS_MATERIAL_\w+)", header))
    assert switches == {t.kernel_define for t in REGISTRY.values() if t.kernel_define is not None}
    generated = kernels._generated_headers()["materials/bsdfs.h"]
    assert re.findall(r'#include "materials/(\w+)\.h"', generated) == bsdfs


def test_mtl_precedences_are_distinct():
    precedences = [t.mtl_precedence for t in REGISTRY.values() if t.from_mtl is not None]
    assert len(set(precedences)) == len(precedences)


def test_scene_format_includes_every_type_documentation():
    assert materials.documentation() in (REPO / "docs" / "SCENE_FORMAT.md").read_text(), (
        "docs/SCENE_FORMAT.md must include the types' docstrings verbatim: paste the output of\n"
        "python -c 'from pyopencl_rt.scene.materials import documentation; print(documentation())'")


# ---------------------------------------------------------------------------------------------
# TOML keys -> record fields.  Expected fields are written out from the documentation (the type
# modules' docstrings and the MATERIAL comments in device/abi.py); every field not listed must be
# 0 (the texture indices -1).

GOLD_ETA = (0.183, 0.421, 1.373)  # cl/materials/conductor.h's example, 3 decimals
GOLD_K = (3.424, 2.346, 1.770)
F0_FLAG = abi.MATERIAL_FLAG_CONDUCTOR_F0

NONLINEAR, BECKMANN = abi.MATERIAL_FLAG_NONLINEAR, abi.MATERIAL_FLAG_BECKMANN
PP_ETA = 1.49 / 1.000277  # Mitsuba's polypropylene in air
T_LUM = 0.212671 + 0.715160 * ((128 / 255 + 0.055) / 1.055) ** 2.4  # the luminance of t.png, (255, 128, 0)
fdr = fresnel_diffuse_reflectance


def rough(distribution, alpha, eta):
    """roughplastic's table and internal reflectance (fdr) for these parameters"""
    table, internal = rough_tables(distribution, alpha, eta)
    return {"table": table, "fdr": internal}


def coated(metal, ior, layer):
    """coatedconductor's metal (eta, k in air) under a coating of index ior, and its layer's block"""
    eta, k = (tuple(float(x) / ior for x in v) for v in metal)
    return {"eta": eta, "k": k, "table": block(*layer)}


def block(*values):
    """A type's own block in ``table`` (coatedconductor's layer, a mix's weight and blended records)"""
    return tuple(values) + (0,) * (abi.ROUGH_TRANSMITTANCE_RES - len(values))


def texp(*names):
    """tex_params naming these fields in slots 0, 1, ..."""
    ids = {name: k for k, name in abi.TEXTURE_PARAMS.items()}
    return sum(ids[name] << (4 * slot) for slot, name in enumerate(names))


CASES = [  # (type, TOML keys, expected record fields)
    ("diffuse", {}, {"albedo": (0.8, 0.8, 0.8)}),
    ("diffuse", {"albedo": [0.25, 0.5, 0.75], "albedo_texture": "t.png"},
     {"albedo": (0.25, 0.5, 0.75), "tex_base": 0}),
    ("conductor", {}, {"specular": (1, 1, 1), "flags": F0_FLAG}),
    ("conductor", {"f0": [0.5, 0.25, 1.0], "roughness": 0.5},
     {"specular": (0.5, 0.25, 1.0), "flags": F0_FLAG, "alpha": 0.25}),
    ("conductor", {"metal": "gold", "alpha": 0.125}, {"eta": GOLD_ETA, "k": GOLD_K, "alpha": 0.125}),
    ("conductor", {"eta": [1.5, 1.25, 1.0], "k": 2}, {"eta": (1.5, 1.25, 1.0), "k": (2, 2, 2)}),
    ("conductor", {"alpha_u": 0.25, "alpha_v": 0.5, "distribution": "beckmann", "masking": "separable"},
     {"specular": (1, 1, 1), "alpha": 0.25, "alpha_v": 0.5,
      "flags": F0_FLAG | abi.MATERIAL_FLAG_ANISOTROPIC | abi.MATERIAL_FLAG_BECKMANN | abi.MATERIAL_FLAG_SEPARABLE}),
    ("dielectric", {}, {"ior": 1.5, "specular": (1, 1, 1)}),
    ("dielectric", {"ior": 1.25, "roughness": 0.5, "tint": [0.5, 0.75, 1.0]},
     {"ior": 1.25, "alpha": 0.25, "specular": (0.5, 0.75, 1.0)}),
    ("dielectric", {"alpha": 0.5}, {"ior": 1.5, "alpha": 0.5, "specular": (1, 1, 1)}),
    ("dielectric", {"alpha_u": 0.5, "alpha_v": 0.125, "distribution": "ggx", "masking": "correlated"},
     {"ior": 1.5, "alpha": 0.5, "alpha_v": 0.125, "specular": (1, 1, 1), "flags": abi.MATERIAL_FLAG_ANISOTROPIC}),
    ("gltf", {}, {"albedo": (1, 1, 1), "metallic": 1, "alpha": 1, "ior": 1.5}),
    ("gltf", {"base_color": [0.5, 0.25, 0.125], "metallic": 0.5, "roughness": 0.5, "ior": 1.25,
              "base_color_texture": "t.png", "metallic_roughness_texture": "t.png"},
     {"albedo": (0.5, 0.25, 0.125), "metallic": 0.5, "alpha": 0.25, "ior": 1.25, "tex_base": 0, "tex_mr": 1}),
    ("gltf", {"alpha": 0.5}, {"albedo": (1, 1, 1), "metallic": 1, "alpha": 0.5, "ior": 1.5}),
    ("plastic", {}, {"albedo": (0.5, 0.5, 0.5), "specular": (1, 1, 1), "ior": PP_ETA, "fdr": fdr(1 / PP_ETA),
                     "spec_weight": 1 / 1.5}),
    ("plastic", {"diffuse_reflectance": [0.25, 0.5, 0.75], "diffuse_reflectance_texture": "t.png",
                 "specular_reflectance": 0.5, "int_ior": 1.5, "ext_ior": 1.25, "nonlinear": True},
     {"albedo": (0.25, 0.5, 0.75), "tex_base": 0, "specular": (0.5, 0.5, 0.5), "ior": 1.2, "fdr": fdr(1 / 1.2),
      "spec_weight": 0.5 / (0.5 * T_LUM + 0.5), "flags": NONLINEAR}),
    ("roughplastic", {}, {"albedo": (0.5, 0.5, 0.5), "specular": (1, 1, 1), "ior": PP_ETA, "alpha": 0.1,
                          "flags": BECKMANN, "spec_weight": 1 / 1.5, **rough("beckmann", 0.1, PP_ETA)}),
    ("roughplastic", {"distribution": "ggx", "alpha": 0.25, "diffuse_reflectance": 0.2, "specular_reflectance": 0.8,
                      "diffuse_reflectance_texture": "t.png", "int_ior": 1.5, "ext_ior": 1.0, "nonlinear": True},
     {"albedo": (0.2, 0.2, 0.2), "tex_base": 0, "specular": (0.8, 0.8, 0.8), "ior": 1.5, "alpha": 0.25,
      "flags": NONLINEAR, "spec_weight": 0.8 / (0.2 * T_LUM + 0.8), **rough("ggx", 0.25, 1.5)}),
    ("principled", {}, {"albedo": (0.5, 0.5, 0.5), "roughness": 0.5, "ior": 1.5, "rates": (1, 1, 1, 0)}),
    ("principled", {"base_color": [0.25, 0.5, 0.75], "roughness": 0.25, "metallic": 0.5, "anisotropic": 0.125,
                    "spec_trans": 0.25, "spec_tint": 0.375, "sheen": 0.5, "sheen_tint": 0.625, "clearcoat": 0.75,
                    "clearcoat_gloss": 0.875, "flatness": 1.0, "eta": 1.25, "main_specular_sampling_rate": 2.0,
                    "clearcoat_sampling_rate": 3.0, "diffuse_reflectance_sampling_rate": 4.0,
                    "base_color_texture": "t.png", "roughness_texture": "t.png", "metallic_texture": "t.png",
                    "anisotropic_texture": "t.png", "spec_trans_texture": "t.png", "spec_tint_texture": "t.png"},
     {"albedo": (0.25, 0.5, 0.75), "roughness": 0.25, "metallic": 0.5, "anisotropic": 0.125, "spec_trans": 0.25,
      "spec_tint": 0.375, "sheen": 0.5, "sheen_tint": 0.625, "clearcoat": 0.75, "clearcoat_gloss": 0.875,
      "flatness": 1.0, "ior": 1.25, "rates": (2, 3, 4, 0), "tex_base": 0, "tex_scalar": (1, 2, 3, 4, 5, -1),
      "tex_params": texp("roughness", "metallic", "anisotropic", "spec_trans", "spec_tint"),
      "flags": abi.MATERIAL_FLAG_ANISOTROPIC}),
    ("principled", {"specular": 0.25, "sheen_texture": "t.png", "sheen_tint_texture": "t.png",
                    "clearcoat_texture": "t.png", "clearcoat_gloss_texture": "t.png", "flatness_texture": "t.png"},
     {"albedo": (0.5, 0.5, 0.5), "roughness": 0.5, "ior": eta_from_specular(0.25), "rates": (1, 1, 1, 0),
      "tex_scalar": (0, 1, 2, 3, 4, -1), "tex_params": texp("sheen", "sheen_tint", "clearcoat", "clearcoat_gloss",
                                                           "flatness")}),
    ("principledthin", {}, {"albedo": (0.5, 0.5, 0.5), "roughness": 0.5, "ior": 1.5, "rates": (1, 1, 1, 1)}),
    ("principledthin", {"base_color": 0.25, "roughness": 0.25, "anisotropic": 0.125, "spec_trans": 0.25,
                        "spec_tint": 0.375, "sheen": 0.5, "sheen_tint": 0.625, "flatness": 0.75, "diff_trans": 1.5,
                        "eta": 1.25, "specular_reflectance_sampling_rate": 2.0,
                        "specular_transmittance_sampling_rate": 3.0, "diffuse_transmittance_sampling_rate": 4.0,
                        "diffuse_reflectance_sampling_rate": 5.0, "base_color_texture": "t.png",
                        "roughness_texture": "t.png", "anisotropic_texture": "t.png", "spec_trans_texture": "t.png",
                        "diff_trans_texture": "t.png", "eta_texture": "t.png"},
     {"albedo": (0.25, 0.25, 0.25), "roughness": 0.25, "anisotropic": 0.125, "spec_trans": 0.25, "spec_tint": 0.375,
      "sheen": 0.5, "sheen_tint": 0.625, "flatness": 0.75, "diff_trans": 1.5, "ior": 1.25, "rates": (2, 3, 4, 5),
      "tex_base": 0, "tex_scalar": (1, 2, 3, 4, 5, -1),
      "tex_params": texp("roughness", "anisotropic", "spec_trans", "diff_trans", "ior"),
      "flags": abi.MATERIAL_FLAG_ANISOTROPIC}),
    ("principledthin", {"spec_tint_texture": "t.png", "sheen_texture": "t.png", "sheen_tint_texture": "t.png",
                        "flatness_texture": "t.png"},
     {"albedo": (0.5, 0.5, 0.5), "roughness": 0.5, "ior": 1.5, "rates": (1, 1, 1, 1), "tex_scalar": (0, 1, 2, 3, -1, -1),
      "tex_params": texp("spec_tint", "sheen", "sheen_tint", "flatness")}),
    ("roughdiffuse", {}, {"albedo": (0.8, 0.8, 0.8), "alpha": 0.2}),
    ("roughdiffuse", {"albedo": [0.25, 0.5, 0.75], "albedo_texture": "t.png", "alpha": 0.5, "fast_approx": True},
     {"albedo": (0.25, 0.5, 0.75), "alpha": 0.5, "tex_base": 0, "flags": abi.MATERIAL_FLAG_FAST_APPROX}),
    ("coatedconductor", {}, {"ior": 1.5, **coated(METALS["copper"], 1.5, (0, 0, 0.01, 10, 1))}),
    ("coatedconductor", {"roughness": 0.5, "ior": 1.25, "metal": "gold", "conductor_roughness": 0.5, "thickness": 0.1,
                         "max_depth": 5, "samples": 2, "distribution": "beckmann", "masking": "separable",
                         "coating_albedo": [0.5, 0.25, 0.125], "coating_g": -0.5},
     {"alpha": 0.25, "ior": 1.25, "flags": BECKMANN | abi.MATERIAL_FLAG_SEPARABLE,
      **coated(METALS["gold"], 1.25, (0.25, 0.25, 0.1, 5, 2, 0.5, 0.25, 0.125, -0.5))}),
    ("coatedconductor", {"alpha_u": 0.1, "alpha_v": 0.2, "eta": [0.2, 0.4, 1.4], "k": [3.0, 2.0, 1.5],
                         "conductor_alpha_u": 0.3, "conductor_alpha_v": 0.4},
     {"alpha": 0.1, "alpha_v": 0.2, "ior": 1.5, "flags": abi.MATERIAL_FLAG_ANISOTROPIC,
      **coated(((0.2, 0.4, 1.4), (3.0, 2.0, 1.5)), 1.5, (0.3, 0.4, 0.01, 10, 1))}),
    ("coatedconductor", {"alpha": 0.3, "reflectance": 0.5, "conductor_alpha": 0.2},  # pbrt's k = 2 sqrt(r / (1 - r))
     {"alpha": 0.3, "ior": 1.5, **coated(((1, 1, 1), (2, 2, 2)), 1.5, (0.2, 0.2, 0.01, 10, 1))}),
    ("diffusetransmission", {}, {"albedo": (0.25, 0.25, 0.25), "table": block(0.25, 0.25, 0.25)}),
    ("diffusetransmission", {"reflectance": [0.5, 0.25, 0.125], "reflectance_texture": "t.png", "transmittance": 0.75},
     {"albedo": (0.5, 0.25, 0.125), "tex_base": 0, "table": block(0.75, 0.75, 0.75)}),
    ("mix", {}, {"table": block(0.5, 1, 2)}),
    ("mix", {"materials": ["b", "a"], "weight": 0.25, "weight_texture": "t.png"},
     {"table": block(0.25, 2, 1), "tex_scalar": (0, -1, -1, -1, -1, -1), "tex_params": texp("mix_weight")}),
]
# the keys every type takes, and what they do to the record
# (emission_directional true packs emission 0 and makes the light a directional area one, which
# tests/render/test_directional_area.py renders from TOML; two-sided it is refused)
COMMON = ({"emission": [1.0, 2.0, 4.0], "two_sided": True, "emission_texture": "t.png", "opacity": 0.5,
           "opacity_texture": "t.png", "emission_directional": False},
          {"emission": (1, 2, 4), "flags": abi.MATERIAL_FLAG_TWO_SIDED | abi.MATERIAL_FLAG_MASK, "tex_emission": 0,
           "opacity": 0.5, "tex_scalar": (1, -1, -1, -1, -1, -1), "tex_params": abi.TEXP_OPACITY})


def _toml_value(v):
    if isinstance(v, bool):
        return str(v).lower()
    return repr(v).replace("'", '"')


def _record(tmp_path, mtype, keys) -> np.void:
    from PIL import Image

    Image.new("RGB", (2, 2), (255, 128, 0)).save(tmp_path / "t.png")
    if mtype == "mix":  # it blends two others, named after it (records 1 and 2)
        keys = {"materials": ["a", "b"], **keys}
    lines = ["[materials.m]", f'type = "{mtype}"'] + [f"{k} = {_toml_value(v)}" for k, v in keys.items()]
    if mtype == "mix":
        lines += ["[materials.a]", "[materials.b]", 'type = "conductor"']
    lines += ["[[shape]]", 'type = "quad"', 'material = "m"', "points = [[0,0,0],[1,0,0],[1,1,0],[0,1,0]]"]
    (tmp_path / "m.toml").write_text("\n".join(lines) + "\n")
    scene = load_scene(tmp_path / "m.toml")
    assert [m.name for m in scene.materials] == (["m", "a", "b"] if mtype == "mix" else ["m"])
    return scene.material_records()[0]


def _check_record(rec, mtype, expected):
    assert rec["type"] == abi.MATERIAL_TYPES[mtype]
    for field in abi.MATERIAL.names:
        if field == "type":
            continue
        default = -1 if field.startswith("tex_") and field != "tex_params" else 1 if field == "normal_scale" else 0
        want = np.broadcast_to(np.asarray(expected.get(field, default), rec[field].dtype), np.shape(rec[field]))
        tol = 1e-3 if field in ("eta", "k") else 0  # the documented gold values have 3 decimals
        if field == "spec_weight":
            tol = 1e-6  # the texture's mean luminance in float32 texels
        assert np.allclose(rec[field], want, rtol=0, atol=tol), (field, rec[field], want)


@pytest.mark.parametrize("mtype, keys, expected", CASES, ids=[f"{c[0]}-{'-'.join(c[1]) or 'defaults'}" for c in CASES])
def test_toml_keys_pack_into_documented_fields(tmp_path, mtype, keys, expected):
    _check_record(_record(tmp_path, mtype, keys), mtype, expected)


@pytest.mark.parametrize("mtype", list(REGISTRY))
def test_common_keys_pack_into_documented_fields(tmp_path, mtype):
    keys, fields = COMMON
    base = next(expected for t, k, expected in CASES if t == mtype and not k)
    expected = {**base, **fields, "flags": base.get("flags", 0) | fields["flags"]}
    _check_record(_record(tmp_path, mtype, keys), mtype, expected)


@pytest.mark.parametrize("mtype", list(REGISTRY))
def test_every_toml_key_is_covered(mtype):
    covered = set(COMMON[0]) | {"type"} | {k for t, keys, _ in CASES if t == mtype for k in keys}
    assert covered == MATERIAL_COMMON_KEYS | REGISTRY[mtype].toml_keys


@pytest.mark.parametrize("keys, message", [({"alpha_u": 0.2}, "go together"),
                                           ({"alpha_u": 0.2, "alpha_v": 0.1, "roughness": 0.3}, "not both"),
                                           ({"distribution": "phong"}, "distribution"),
                                           ({"masking": "uncorrelated"}, "masking")])
def test_distribution_keys_are_checked(tmp_path, keys, message):
    with pytest.raises(Exception, match=message):
        _record(tmp_path, "conductor", keys)


def test_unknown_type_is_an_error():
    with pytest.raises(ValueError, match="unknown type 'velvet'"):
        Material(name="v", type="velvet").record()


def test_diffuse_maps_to_mitsuba_two_sided_diffuse():
    bsdf = Material(albedo=(0.25, 0.5, 0.75)).mitsuba_bsdf()
    assert bsdf == {"type": "twosided", "material": {"type": "diffuse",
                                                     "reflectance": {"type": "rgb", "value": [0.25, 0.5, 0.75]}}}
    with pytest.raises(ValueError, match="not exported to Mitsuba"):
        Material(type="gltf").mitsuba_bsdf()


def test_glass_and_metals_map_to_mitsuba():
    """Dielectrics and conductors given by eta and k (or the f0 = 1 mirror) have Mitsuba
    counterparts with the same parameters; Schlick's f0 < 1 has none."""
    rgb = lambda v: {"type": "rgb", "value": list(v)}  # noqa: E731
    assert Material(type="dielectric", ior=1.33, tint=(1.0, 0.5, 0.25)).mitsuba_bsdf() == {
        "type": "dielectric", "int_ior": 1.33, "ext_ior": 1.0, "specular_reflectance": rgb((1.0, 0.5, 0.25)),
        "specular_transmittance": rgb((1.0, 0.5, 0.25))}
    assert Material(type="dielectric", alpha=0.25).mitsuba_bsdf()["type"] == "roughdielectric"
    gold = Material(type="conductor", alpha=0.25, eta=(0.5, 0.25, 1.0), k=(3.0, 2.0, 1.5)).mitsuba_bsdf()
    assert gold == {"type": "roughconductor", "distribution": "ggx", "alpha": 0.25, "eta": rgb((0.5, 0.25, 1.0)),
                    "k": rgb((3.0, 2.0, 1.5))}
    assert Material(type="conductor").mitsuba_bsdf() == {"type": "conductor", "material": "none"}
    aniso = Material(type="dielectric", alpha=0.25, alpha_v=0.5, distribution="beckmann").mitsuba_bsdf()
    assert {k: aniso[k] for k in ("type", "distribution", "alpha_u", "alpha_v")} == {
        "type": "roughdielectric", "distribution": "beckmann", "alpha_u": 0.25, "alpha_v": 0.5}
    with pytest.raises(ValueError, match="f0"):
        Material(type="conductor", f0=(0.9, 0.8, 0.7)).mitsuba_bsdf()


def test_mitsuba_types_map_to_mitsuba():
    """plastic, roughplastic and principled export as Mitsuba's own plugin with our parameters,
    wrapped in twosided as ours reflect on both sides; a transmitting principled and
    principledthin are not wrapped (the first has an inside, the second is two-sided itself)."""
    rgb = lambda v: {"type": "rgb", "value": list(v)}  # noqa: E731
    plastic = Material(type="plastic", albedo=(0.5, 0.25, 0.125), ior=1.25, nonlinear=True,
                       specular_reflectance=(0.5, 0.5, 0.5)).mitsuba_bsdf()
    assert plastic == {"type": "twosided", "material": {
        "type": "plastic", "diffuse_reflectance": rgb((0.5, 0.25, 0.125)), "int_ior": 1.25, "ext_ior": 1.0,
        "nonlinear": True, "specular_reflectance": rgb((0.5, 0.5, 0.5))}}
    rough = Material(type="roughplastic", alpha=0.25, distribution="beckmann").mitsuba_bsdf()["material"]
    assert (rough["type"], rough["distribution"], rough["alpha"], "specular_reflectance" in rough) == (
        "roughplastic", "beckmann", 0.25, False)
    disney = Material(type="principled", metallic=0.5, ior=1.25, params={"roughness": 0.25, "sheen": 0.5})
    assert disney.mitsuba_bsdf() == {"type": "twosided", "material": {
        "type": "principled", "base_color": rgb((0.8, 0.8, 0.8)), "roughness": 0.25, "metallic": 0.5, "eta": 1.25,
        "sheen": 0.5, "main_specular_sampling_rate": 1.0, "clearcoat_sampling_rate": 1.0,
        "diffuse_reflectance_sampling_rate": 1.0}}
    disney.params["spec_trans"] = 0.5
    assert disney.mitsuba_bsdf()["type"] == "principled"
    assert Material(type="principledthin", params={"diff_trans": 1.5}).mitsuba_bsdf()["diff_trans"] == 1.5
