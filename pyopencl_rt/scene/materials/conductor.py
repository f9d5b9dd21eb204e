"""`"conductor"` — a metal: a mirror when smooth, GGX or Beckmann microfacets otherwise
(`cl/materials/conductor.h`). Give at most one of `metal`, `eta` + `k`, `f0`; with none it is a
perfect mirror (`f0` = 1).

| key | type | default | meaning |
|---|---|---|---|
| `roughness` / `alpha` | number in [0, 1] | 0 | see **Roughness** above (also `distribution`, `alpha_u`/`alpha_v`, `masking`) |
| `metal` | `"gold"`, `"silver"`, `"copper"` or `"aluminium"` | | the metal's complex index of refraction at 650, 550, 450 nm (refractiveindex.info data, as tabulated in Chaos Group's "Understanding metalness") |
| `eta`, `k` | [r, g, b] or one number (`eta` > 0, `k` ≥ 0), both | | complex index of refraction η + iκ; exact Fresnel reflectance |
| `f0` | [r, g, b] in [0, 1], or one number | 1 | reflectance at normal incidence, Schlick's approximation |
"""
from __future__ import annotations

from ...device import abi
from .microfacet import DISTRIBUTION_KEYS, ROUGHNESS_KEYS, distribution_to_mitsuba, pack_distribution, \
    read_distribution

# Complex indices of refraction eta + i k of named metals at the RGB wavelengths 650, 550 and
# 450 nm (sampled from the refractiveindex.info data sets, as tabulated in Chaos Group's
# "Understanding metalness", 2014).
METALS = {
    "gold": ((0.18299, 0.42108, 1.3734), (3.4242, 2.3459, 1.7704)),
    "silver": ((0.16262, 0.14512, 0.13550), (4.0728, 3.1900, 2.1997)),
    "copper": ((0.27105, 0.67693, 1.3164), (3.6092, 2.6248, 2.2921)),
    "aluminium": ((1.3456, 0.96521, 0.61722), (7.4746, 6.3995, 5.3031)),
}

TOML_KEYS = ROUGHNESS_KEYS | DISTRIBUTION_KEYS | {"metal", "eta", "k", "f0"}
KERNEL_DEFINE = "HAS_MATERIAL_CONDUCTOR"
MTL_PRECEDENCE = 2


def read_toml(material, table) -> None:
    read_distribution(material, table)
    given = [k for k in ("metal", "f0") if k in table] + (["eta/k"] if "eta" in table or "k" in table else [])
    if len(given) > 1:
        raise table.error(f"give only one of 'metal', 'eta' and 'k', or 'f0' (got {', '.join(given)})")
    if "metal" in table:
        material.eta, material.k = METALS[table.choice("metal", "metal", METALS)]
    elif "eta" in table or "k" in table:
        material.eta, material.k = read_index(table)
    else:
        material.f0 = table.rgb01("f0", 1.0)


def read_index(table) -> tuple:
    """(eta, k) of a table's 'eta' and 'k' (both, eta > 0, k >= 0), as tuples of floats."""
    if "eta" not in table or "k" not in table:
        raise table.error("'eta' and 'k' (the complex index of refraction eta + i k) go together")
    eta = table.vector("eta", allow_scalar=True)
    k = table.vector("k", allow_scalar=True)
    if not (eta > 0).all():
        raise table.error(f"'eta' must be > 0, got {eta.tolist()}")
    if k.min() < 0:
        raise table.error(f"'k' must not be negative, got {k.tolist()}")
    return tuple(float(x) for x in eta), tuple(float(x) for x in k)


def from_mtl(material, mtl) -> bool:
    """A mirror: ``illum 3`` (ray-traced reflection) with ``Kd`` = 0 and ``Ks`` > 0, F0 = ``Ks``."""
    if not (mtl.illum == 3 and max(material.albedo) == 0.0 and max(mtl.specular) > 0.0):
        return False
    material.f0, material.alpha = mtl.specular, mtl.alpha or 0.0
    return True


def pack(material, record) -> None:
    """Fresnel from eta + i k, or (eta None) from f0 by Schlick, flagged MATERIAL_FLAG_CONDUCTOR_F0; the
    distribution (alpha, alpha_v and their flags)."""
    pack_distribution(material, record)
    if material.eta is None:
        record["flags"] |= abi.MATERIAL_FLAG_CONDUCTOR_F0
        record["specular"] = material.f0
    else:
        record["eta"] = material.eta
        record["k"] = material.k if material.k is not None else (0.0, 0.0, 0.0)


def to_mitsuba(material) -> dict:
    """Mitsuba's ``conductor`` (smooth) or ``roughconductor`` (the same distribution and alphas) with our
    eta and k as RGB values; f0 = 1 is Mitsuba's perfect mirror (``material = "none"``).  Schlick's
    f0 < 1 has no Mitsuba counterpart (ValueError).  (Mitsuba's masking is always separable.)"""
    smooth = material.alpha <= 0.0 and not material.is_anisotropic
    bsdf = {"type": "conductor"} if smooth else {"type": "roughconductor", **distribution_to_mitsuba(material)}
    if material.eta is not None:
        k = material.k if material.k is not None else (0.0, 0.0, 0.0)
        bsdf["eta"] = {"type": "rgb", "value": [float(x) for x in material.eta]}
        bsdf["k"] = {"type": "rgb", "value": [float(x) for x in k]}
    elif all(float(x) == 1.0 for x in material.f0):
        bsdf["material"] = "none"
    else:
        raise ValueError(f"material {material.name!r}: a conductor given by f0 (Schlick) has no Mitsuba counterpart")
    return bsdf
