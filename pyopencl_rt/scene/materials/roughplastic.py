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


# ------------------------------------------------------------------ Mitsuba's tables, in float64
# (include/mitsuba/render/microfacet.h: eval_transmittance, eval_reflectance; roughplastic.cpp)

def _fresnel(cos_i, eta):
    """Mitsuba's fresnel(): (reflectance, cos_theta_t, eta_ti)."""
    outside = cos_i >= 0
    eta_it = np.where(outside, eta, 1 / eta)
    eta_ti = np.where(outside, 1 / eta, eta)
    ct2 = 1 - (1 - cos_i * cos_i) * eta_ti * eta_ti
    ci, ct = np.abs(cos_i), np.sqrt(np.maximum(ct2, 0))
    with np.errstate(invalid="ignore", divide="ignore"):
        a_s = (ci - eta_it * ct) / (ci + eta_it * ct)
        a_p = (ct - eta_it * ci) / (ct + eta_it * ci)
        r = 0.5 * (a_s * a_s + a_p * a_p)
    r = np.where(eta == 1, 0.0, np.where(ci == 0, 1.0, r))
    return r, np.where(outside, -ct, ct), eta_ti


def _smith_g1(v, m, alpha, beckmann):
    xy = alpha * alpha * (v[..., 0] ** 2 + v[..., 1] ** 2)
    with np.errstate(invalid="ignore", divide="ignore"):
        t2 = xy / v[..., 2] ** 2
        if beckmann:
            a = 1 / np.sqrt(t2)
            r = np.where(a >= 1.6, 1.0, (3.535 * a + 2.181 * a * a) / (1 + 2.276 * a + 2.577 * a * a))
        else:
            r = 2 / (1 + np.sqrt(1 + t2))
    r = np.where(xy == 0, 1.0, r)
    return np.where((v * m).sum(-1) * v[..., 2] <= 0, 0.0, r)


def _visible_slopes(cos_theta, u, beckmann):
    """Mitsuba's sample_visible_11: the slopes of a visible normal for alpha = 1."""
    from scipy.special import erf, erfinv

    if beckmann:
        tan_t = np.sqrt(np.maximum(0, 1 - cos_theta ** 2)) / cos_theta
        with np.errstate(divide="ignore"):
            cot_t = 1 / tan_t
        maxval = erf(cot_t)
        u = np.clip(u, 1e-6, 1 - 1e-6)
        ux = u[..., 0]
        x = maxval - (maxval + 1) * erf(np.sqrt(-np.log(ux)))
        ux = ux * (1 + maxval + tan_t * np.exp(-cot_t * cot_t) / np.sqrt(np.pi))
        for _ in range(3):
            slope = erfinv(x)
            value = 1 + x + tan_t * np.exp(-slope * slope) / np.sqrt(np.pi) - ux
            x = x - value / (1 - slope * tan_t)
        return erfinv(x), erfinv(2 * u[..., 1] - 1)
    x, y = 2 * u[..., 0] - 1, 2 * u[..., 1] - 1  # the concentric disk (Shirley & Chiu, Cline's form)
    q13 = np.abs(x) < np.abs(y)
    r, rp = np.where(q13, y, x), np.where(q13, x, y)
    with np.errstate(invalid="ignore", divide="ignore"):
        phi = 0.25 * np.pi * rp / r
    phi = np.where(q13, 0.5 * np.pi - phi, phi)
    phi = np.where((x == 0) & (y == 0), 0.0, phi)
    px, py = r * np.cos(phi), r * np.sin(phi)
    s = 0.5 * (1 + cos_theta)
    py = np.sqrt(np.maximum(0, 1 - px * px)) * (1 - s) + py * s
    z = np.sqrt(np.maximum(0, 1 - px * px - py * py))
    sin_t = np.sqrt(np.maximum(0, 1 - cos_theta ** 2))
    norm = 1 / (sin_t * py + cos_theta * z)
    return (cos_theta * py - sin_t * z) * norm, px * norm


