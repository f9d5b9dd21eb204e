"""**Roughness** (conductor, dielectric, gltf): `roughness` in [0, 1] is the perceptual roughness
of glTF and Disney, the GGX (Trowbridge–Reitz) α = `roughness`²; or give `alpha` in [0, 1]
directly (Mitsuba's and pbrt's α), not both. α < 0.001 is treated as perfectly smooth (a delta
lobe). Single-scattering microfacets lose energy at high roughness (a white rough metal of
α = 1 reflects about 40 % on average; α = 0.2: 92 %).
"""
from __future__ import annotations

ROUGHNESS_KEYS = frozenset({"roughness", "alpha"})


def read_alpha(table, default_roughness: float = 0.0) -> float:
    """The GGX alpha of a material table: 'alpha', or 'roughness' squared."""
    if "roughness" in table and "alpha" in table:
        raise table.error("give 'roughness' or 'alpha', not both")
    if "alpha" in table:
        return table.number("alpha", None, minimum=0.0, maximum=1.0)
    return table.number("roughness", default_roughness, minimum=0.0, maximum=1.0) ** 2
