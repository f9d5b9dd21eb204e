"""`"principled"` — Mitsuba 3's principled BSDF: the Disney BSDF as Mitsuba implements it
(metallic and dielectric specular, specular transmission, clearcoat, sheen, diffuse with
retro-reflection; `cl/materials/principled.h`). Keys and defaults are Mitsuba's.

| key | type | default | meaning |
|---|---|---|---|
| `base_color` | [r, g, b] in [0, 1], or one number | 0.5 | base colour |
| `roughness` | number in [0, 1] | 0.5 | GGX α = max(0.001, `roughness`²) (split by `anisotropic`) |
| `metallic`, `anisotropic`, `spec_trans`, `spec_tint`, `sheen`, `sheen_tint`, `clearcoat`, `clearcoat_gloss`, `flatness` | number in [0, 1] | 0 | the Disney parameters (`spec_trans`: specular transmission, the surface then the interface of a solid) |
| `eta` or `specular` | number > 0, or in [0, 1] | `specular` 0.5 | relative index of refraction, or `specular` giving η = 2 / (1 − √(0.08 `specular`)) − 1 |
| `main_specular_sampling_rate`, `clearcoat_sampling_rate`, `diffuse_reflectance_sampling_rate` | number ≥ 0 | 1 | Mitsuba's lobe sampling rates |
| `base_color_texture` | image path | none | multiplies `base_color` (sRGB-decoded) |
| `roughness_texture`, `metallic_texture`, `anisotropic_texture`, `spec_trans_texture`, `spec_tint_texture`, `sheen_texture`, `sheen_tint_texture`, `clearcoat_texture`, `clearcoat_gloss_texture`, `flatness_texture` | image path | none | multiplies the parameter (linear; a colour image by its luminance); at most 6 per material |

Without transmission both sides of a surface look alike (Mitsuba's is black from behind).
"""
from __future__ import annotations

import numpy as np

from ...device import abi

SCALARS = ("metallic", "anisotropic", "spec_trans", "spec_tint", "sheen", "sheen_tint", "clearcoat",
           "clearcoat_gloss", "flatness")
RATES = ("main_specular_sampling_rate", "clearcoat_sampling_rate", "diffuse_reflectance_sampling_rate")
TEXTURED = ("roughness",) + SCALARS
TOML_KEYS = frozenset({"base_color", "base_color_texture", "roughness", "eta", "specular", *SCALARS, *RATES,
                       *(f"{p}_texture" for p in TEXTURED)})
KERNEL_DEFINE = "HAS_MATERIAL_PRINCIPLED"


def eta_from_specular(specular: float) -> float:
    """Mitsuba's 2 / (1 - sqrt(0.08 specular)) - 1, in float32."""
    f = np.float32
    return float(f(2) * (f(1) / (f(1) - np.sqrt(f(0.08) * f(specular)))) - f(1))


def principled_eta(eta, specular, transmits: bool) -> float:
    """The relative index: eta (1 becomes 1.001 with transmission), else from specular (default
    0.5; 0 becomes 1e-3 with transmission), as Mitsuba's constructor."""
    if eta is not None:
        return 1.001 if transmits and eta == 1.0 else float(eta)
    s = 0.5 if specular is None else float(specular)
    return eta_from_specular(1e-3 if transmits and s == 0.0 else s)


def read_scalars(material, table, names, textured) -> None:
    """base_color, roughness and the named scalars (default 0), the rates, the textures."""
    from ..textures import scalar_texture

    material.albedo = table.rgb01("base_color", 0.5)
    material.base_texture = table.texture("base_color_texture", srgb=True)
    material.params["roughness"] = table.number("roughness", 0.5, minimum=0.0, maximum=1.0)
    for name in names:
        if name == "diff_trans":
            material.params[name] = table.number(name, 0.0, minimum=0.0, maximum=2.0)
        else:
            material.params[name] = table.number(name, 0.0, minimum=0.0, maximum=1.0)
    for name in textured:
        tex = table.texture(f"{name}_texture", srgb=False)
        if tex is not None:
            material.scalar_textures["ior" if name == "eta" else name] = scalar_texture(tex)
    if len(material.scalar_textures) > abi.TEX_SLOTS:
        raise table.error(f"at most {abi.TEX_SLOTS} textured parameters, got {len(material.scalar_textures)}")


def read_toml(material, table) -> None:
    read_scalars(material, table, SCALARS, TEXTURED)
    material.metallic = material.params.pop("metallic")
    if "eta" in table and "specular" in table:
        raise table.error("give 'eta' or 'specular', not both")
    transmits = material.params["spec_trans"] > 0 or "spec_trans" in material.scalar_textures
    eta = table.number("eta", None, positive=True) if "eta" in table else None
    specular = table.number("specular", None, minimum=0.0, maximum=1.0) if "specular" in table else None
    material.ior = principled_eta(eta, specular, transmits)
    material.params["rates"] = tuple(table.number(r, 1.0, minimum=0.0) for r in RATES) + (0.0,)


def pack_params(material, record, rates) -> None:
    """albedo, ior and material.params by field name (roughness 0.5 and the rates `rates` unless
    given)."""
    record["albedo"] = material.albedo
    record["ior"] = material.ior
    params = {"roughness": 0.5, "rates": rates, **material.params}
    for name, value in params.items():
        if name in record.dtype.names:
            record[name] = value
    if material.is_anisotropic:  # the frame's tangent is dp/du, as Mitsuba's sh_frame (dispatch.h, bsdf_frame)
        record["flags"] |= abi.MATERIAL_FLAG_ANISOTROPIC


def pack(material, record) -> None:
    """base_color in albedo, metallic, eta in ior, the rest in the fields of their names; rates:
    main specular, clearcoat, diffuse reflection."""
    pack_params(material, record, (1.0, 1.0, 1.0, 0.0))
    record["metallic"] = material.metallic


def to_mitsuba(material) -> dict:
    """Mitsuba's principled with the same parameters (eta, not specular), without textures;
    twosided unless it transmits (as ours)."""
    p = material.params
    bsdf = {"type": "principled", "base_color": {"type": "rgb", "value": [float(x) for x in material.albedo]},
            "roughness": float(p.get("roughness", 0.5)), "metallic": float(material.metallic),
            "eta": float(material.ior)}
    for name in SCALARS[1:]:
        if p.get(name, 0.0) != 0.0:
            bsdf[name] = float(p[name])
    for key, rate in zip(RATES, p.get("rates", (1.0, 1.0, 1.0))):
        bsdf[key] = float(rate)
    transmits = (1.0 - material.metallic) * p.get("spec_trans", 0.0) > 0 or "spec_trans" in material.scalar_textures
    return bsdf if transmits else {"type": "twosided", "material": bsdf}
