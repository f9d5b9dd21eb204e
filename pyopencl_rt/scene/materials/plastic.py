"""`"plastic"` — Mitsuba 3's smooth plastic: a diffuse base under a smooth dielectric coat, with
Mitsuba's closed form of the light scattered back and forth under the coat
(`cl/materials/plastic.h`). Keys and defaults are Mitsuba's.

| key | type | default | meaning |
|---|---|---|---|
| `diffuse_reflectance` | [r, g, b] in [0, 1], or one number | 0.5 | the base's reflectance |
| `diffuse_reflectance_texture` | image path | none | multiplies `diffuse_reflectance` (sRGB-decoded) |
| `specular_reflectance` | [r, g, b] in [0, 1], or one number | 1 | scales the coat's reflection (1 is physical) |
| `int_ior`, `ext_ior` | number > 0 | 1.49, 1.000277 | indices of refraction of the coat and of the outside (polypropylene and air) |
| `nonlinear` | boolean | false | Mitsuba's `nonlinear`: the colour darkens and saturates through the internal scattering (d / (1 − d F_dr) instead of d / (1 − F_dr)) |

Both sides of a surface look alike (Mitsuba's plastic is black from behind).
"""
from __future__ import annotations

import numpy as np

from ...device import abi

TOML_KEYS = frozenset({"diffuse_reflectance", "diffuse_reflectance_texture", "specular_reflectance", "int_ior",
                       "ext_ior", "nonlinear"})
KERNEL_DEFINE = "HAS_MATERIAL_PLASTIC"

POLYPROPYLENE, AIR = 1.49, 1.000277  # Mitsuba's defaults (include/mitsuba/render/ior.h)


def read_coat(material, table) -> None:
    """The keys plastic and roughplastic share."""
    material.albedo = table.rgb01("diffuse_reflectance", 0.5)
    material.base_texture = table.texture("diffuse_reflectance_texture", srgb=True)
    material.specular_reflectance = table.rgb01("specular_reflectance", 1.0)
    int_ior = table.number("int_ior", POLYPROPYLENE, positive=True)
    ext_ior = table.number("ext_ior", AIR, positive=True)
    material.ior = int_ior / ext_ior
    material.nonlinear = table.boolean("nonlinear", False)


def read_toml(material, table) -> None:
    read_coat(material, table)


def fresnel_diffuse_reflectance(eta: float) -> float:
    """Mitsuba's fresnel_diffuse_reflectance: the hemispherically averaged Fresnel reflectance at
    relative index eta, by Egan & Hilgeman's fit (eta < 1) or d'Eon & Irving's (eta >= 1),
    in float32 as Mitsuba evaluates it."""
    f = np.float32
    eta = f(eta)
    inv = f(1) / eta
    if eta < 1:
        return float(f(0.0636) * inv + (eta * (eta * f(-1.4399) + f(0.7099)) + f(0.6681)))
    c = [f(0.919317), f(-3.4793), f(6.75335), f(-7.80989), f(4.98554), f(-1.36881)]
    r = c[-1]
    for k in c[-2::-1]:
        r = r * inv + k
    return float(r)


def internal_diffuse_reflectance(eta: float) -> float:
    """fdr_int, the coat's reflectance for diffuse light from inside: Mitsuba's
    fresnel_diffuse_reflectance(1 / eta) up to eta = 2, its fit's range; beyond, where the fit
    errs (by 4% at eta 3, and above 1 from 3.7 on, which makes Mitsuba's plastic negative), the
    exact hemispherical average 2 int F(cos) cos dcos of the Fresnel reflectance at 1 / eta."""
    if eta <= 2.0:
        return fresnel_diffuse_reflectance(1.0 / eta)
    e = 1.0 / eta  # light from inside: the transmitted side's index over the incident one's
    c_crit = np.sqrt(1.0 - e * e)  # total internal reflection below it: 2 int c dc = c_crit^2
    x, w = np.polynomial.legendre.leggauss(64)
    c = c_crit + (1.0 - c_crit) * 0.5 * (x + 1.0)
    ct = np.sqrt(np.maximum(0.0, 1.0 - (1.0 - c * c) / (e * e)))
    r_par = (e * c - ct) / (e * c + ct)
    r_perp = (c - e * ct) / (c + e * ct)
    f = 0.5 * (r_par ** 2 + r_perp ** 2)
    return float(c_crit ** 2 + (1.0 - c_crit) * np.sum(w * c * f))  # 2 * 1/2 of the interval * sum


def specular_weight(material) -> float:
    """Mitsuba's specular sampling weight s / (d + s): s the mean of specular_reflectance, d the
    mean of diffuse_reflectance (times its texture's mean luminance, Mitsuba's mean of a bitmap;
    ``params["diffuse_mean"]`` overrides it, as the XML import sets it for a checkerboard)."""
    d = material.params.get("diffuse_mean")
    if d is None:
        d = float(np.mean(material.albedo))
        lum = np.array([0.212671, 0.715160, 0.072169])
        tex = material.base_texture
        if tex is not None and hasattr(tex, "texels"):
            d *= float((tex.texels[..., :3].astype(np.float64) @ lum).mean())
        elif tex is not None:  # no image of its own (pbrt's directionmix): its estimated mean
            d *= float(tex.mean_rgb() @ lum)
    s = float(np.mean(material.specular_reflectance))
    return s / (d + s) if d + s > 0 else 0.5


def pack_coat(material, record) -> None:
    """The fields plastic and roughplastic share."""
    record["albedo"] = material.albedo
    record["specular"] = material.specular_reflectance
    record["ior"] = material.ior
    record["spec_weight"] = specular_weight(material)
    if material.nonlinear:
        record["flags"] |= abi.MATERIAL_FLAG_NONLINEAR


def pack(material, record) -> None:
    """diffuse_reflectance in albedo, specular_reflectance in specular, eta in ior, fdr_int in
    fdr, the sampling weight in spec_weight."""
    pack_coat(material, record)
    record["fdr"] = internal_diffuse_reflectance(material.ior)


def coat_to_mitsuba(material, bsdf) -> dict:
    """The coat's parameters added to ``bsdf``, wrapped in Mitsuba's twosided (ours reflect on
    both sides)."""
    rgb = lambda v: {"type": "rgb", "value": [float(x) for x in v]}  # noqa: E731
    bsdf.update({"diffuse_reflectance": rgb(material.albedo), "int_ior": float(material.ior), "ext_ior": 1.0,
                 "nonlinear": bool(material.nonlinear)})
    if tuple(material.specular_reflectance) != (1.0, 1.0, 1.0):
        bsdf["specular_reflectance"] = rgb(material.specular_reflectance)
    return {"type": "twosided", "material": bsdf}


def to_mitsuba(material) -> dict:
    """Mitsuba's twosided plastic (int_ior = our eta, ext_ior = 1), without textures."""
    return coat_to_mitsuba(material, {"type": "plastic"})
