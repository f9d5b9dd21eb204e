"""`"diffuse"` — Lambertian reflection (`cl/materials/diffuse.h`):

| key | type | default | meaning |
|---|---|---|---|
| `albedo` | [r, g, b] in [0, 1], or one number | 0.8 | diffuse reflectance |
| `albedo_texture` | image path | none | multiplies `albedo` (sRGB-decoded) |
"""
from __future__ import annotations

TOML_KEYS = frozenset({"albedo", "albedo_texture"})
KERNEL_DEFINE = None  # always compiled: cl/materials/dispatch.h falls back to it
MTL_PRECEDENCE = 3  # last: every MTL material that no other type claims


def read_toml(material, table) -> None:
    material.albedo = table.rgb01("albedo", 0.8)
    material.base_texture = table.texture("albedo_texture", srgb=True)


def from_mtl(material, mtl) -> bool:
    return True


def pack(material, record) -> None:
    record["albedo"] = material.albedo


def to_mitsuba(material) -> dict:
    """Mitsuba's diffuse on both sides, as ours."""
    reflectance = {"type": "rgb", "value": [float(x) for x in material.albedo]}
    return {"type": "twosided", "material": {"type": "diffuse", "reflectance": reflectance}}
