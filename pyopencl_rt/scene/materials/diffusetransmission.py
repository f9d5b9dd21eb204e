"""`"diffusetransmission"` — a sheet that scatters light diffusely on both sides, reflecting some and
letting some through (pbrt-v4's `diffusetransmission`; `cl/materials/diffusetransmission.h`): paper,
a lampshade, a leaf. pbrt files name it too.

| key | type | default | meaning |
|---|---|---|---|
| `reflectance` | [r, g, b] in [0, 1], or one number | 0.25 | the share scattered back, Lambertian |
| `reflectance_texture` | image path | none | multiplies `reflectance` (sRGB-decoded) |
| `transmittance` | [r, g, b] in [0, 1], or one number | 0.25 | the share scattered through to the other side, Lambertian |

Light goes through without bending (no refraction), so a closed shape of it is no glass: it is a
translucent skin. Sampled on either side in proportion to the larger of the two colours' channels.
"""
from __future__ import annotations

TOML_KEYS = frozenset({"reflectance", "reflectance_texture", "transmittance"})
KERNEL_DEFINE = "HAS_MATERIAL_DIFFUSETRANSMISSION"


# its block in Material.table (cl/materials/diffusetransmission.h's DT_TRANSMITTANCE): the transmittance's RGB
TRANSMITTANCE = slice(0, 3)


def read_toml(material, table) -> None:
    material.albedo = table.rgb01("reflectance", 0.25)
    material.base_texture = table.texture("reflectance_texture", srgb=True)
    material.params["transmittance"] = table.rgb01("transmittance", 0.25)


def pack(material, record) -> None:
    """reflectance in albedo (its texture in tex_base, as every type's), transmittance in its block"""
    record["albedo"] = material.albedo
    record["table"][TRANSMITTANCE] = material.params.get("transmittance", (0.25, 0.25, 0.25))
