"""`"dielectric"` — glass: Fresnel reflection and refraction (total internal reflection included),
smooth or rough (GGX or Beckmann microfacets, `cl/materials/dielectric.h`).

| key | type | default | meaning |
|---|---|---|---|
| `ior` | number > 0 | 1.5 | index of refraction of the inside (the back of triangles, the inside of spheres) relative to the outside |
| `roughness` / `alpha` | number in [0, 1] | 0 | see **Roughness** above (also `distribution`, `alpha_u`/`alpha_v`, `masking`) |
| `tint` | [r, g, b] in [0, 1], or one number | 1 | multiplies reflection and transmission |

Glass should be closed geometry (a sphere, a closed mesh with outward-facing triangles).
"""
from __future__ import annotations

from ...device import abi
from .microfacet import DISTRIBUTION_KEYS, ROUGHNESS_KEYS, distribution_to_mitsuba, pack_distribution, \
    read_distribution

TOML_KEYS = ROUGHNESS_KEYS | DISTRIBUTION_KEYS | {"ior", "tint"}
KERNEL_DEFINE = "HAS_MATERIAL_DIELECTRIC"
MTL_PRECEDENCE = 0  # transparency wins over every other statement


def read_toml(material, table) -> None:
    read_distribution(material, table)
    material.ior = table.number("ior", 1.5, positive=True)
    material.tint = table.rgb01("tint", 1.0)


def from_mtl(material, mtl) -> bool:
    """Transparent or refracting: ``d`` < 1, ``Tr`` > 0 or ``illum`` 4, 6, 7 or 9; IOR ``Ni``."""
    if not (mtl.opacity < 1.0 or mtl.illum in (4, 6, 7, 9)):
        return False
    material.ior, material.alpha = mtl.ior, mtl.alpha or 0.0
    return True


def pack(material, record) -> None:
    """The tint goes in the record's specular field (a base texture multiplies it); the distribution
    (alpha, alpha_v and their flags)."""
    pack_distribution(material, record)
    record["ior"] = material.ior
    record["specular"] = material.tint
    if getattr(material, "thin", False):
        record["flags"] |= abi.MATERIAL_FLAG_THIN


def to_mitsuba(material) -> dict:
    """Mitsuba's ``dielectric`` (smooth) or ``roughdielectric`` (the same distribution and alphas) of
    int_ior = ior, ext_ior = 1, the tint as both specular reflectance and transmittance."""
    tint = {"type": "rgb", "value": [float(x) for x in material.tint]}
    smooth = material.alpha <= 0.0 and not material.is_anisotropic
    bsdf = {"type": "dielectric"} if smooth else {"type": "roughdielectric", **distribution_to_mitsuba(material)}
    return {**bsdf, "int_ior": float(material.ior), "ext_ior": 1.0, "specular_reflectance": tint,
            "specular_transmittance": tint}
