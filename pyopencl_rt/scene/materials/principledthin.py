"""`"principledthin"` — Mitsuba 3's thin principled BSDF: the Disney BSDF of a thin sheet (leaves,
paper, cloth): specular and diffuse reflection and transmission without refraction
(`cl/materials/principledthin.h`). Keys and defaults are Mitsuba's.

| key | type | default | meaning |
|---|---|---|---|
| `base_color` | [r, g, b] in [0, 1], or one number | 0.5 | base colour |
| `roughness` | number in [0, 1] | 0.5 | as `principled` (transmission: scaled by 0.65 η − 0.35) |
| `anisotropic`, `spec_trans`, `spec_tint`, `sheen`, `sheen_tint`, `flatness` | number in [0, 1] | 0 | as `principled` |
| `diff_trans` | number in [0, 2] | 0 | diffuse transmission (2: all of the diffuse part) |
| `eta` | number > 0 | 1.5 | the sheet's index of refraction (its specular reflectance) |
| `specular_reflectance_sampling_rate`, `specular_transmittance_sampling_rate`, `diffuse_transmittance_sampling_rate`, `diffuse_reflectance_sampling_rate` | number ≥ 0 | 1 | Mitsuba's lobe sampling rates |
| `base_color_texture` | image path | none | multiplies `base_color` (sRGB-decoded) |
| `roughness_texture`, `anisotropic_texture`, `spec_trans_texture`, `spec_tint_texture`, `sheen_texture`, `sheen_tint_texture`, `flatness_texture`, `diff_trans_texture`, `eta_texture` | image path | none | multiplies the parameter (linear; a colour image by its luminance); at most 6 per material |
"""
from __future__ import annotations

from .principled import pack_params, read_scalars

SCALARS = ("anisotropic", "spec_trans", "spec_tint", "sheen", "sheen_tint", "flatness", "diff_trans")
RATES = ("specular_reflectance_sampling_rate", "specular_transmittance_sampling_rate",
         "diffuse_transmittance_sampling_rate", "diffuse_reflectance_sampling_rate")
TEXTURED = ("roughness",) + SCALARS + ("eta",)
TOML_KEYS = frozenset({"base_color", "base_color_texture", "roughness", "eta", *SCALARS, *RATES,
                       *(f"{p}_texture" for p in TEXTURED)})
KERNEL_DEFINE = "HAS_MATERIAL_PRINCIPLEDTHIN"


def read_toml(material, table) -> None:
    read_scalars(material, table, SCALARS, TEXTURED)
    material.ior = table.number("eta", 1.5, positive=True)
    material.params["rates"] = tuple(table.number(r, 1.0, minimum=0.0) for r in RATES)


def pack(material, record) -> None:
    """base_color in albedo, eta in ior, the rest in the fields of their names; rates: specular
    reflection, specular transmission, diffuse transmission, diffuse reflection."""
    pack_params(material, record, (1.0, 1.0, 1.0, 1.0))


def to_mitsuba(material) -> dict:
    """Mitsuba's principledthin with the same parameters, without textures."""
    p = material.params
    bsdf = {"type": "principledthin", "base_color": {"type": "rgb", "value": [float(x) for x in material.albedo]},
            "roughness": float(p.get("roughness", 0.5)), "eta": float(material.ior)}
    for name in SCALARS:
        if p.get(name, 0.0) != 0.0:
            bsdf[name] = float(p[name])
    for key, rate in zip(RATES, p.get("rates", (1.0, 1.0, 1.0, 1.0))):
        bsdf[key] = float(rate)
    return bsdf
