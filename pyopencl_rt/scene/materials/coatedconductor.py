"""`"coatedconductor"` — a metal under a clear coat: pbrt-v4's `coatedconductor`, a dielectric
interface over a conductor with the light that bounces between them simulated by a random walk, as
pbrt-v4 estimates its layered BSDF (`cl/materials/coatedconductor.h`). pbrt files name it too.

| key | type | default | meaning |
|---|---|---|---|
| `roughness` / `alpha` | number in [0, 1] | 0 | the coating's roughness (see **Roughness** above; also `distribution`, `alpha_u`/`alpha_v`, `masking`) |
| `ior` | number > 0 | 1.5 | the coating's index of refraction |
| `metal` | `"gold"`, `"silver"`, `"copper"` or `"aluminium"` | `"copper"` | the metal under the coating (as `conductor`'s) |
| `eta`, `k` | [r, g, b] or one number (`eta` > 0, `k` ≥ 0), both | | the metal's complex index of refraction in air, instead of `metal` (divided by `ior` under the coating) |
| `reflectance` | [r, g, b] in [0, 1), or one number | | instead of `metal` or `eta`/`k`: the metal whose reflectance at normal incidence in air this is (pbrt's eta 1 and k = 2 √r / √(1 − r)) |
| `conductor_roughness` / `conductor_alpha` | number in [0, 1] | 0 | the metal's roughness under the coating (GGX; `conductor_alpha_u`, `conductor_alpha_v` for anisotropy) |
| `thickness` | number ≥ 0 | 0.01 | the coating's thickness in mean free paths: light crossing it at angle θ keeps exp(−thickness / cos θ) |
| `coating_albedo` | [r, g, b] in [0, 1], or one number | 0 | the coating's single-scattering albedo (pbrt's `albedo`): above 0, the coating is a medium that scatters what it does not absorb |
| `coating_g` | number in (−1, 1) | 0 | the asymmetry of the coating's Henyey-Greenstein phase function (pbrt's `g`; > 0 forward) |
| `max_depth` | integer ≥ 1 | 10 | the longest walk between the layers (pbrt's `maxdepth`) |
| `samples` | integer ≥ 1 | 1 | walks per estimate (pbrt's `nsamples`) |

The coating reflects by its Fresnel term (with a rough coating, a glossy highlight over the metal's);
what it lets through reaches the metal, and what the metal reflects bounces between the two before it
leaves: a coated metal is deeper in colour and has a second, sharper highlight. Two-sided, as pbrt's.
A scattering coating (`coating_albedo` > 0) turns part of the light back before it reaches the metal:
a milky, diffuse sheen over the metal, stronger the thicker the coating.
Its value, its density and its samples are estimates (random walks), exactly as pbrt-v4 renders it;
a smooth, clear coating over a smooth metal is a mirror (no light sampling).
"""
from __future__ import annotations

import numpy as np

from .conductor import METALS, read_index
from .microfacet import DISTRIBUTION_KEYS, ROUGHNESS_KEYS, pack_distribution, read_distribution

TOML_KEYS = ROUGHNESS_KEYS | DISTRIBUTION_KEYS | {
    "ior", "metal", "eta", "k", "reflectance", "conductor_roughness", "conductor_alpha", "conductor_alpha_u",
    "conductor_alpha_v", "thickness", "max_depth", "samples", "coating_albedo", "coating_g"}
KERNEL_DEFINE = "HAS_MATERIAL_COATEDCONDUCTOR"
# the layer's parameter block in Material.table, in cl/materials/coatedconductor.h's COATED_* order
LAYER = ("conductor_alpha_u", "conductor_alpha_v", "thickness", "max_depth", "samples", "albedo_r", "albedo_g",
         "albedo_b", "g")
DEFAULTS = {"conductor_alpha_u": 0.0, "conductor_alpha_v": 0.0, "thickness": 0.01, "max_depth": 10, "samples": 1,
            "albedo_r": 0.0, "albedo_g": 0.0, "albedo_b": 0.0, "g": 0.0}