def _sample_visible(wi, u, alpha, beckmann):
    """Mitsuba's MicrofacetDistribution::sample (visible normals) for wi (N, 1, 3), u (1, M, 2)."""
    wp = np.stack([alpha * wi[..., 0], alpha * wi[..., 1], wi[..., 2]], -1)
    wp /= np.linalg.norm(wp, axis=-1, keepdims=True)
    s2 = wp[..., 0] ** 2 + wp[..., 1] ** 2
    with np.errstate(invalid="ignore", divide="ignore"):
        cs = np.clip(wp[..., :2] / np.sqrt(s2)[..., None], -1, 1)
    flat = s2 <= 4 * 2.0 ** -24
    cos_phi, sin_phi = np.where(flat, 1.0, cs[..., 0]), np.where(flat, 0.0, cs[..., 1])
    sx, sy = _visible_slopes(wp[..., 2], u, beckmann)
    tx = (cos_phi * sx - sin_phi * sy) * alpha
    ty = (sin_phi * sx + cos_phi * sy) * alpha
    m = np.stack([-tx, -ty, np.ones_like(tx)], -1)
    return m / np.linalg.norm(m, axis=-1, keepdims=True)


def _quadrature(wi, alpha, eta, beckmann, transmit):
    """Mitsuba's eval_transmittance (transmit) or eval_reflectance for each direction of wi (N, 3):
    the integral over visible normals m of (1 - F) G1(wt, m) (or F G1(wr, m)), by a
    Gauss-Legendre rule of 32 x 32 (eta > 1) or 128 x 128 nodes over the sample square."""
    res = 32 if eta > 1 else 128
    nodes, weights = np.polynomial.legendre.leggauss(res)
    nx, ny = np.meshgrid(nodes, nodes)
    wx, wy = np.meshgrid(weights, weights)
    u = np.stack([nx.ravel(), ny.ravel()], -1)[None] * 0.5 + 0.5
    w = (wx * wy).ravel()[None] * 0.25
    v = wi[:, None, :]
    m = _sample_visible(v, u, alpha, beckmann)
    vm = (v * m).sum(-1)
    f, cos_t, eta_ti = _fresnel(vm, eta)
    if transmit:
        out = m * (vm * eta_ti + cos_t)[..., None] - v * eta_ti[..., None]
        g = _smith_g1(out, m, alpha, beckmann) * (1 - f)
        g = np.where(out[..., 2] * v[..., 2] >= 0, 0.0, g)
    else:
        out = 2 * vm[..., None] * m - v
        g = _smith_g1(out, m, alpha, beckmann) * f
        g = np.where((out[..., 2] <= 0) | (v[..., 2] <= 0), 0.0, g)
    return (np.nan_to_num(g) * w).sum(-1)


@lru_cache(maxsize=256)
def rough_tables(distribution: str, alpha: float, eta: float) -> tuple[np.ndarray, float]:
    """(external transmittance at cos = k / 63, k = 0..63; internal reflectance) of a rough
    dielectric coat, as Mitsuba's roughplastic precomputes them: the transmittance of light
    arriving from outside, and 2 * the mean over the same cosines of cos * the reflectance seen
    from inside (relative index 1 / eta)."""
    beckmann = distribution == "beckmann"
    alpha = max(float(alpha), 1e-4)
    n = abi.ROUGH_TRANSMITTANCE_RES
    mu = np.maximum(1e-6, np.linspace(0, 1, n))
    wi = np.stack([np.sqrt(1 - mu * mu), np.zeros(n), mu], -1)
    table = _quadrature(wi, alpha, float(eta), beckmann, transmit=True)
    internal = float(np.mean(_quadrature(wi, alpha, 1 / float(eta), beckmann, transmit=False) * mu) * 2)
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
    """Mitsuba's roughplastic of the same distribution and alpha, without textures."""
    return coat_to_mitsuba(material, {"type": "roughplastic", "distribution": material.distribution,
                                      "alpha": float(material.alpha)})
