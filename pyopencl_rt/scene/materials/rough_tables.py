"""Mitsuba 3's integrals of a rough dielectric interface (include/mitsuba/render/microfacet.h:
``eval_transmittance``, ``eval_reflectance``), compiled with numba: the helper behind
roughplastic's tables (roughplastic.py).  Imported on first use (numba's import and, without its
disk cache, the compilation cost a second or two).

For a direction wi (cos_theta = mu, in the xz plane), the integral over the visible normals m of
wi (Mitsuba's sample() of the GGX or Beckmann distribution, driven by a Gauss-Legendre rule of
res x res nodes over the unit square, res = 32 for eta > 1 and 128 otherwise, as Mitsuba) of
(1 - F(wi.m)) G1(wt, m) for the refracted wt (transmittance), or F(wi.m) G1(wr, m) for the
reflected wr (reflectance); 0 where wt does not cross the surface or wr does not leave it.
"""
from __future__ import annotations

import math

import numpy as np
from numba import njit

SQRT_PI_INV = 1.0 / math.sqrt(math.pi)


def _jit(fn):
    try:
        return njit(cache=True, nogil=True, error_model="numpy")(fn)
    except RuntimeError:  # no writable cache location
        return njit(nogil=True, error_model="numpy")(fn)


@_jit
def _erfinv(x):
    """Giles' single-precision approximation (Dr.Jit's erfinv, as Mitsuba samples with it)."""
    w = -math.log((1.0 - x) * (1.0 + x))
    if w < 5.0:
        w -= 2.5
        p = 2.81022636e-08
        for c in (3.43273939e-07, -3.5233877e-06, -4.39150654e-06, 0.00021858087, -0.00125372503,
                  -0.00417768164, 0.246640727, 1.50140941):
            p = c + p * w
    else:
        w = math.sqrt(w) - 3.0
        p = -0.000200214257
        for c in (0.000100950558, 0.00134934322, -0.00367342844, 0.00573950773, -0.0076224613,
                  0.00943887047, 1.00167406, 2.83297682):
            p = c + p * w
    return p * x


@_jit
def _slopes(cos_theta, ux, uy, beckmann):
    """Mitsuba's sample_visible_11 (alpha 1)."""
    if beckmann:
        sin_theta = math.sqrt(max(0.0, 1.0 - cos_theta * cos_theta))
        tan_t = sin_theta / cos_theta
        cot_t = math.inf if tan_t == 0.0 else 1.0 / tan_t
        maxval = math.erf(cot_t)
        ux = min(max(ux, 1e-6), 1.0 - 1e-6)
        uy = min(max(uy, 1e-6), 1.0 - 1e-6)
        x = maxval - (maxval + 1.0) * math.erf(math.sqrt(-math.log(ux)))
        e = 0.0 if cot_t == math.inf else math.exp(-cot_t * cot_t)
        ux *= 1.0 + maxval + SQRT_PI_INV * tan_t * e
        for _ in range(3):
            slope = _erfinv(x)
            value = 1.0 + x + SQRT_PI_INV * tan_t * math.exp(-slope * slope) - ux
            x -= value / (1.0 - slope * tan_t)
        return _erfinv(x), _erfinv(2.0 * uy - 1.0)
    x, y = 2.0 * ux - 1.0, 2.0 * uy - 1.0  # the concentric disk
    if x == 0.0 and y == 0.0:
        px = py = 0.0
    else:
        if abs(x) < abs(y):
            r, phi = y, 0.5 * math.pi - 0.25 * math.pi * x / y
        else:
            r, phi = x, 0.25 * math.pi * y / x
        px, py = r * math.cos(phi), r * math.sin(phi)
    s = 0.5 * (1.0 + cos_theta)
    py = math.sqrt(max(0.0, 1.0 - px * px)) * (1.0 - s) + py * s
    z = math.sqrt(max(0.0, 1.0 - px * px - py * py))
    sin_t = math.sqrt(max(0.0, 1.0 - cos_theta * cos_theta))
    norm = 1.0 / (sin_t * py + cos_theta * z)
    return (cos_theta * py - sin_t * z) * norm, px * norm


@_jit
def _g1(vx, vy, vz, mx, my, mz, alpha, beckmann):
    xy = alpha * alpha * (vx * vx + vy * vy)
    if (vx * mx + vy * my + vz * mz) * vz <= 0.0:  # v sees the back of m
        return 0.0
    if xy == 0.0:
        return 1.0
    t2 = xy / (vz * vz)
    if beckmann:
        a = 1.0 / math.sqrt(t2)
        return 1.0 if a >= 1.6 else (3.535 * a + 2.181 * a * a) / (1.0 + 2.276 * a + 2.577 * a * a)
    return 2.0 / (1.0 + math.sqrt(1.0 + t2))


@_jit
def integrate(mu, nodes, weights, alpha, eta, beckmann, transmit):
    """The transmittance (or reflectance) for each cosine of mu."""
    out = np.zeros(len(mu))
    n = len(nodes)
    for k in range(len(mu)):
        wz = mu[k]
        wx = math.sqrt(1.0 - wz * wz)
        # the stretched direction's frame (Mitsuba's sample(): stretch, sincos_phi)
        px, pz = alpha * wx, wz
        ln = math.sqrt(px * px + pz * pz)
        px, pz = px / ln, pz / ln
        cos_phi, sin_phi = (1.0, 0.0) if px * px <= 4.0 * 2.0 ** -24 else (min(max(px / abs(px), -1.0), 1.0), 0.0)
        total = 0.0
        for i in range(n):
            for j in range(n):
                sx, sy = _slopes(pz, 0.5 * nodes[i] + 0.5, 0.5 * nodes[j] + 0.5, beckmann)
                tx = (cos_phi * sx - sin_phi * sy) * alpha
                ty = (sin_phi * sx + cos_phi * sy) * alpha
                ml = math.sqrt(tx * tx + ty * ty + 1.0)
                mx, my, mz = -tx / ml, -ty / ml, 1.0 / ml
                c = wx * mx + wz * mz  # wi.m (wi.y = 0)
                # Mitsuba's fresnel()
                e_it, e_ti = (eta, 1.0 / eta) if c >= 0.0 else (1.0 / eta, eta)
                ct2 = 1.0 - (1.0 - c * c) * e_ti * e_ti
                ci, ct = abs(c), math.sqrt(max(ct2, 0.0))
                if eta == 1.0:
                    f = 0.0
                elif ci == 0.0:
                    f = 1.0
                else:
                    a_s = (ci - e_it * ct) / (ci + e_it * ct)
                    a_p = (ct - e_it * ci) / (ct + e_it * ci)
                    f = 0.5 * (a_s * a_s + a_p * a_p)
                if transmit:
                    cos_t = -ct if c >= 0.0 else ct
                    s = c * e_ti + cos_t
                    ox, oy, oz = mx * s - wx * e_ti, my * s, mz * s - wz * e_ti
                    if oz * wz >= 0.0:
                        continue
                    g = _g1(ox, oy, oz, mx, my, mz, alpha, beckmann) * (1.0 - f)
                else:
                    ox, oy, oz = 2.0 * c * mx - wx, 2.0 * c * my, 2.0 * c * mz - wz
                    if oz <= 0.0 or wz <= 0.0:
                        continue
                    g = _g1(ox, oy, oz, mx, my, mz, alpha, beckmann) * f
                if g == g:
                    total += g * weights[i] * weights[j] * 0.25
        out[k] = total
    return out
