"""`"gltf"` — glTF 2.0's metallic-roughness material: a diffuse base under a GGX specular layer
(Schlick Fresnel from F0 = ((ior − 1)/(ior + 1))² for the dielectric, `base_color` for metal),
blended by `metallic` (`cl/materials/gltf.h`). Defaults are glTF's.

| key | type | default | meaning |
|---|---|---|---|
| `base_color` | [r, g, b] in [0, 1], or one number | 1 | glTF `baseColorFactor` (linear RGB) |
| `metallic` | number in [0, 1] | 1 | glTF `metallicFactor` |
| `roughness` / `alpha` | number in [0, 1] | roughness 1 | glTF `roughnessFactor` (α = roughness²) |
| `ior` | number > 0 | 1.5 | KHR_materials_ior |
| `base_color_texture` | image path | none | multiplies `base_color` (sRGB-decoded) |
| `metallic_roughness_texture` | image path | none | B multiplies metallic, G roughness (linear) |
"""
from __future__ import annotations

from .microfacet import ROUGHNESS_KEYS, read_alpha

TOML_KEYS = ROUGHNESS_KEYS | {"base_color", "metallic", "ior", "base_color_texture", "metallic_roughness_texture"}
KERNEL_DEFINE = "HAS_MATERIAL_GLTF"
MTL_PRECEDENCE = 1


def read_toml(material, table) -> None:
    material.alpha = read_alpha(table, default_roughness=1.0)
    material.albedo = table.rgb01("base_color", 1.0)
    material.metallic = table.number("metallic", 1.0, minimum=0.0, maximum=1.0)
    material.ior = table.number("ior", 1.5, positive=True)
    material.base_texture = table.texture("base_color_texture", srgb=True)
    material.mr_texture = table.texture("metallic_roughness_texture", srgb=False)


def from_mtl(material, mtl) -> bool:
    """The PBR extension's metallic ``Pm``, or plastic: ``illum 2`` (highlights) with ``Ks`` > 0
    (metallic 0); base colour ``Kd``, IOR ``Ni``, roughness 1 unless ``Pr`` or ``Ns`` give one."""
    if not (mtl.metallic is not None or (mtl.illum == 2 and max(mtl.specular) > 0.0)):
        return False
    material.metallic = 0.0 if mtl.metallic is None else mtl.metallic
    material.ior = mtl.ior
    material.alpha = 1.0 if mtl.alpha is None else mtl.alpha
    return True


def pack(material, record) -> None:
    """base_color in the record's albedo field."""
    record["albedo"] = material.albedo
    record["metallic"] = material.metallic
    record["alpha"] = material.alpha
    record["ior"] = material.ior