def reflectance_to_index(r) -> tuple:
    """pbrt-v4's conductor of normal reflectance r: eta 1 and k = 2 sqrt(r) / sqrt(1 - r), r clamped to
    [0, 0.9999]."""
    r = np.clip(np.asarray(r, np.float64), 0.0, 0.9999)
    return (1.0, 1.0, 1.0), tuple(float(x) for x in 2 * np.sqrt(r) / np.sqrt(1 - r))


def read_toml(material, table) -> None:
    read_distribution(material, table)
    material.ior = table.number("ior", 1.5, positive=True)
    given = [k for k in ("metal", "reflectance") if k in table] + (["eta/k"] if "eta" in table or "k" in table else [])
    if len(given) > 1:
        raise table.error(f"give only one of 'metal', 'eta' and 'k', or 'reflectance' (got {', '.join(given)})")
    if "eta" in table or "k" in table:
        material.eta, material.k = read_index(table)
    elif "reflectance" in table:
        material.eta, material.k = reflectance_to_index(table.rgb01("reflectance", 0.5))
    else:
        material.eta, material.k = METALS[table.choice("metal", "metal", METALS) if "metal" in table else "copper"]
    if "conductor_alpha_u" in table or "conductor_alpha_v" in table:
        au = table.number("conductor_alpha_u", None, minimum=0.0, maximum=1.0)
        av = table.number("conductor_alpha_v", None, minimum=0.0, maximum=1.0)
    else:
        if "conductor_alpha" in table and "conductor_roughness" in table:
            raise table.error("give 'conductor_roughness' or 'conductor_alpha', not both")
        au = av = (table.number("conductor_alpha", None, minimum=0.0, maximum=1.0) if "conductor_alpha" in table
                   else table.number("conductor_roughness", 0.0, minimum=0.0, maximum=1.0) ** 2)
    material.params.update(conductor_alpha_u=au, conductor_alpha_v=av,
                           thickness=table.number("thickness", 0.01, minimum=0.0),
                           max_depth=_count(table, "max_depth", 10), samples=_count(table, "samples", 1))
    g = table.number("coating_g", 0.0)
    if not -1.0 < g < 1.0:
        raise table.error(f"'coating_g' must be in (-1, 1), got {g:g}")
    set_coating_medium(material, table.rgb01("coating_albedo", 0.0) if "coating_albedo" in table else (0.0,) * 3, g)


def set_coating_medium(material, albedo, g) -> None:
    """The scattering coating's albedo (each channel in [0, 1]) and Henyey-Greenstein g in (-1, 1), as the
    loaders have checked them."""
    material.params.update(albedo_r=float(albedo[0]), albedo_g=float(albedo[1]), albedo_b=float(albedo[2]),
                           g=float(g))


def _count(table, key, default) -> int:
    value = table.number(key, default, minimum=1)
    if value != int(value) or value > 1000:
        raise table.error(f"'{key}' must be a whole number from 1 to 1000, got {value}")
    return int(value)


def pack(material, record) -> None:
    """The coating's distribution and index; the metal's eta and k relative to the coating (divided by
    its index, as pbrt-v4 puts the metal under it); the layer's block in ``table``."""
    pack_distribution(material, record)
    record["ior"] = material.ior
    eta = material.eta if material.eta is not None else METALS["copper"][0]
    k = material.k if material.k is not None else METALS["copper"][1]
    record["eta"] = tuple(float(x) / material.ior for x in eta)
    record["k"] = tuple(float(x) / material.ior for x in k)
    if material.base_texture is not None:  # pbrt's reflectance texture: r = albedo x texel (cl/scene/textures.h)
        record["albedo"] = material.albedo
    for i, key in enumerate(LAYER):
        record["table"][i] = float(material.params.get(key, DEFAULTS[key]))
