"""`"mix"` — a blend of two materials (Mitsuba 3's `blendbsdf`, pbrt-v4's `"mix"` material):
`(1 − w)` times the first plus `w` times the second (`cl/materials/mix.h`), rendered as Mitsuba
renders a blendbsdf: a light sample sees the blend of both, and the BSDF sample of one of them
(the second with probability `w`) is weighed by the blend over the blended densities. A mix inside
a mix is resolved by picking one material at each level, with probability as its weight, as
pbrt-v4 does (the same image in expectation, more noise). The emission (`emission`, `emission_texture`,
`two_sided`) and an alpha mask are the mix's own; the blended materials' emission is not used.
The albedo AOV shows the material picked at each sample (averaged over samples: the blend).

| key | type | default | meaning |
|---|---|---|---|
| `materials` | [NAME, NAME] | (required) | the two blended materials (names of `[materials.NAME]` tables) |
| `weight` | number in [0, 1] | 0.5 | `w`: 0 is the first material, 1 the second |
| `weight_texture` | image path | none | multiplies `weight` (its luminance, not sRGB-decoded; triangles only) |
"""
from __future__ import annotations

TOML_KEYS = frozenset({"materials", "weight", "weight_texture"})
KERNEL_DEFINE = "HAS_MATERIAL_MIX"


def read_toml(material, table) -> None:
    """The weight; the two names in material.params["materials"] (the TOML loader resolves them to
    material.blend once every table is read)."""
    from ..textures import scalar_texture

    names = table.table.get("materials")
    if not (isinstance(names, list) and len(names) == 2 and all(isinstance(n, str) for n in names)):
        raise table.error(f"'materials' must name the two blended materials, as [\"a\", \"b\"], got {names!r}")
    material.params["materials"] = tuple(names)
    material.mix_weight = table.number("weight", 0.5, minimum=0.0, maximum=1.0)
    texture = table.texture("weight_texture", srgb=False)
    if texture is not None:
        material.scalar_textures["mix_weight"] = scalar_texture(texture)


# its block in Material.table, in cl/materials/mix.h's MIX_* order: the weight, then the two blended
# records' indices (floats, exact below 2^24), which Material.record writes (it knows the scene's materials)
WEIGHT, BLENDED = 0, slice(1, 3)


def pack(material, record) -> None:
    """The weight in its block (``table``)."""
    if len(material.blend) != 2:
        raise ValueError(f"material {material.name!r}: a mix needs its two materials (Material.blend)")
    record["table"][WEIGHT] = min(max(float(material.mix_weight), 0.0), 1.0)


def to_mitsuba(material) -> dict:
    """Mitsuba's blendbsdf of the two materials' BSDFs (a constant weight only)."""
    if "mix_weight" in material.scalar_textures or material.vertex_colors:
        raise ValueError(f"material {material.name!r}: a textured mix weight is not exported to Mitsuba")
    for m in material.blend:
        if m.textures() or m.masked or m.one_sided or m.vertex_colors:
            raise ValueError(f"material {material.name!r}: a textured, masked or one-sided material in a mix "
                             "is not exported to Mitsuba")
    return {"type": "blendbsdf", "weight": float(material.mix_weight),
            "bsdf_0": material.blend[0].mitsuba_bsdf(), "bsdf_1": material.blend[1].mitsuba_bsdf()}
