"""**Roughness** (conductor, dielectric, gltf): `roughness` in [0, 1] is the perceptual roughness
of glTF and Disney, the GGX (Trowbridge–Reitz) α = `roughness`²; or give `alpha` in [0, 1]
directly (Mitsuba's and pbrt's α), not both. α < 0.001 is treated as perfectly smooth (a delta
lobe). Single-scattering microfacets lose energy at high roughness (a white rough metal of
α = 1 reflects about 40 % on average; α = 0.2: 92 %).

`conductor` and `dielectric` also take (Mitsuba 3's roughconductor / roughdielectric):

| key | type | default | meaning |
|---|---|---|---|
| `distribution` | `"ggx"` or `"beckmann"` | `"ggx"` | the microfacet distribution |
| `alpha_u`, `alpha_v` | numbers in [0, 1], both | | anisotropic α along the tangent (dp/du: of a mesh's UVs, else of its triangles' first edge; a sphere's circles the z axis) and the bitangent, instead of `alpha` / `roughness` |
| `masking` | `"correlated"` or `"separable"` | `"correlated"` | Smith's shadowing-masking: height-correlated (pbrt-v4) or G1(wo) G1(wi) (Mitsuba 3) |
"""
from __future__ import annotations

from ...device import abi

ROUGHNESS_KEYS = frozenset({"roughness", "alpha"})
# the distribution keys of conductor and dielectric
DISTRIBUTION_KEYS = frozenset({"distribution", "alpha_u", "alpha_v", "masking"})
DISTRIBUTIONS = ("ggx", "beckmann")
MASKINGS = ("correlated", "separable")


def read_alpha(table, default_roughness: float = 0.0) -> float:
    """The GGX alpha of a material table: 'alpha', or 'roughness' squared."""
    if "roughness" in table and "alpha" in table:
        raise table.error("give 'roughness' or 'alpha', not both")
    if "alpha" in table:
        return table.number("alpha", None, minimum=0.0, maximum=1.0)
    return table.number("roughness", default_roughness, minimum=0.0, maximum=1.0) ** 2


def read_distribution(material, table) -> None:
    """alpha (and alpha_v), distribution and masking of a conductor or dielectric table."""
    if "alpha_u" in table or "alpha_v" in table:
        if "alpha_u" not in table or "alpha_v" not in table:
            raise table.error("'alpha_u' and 'alpha_v' go together")
        if "alpha" in table or "roughness" in table:
            raise table.error("give 'alpha_u' and 'alpha_v', or 'alpha' / 'roughness', not both")
        material.alpha = table.number("alpha_u", None, minimum=0.0, maximum=1.0)
        material.alpha_v = table.number("alpha_v", None, minimum=0.0, maximum=1.0)
    else:
        material.alpha = read_alpha(table)
    material.distribution = table.choice("distribution", "distribution", DISTRIBUTIONS) \
        if "distribution" in table else "ggx"
    material.masking = table.choice("masking", "masking", MASKINGS) if "masking" in table else "correlated"


def pack_distribution(material, record) -> None:
    """alpha, alpha_v and the flags of the distribution (cl/materials/microfacet.h, Microfacet)."""
    record["alpha"] = material.alpha
    if material.is_anisotropic:
        record["flags"] |= abi.MATERIAL_FLAG_ANISOTROPIC
        record["alpha_v"] = material.alpha_v if material.alpha_v is not None else material.alpha
    if material.distribution == "beckmann":
        record["flags"] |= abi.MATERIAL_FLAG_BECKMANN
    if material.masking == "separable":
        record["flags"] |= abi.MATERIAL_FLAG_SEPARABLE


def distribution_to_mitsuba(material) -> dict:
    """The alpha / alpha_u, alpha_v and distribution of a Mitsuba rough conductor or dielectric."""
    if material.is_anisotropic:
        av = material.alpha_v if material.alpha_v is not None else material.alpha
        return {"distribution": material.distribution, "alpha_u": float(material.alpha), "alpha_v": float(av)}
    return {"distribution": material.distribution, "alpha": float(material.alpha)}
