"""`"roughplastic"` — Mitsuba 3's rough plastic: a diffuse base under a rough dielectric coat of
GGX or Beckmann microfacets, with Mitsuba's approximation of the internal scattering
(`cl/materials/roughplastic.h`). Keys and defaults are Mitsuba's; the other keys are `plastic`'s.

| key | type | default | meaning |
|---|---|---|---|
| `diffuse_reflectance`, `diffuse_reflectance_texture`, `specular_reflectance`, `int_ior`, `ext_ior`, `nonlinear` | | | as `plastic` (`int_ior` ≠ `ext_ior`) |
| `alpha` | number in [0, 1] | 0.1 | the distribution's α (at least 10⁻⁴) |
| `distribution` | `"beckmann"` or `"ggx"` | `"beckmann"` | the microfacet distribution |

The coat's transmittance by angle and its internal reflectance are integrated at load time as
Mitsuba integrates them (a 64-entry table per material).
"""
from __future__ import annotations

from functools import lru_cache

import numpy as np

from ...device import abi
from .plastic import coat_to_mitsuba, pack_coat, read_coat

TOML_KEYS = frozenset({"diffuse_reflectance", "diffuse_reflectance_texture", "specular_reflectance", "int_ior",
                       "ext_ior", "nonlinear", "alpha", "distribution"})
KERNEL_DEFINE = "HAS_MATERIAL_ROUGHPLASTIC"
DISTRIBUTIONS = ("beckmann", "ggx")


def read_toml(material, table) -> None:
    read_coat(material, table)
    if material.ior == 1.0:
        raise table.error("'int_ior' and 'ext_ior' must differ")
    material.alpha = table.number("alpha", 0.1, minimum=0.0, maximum=1.0)
    material.distribution = table.choice("distribution", "distribution", DISTRIBUTIONS) \
        if "distribution" in table else "beckmann"


@lru_cache(maxsize=256)
def rough_tables(distribution: str, alpha: float, eta: float) -> tuple[np.ndarray, float]:
    """(external transmittance at cos = k / 63, k = 0..63; internal reflectance) of a rough
    dielectric coat, as Mitsuba's roughplastic precomputes them (rough_tables.py: its
    integrals): the transmittance of light arriving from outside, and 2 * the mean over the same
    cosines of cos * the reflectance seen from inside (relative index 1 / eta)."""
    from .rough_tables import integrate

    beckmann = distribution == "beckmann"
    alpha = max(float(alpha), 1e-4)
    mu = np.maximum(1e-6, np.linspace(0, 1, abi.ROUGH_TRANSMITTANCE_RES))

    def rule(eta):  # Mitsuba's: 32 x 32 Gauss-Legendre nodes, 128 x 128 for eta < 1
        return np.polynomial.legendre.leggauss(32 if eta > 1 else 128)

    table = integrate(mu, *rule(eta), alpha, float(eta), beckmann, True)
    internal = float(np.mean(integrate(mu, *rule(1 / eta), alpha, 1 / float(eta), beckmann, False) * mu) * 2)
    table.setflags(write=False)
    return table, internal


def pack(material, record) -> None:
    """As plastic, with alpha, MATERIAL_FLAG_BECKMANN, the transmittance table in table and the
    internal reflectance in fdr."""
    pack_coat(material, record)
    record["alpha"] = material.alpha
    if material.distribution == "beckmann":
        record["flags"] |= abi.MATERIAL_FLAG_BECKMANN
    table, internal = rough_tables(material.distribution, float(material.alpha), float(material.ior))
    record["table"] = table
    record["fdr"] = internal


def to_mitsuba(material) -> dict:
    """Mitsuba's twosided roughplastic of the same distribution and alpha, without textures."""
    return coat_to_mitsuba(material, {"type": "roughplastic", "distribution": material.distribution,
                                      "alpha": float(material.alpha)})
