/* Rough diffuse reflection ("roughdiffuse"): the Oren-Nayar model (Oren & Nayar 1994), as Mitsuba 0.6's
 * roughdiffuse plugin defines it (pyopencl_rt/scene/materials/roughdiffuse.py).
 *
 * The surface is made of V-shaped grooves whose facets are ideal diffuse reflectors, their slopes
 * spread with standard deviation sigma (radians): shadowing, masking and one interreflection between
 * the facets make it brighter toward the light at grazing angles and flatter than Lambert's law.
 * sigma comes from Mitsuba's RMS slope alpha as sigma = alpha / sqrt(2) (Mitsuba's fit to the
 * microfacet models' alpha).  With theta_i, theta_o the polar angles, phi the azimuth between wo and
 * wi, a = max(theta_i, theta_o), b = min(theta_i, theta_o), s2 = sigma^2 and rho the albedo:
 *
 *   full model:  f = rho / pi (C1 + cos(phi) C2 tan(b) + (1 - |cos(phi)|) C3 tan((a + b) / 2))
 *                    + rho^2 / pi C4 (1 - cos(phi) (2 b / pi)^2)
 *     C1 = 1 - 0.5 s2 / (s2 + 0.33)
 *     C2 = 0.45 s2 / (s2 + 0.09) (sin(a) where cos(phi) >= 0, else sin(a) - (2 b / pi)^3)
 *     C3 = 0.125 s2 / (s2 + 0.09) (4 a b / pi^2)^2
 *     C4 = 0.17 s2 / (s2 + 0.13)          (the interreflection term)
 *   fast model (MATERIAL_FLAG_FAST_APPROX; Mitsuba's useFastApprox, the paper's qualitative model):
 *                f = rho / pi (A + B max(0, cos(phi)) sin(a) tan(b)),
 *     A = 1 - 0.5 s2 / (s2 + 0.33),  B = 0.45 s2 / (s2 + 0.09)
 *
 * cos(phi) is taken as 0 where either direction is within 1e-4 of the normal (its azimuth is
 * undefined).  sigma = 0 is Lambert's law, rho / pi.  Both directions must lie above the surface
 * (the frame's z on wo's side: two-sided, as our diffuse; Mitsuba's is black from behind, which
 * MATERIAL_FLAG_ONE_SIDED gives).  Sampling is cosine-weighted, pdf = cos(theta_i) / pi, as
 * Mitsuba's: the weight is f pi.
 *
 * Record (abi.MATERIAL): albedo rho, alpha Mitsuba's alpha, flags MATERIAL_FLAG_FAST_APPROX.
 */
#ifndef PYOPENCL_RT_ROUGHDIFFUSE_H
#define PYOPENCL_RT_ROUGHDIFFUSE_H

#include "render/lanes_math.h"
#include "render/sampling.h"
#include "materials/record.h"

typedef struct {
    pvec3 albedo;
    pfloat sigma2; /* sigma^2 = alpha^2 / 2 */
    pint fast;
} RoughDiffuseParams;

/* f |cos_i| for local wo, wi (both with z > 0 where `ok`; 0 elsewhere) */
RT_INLINE pvec3 roughdiffuse_f(const RoughDiffuseParams *p, pint ok, pvec3 wo, pvec3 wi)
{
    const pfloat cos_o = pclamp(wo.z, 0.0f, 1.0f), cos_i = pclamp(wi.z, 0.0f, 1.0f);
    const pfloat sin_o = psqrt(1.0f - cos_o * cos_o), sin_i = psqrt(1.0f - cos_i * cos_i);
    const pint azimuth = (sin_o > 1e-4f) & (sin_i > 1e-4f);
    const pfloat cos_phi = azimuth ? pclamp((wo.x * wi.x + wo.y * wi.y) / (sin_o * sin_i), -1.0f, 1.0f)
                                   : PFLOAT(0.0f);
    /* a is the larger polar angle (the smaller cosine), b the smaller */
    const pint o_steeper = cos_o > cos_i;
    const pfloat sin_a = o_steeper ? sin_i : sin_o, sin_b = o_steeper ? sin_o : sin_i;
    const pfloat cos_a = o_steeper ? cos_i : cos_o, cos_b = o_steeper ? cos_o : cos_i;
    const pfloat tan_b = sin_b / pfmax(cos_b, PFLOAT(1e-30f));
    const pfloat s2 = p->sigma2;
    const pfloat c1 = 1.0f - 0.5f * s2 / (s2 + 0.33f), k = s2 / (s2 + 0.09f);
    pfloat single = c1 + 0.45f * k * pfmax(cos_phi, PFLOAT(0.0f)) * sin_a * tan_b; /* the fast model */
    pfloat twice = PFLOAT(0.0f);
    const pint full = ok & pnot(p->fast);
    if (pany(full)) {
        const pfloat a = pacos(cos_a), b = pacos(cos_b);
        const pfloat b2pi = 2.0f * INV_PI_F * b, ab = 4.0f * INV_PI_F * INV_PI_F * a * b;
        const pfloat c2 = 0.45f * k * (cos_phi >= 0.0f ? sin_a : sin_a - b2pi * b2pi * b2pi);
        const pfloat c3 = 0.125f * k * ab * ab;
        const pfloat tan_half = (sin_a + sin_b) / pfmax(cos_a + cos_b, PFLOAT(1e-30f)); /* tan((a + b) / 2) */
        const pfloat s = c1 + cos_phi * c2 * tan_b + (1.0f - pabs(cos_phi)) * c3 * tan_half;
        single = full ? s : single;
        twice = full ? 0.17f * s2 / (s2 + 0.13f) * (1.0f - cos_phi * b2pi * b2pi) : twice;
    }
    const pvec3 rho = p->albedo;
    const pvec3 f = pv3_add(pv3_scale(rho, single), pv3_scale(pv3_mul(rho, rho), twice));
    return pv3_sel(pv3_zero(), pv3_scale(f, INV_PI_F * cos_i), ok);
}

/* f * |cos_i| and *pdf for local wo and wi */
RT_INLINE pvec3 roughdiffuse_eval(const RoughDiffuseParams *p, pint active, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    const pint ok = active & (wo.z > 0.0f) & (wi.z > 0.0f);
    *pdf = ok ? pdf_cosine_hemisphere(wi.z) : PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    return roughdiffuse_f(p, ok, wo, wi);
}

/* a cosine-weighted wi from u0, u1; the weight f |cos_i| / pdf */
RT_INLINE pvec3 roughdiffuse_sample(const RoughDiffuseParams *p, pint active, pvec3 wo, pfloat u0, pfloat u1,
                                    pvec3 *wi, pfloat *pdf, pint *delta)
{
    const pvec3 li = sample_cosine_hemisphere(u0, u1);
    const pint ok = active & (wo.z > 0.0f) & (li.z > 0.0f);
    *wi = li;
    *delta = PINT(0);
    *pdf = ok ? pdf_cosine_hemisphere(li.z) : PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    const pvec3 f = roughdiffuse_f(p, ok, wo, li);
    return pv3_sel(pv3_zero(), pv3_div(f, ok ? *pdf : PFLOAT(1.0f)), ok);
}

/* The parameters from the lanes' Material fields. */
RT_INLINE RoughDiffuseParams roughdiffuse_params(const MaterialLanes *m)
{
    const RoughDiffuseParams p = {.albedo = m->albedo, .sigma2 = 0.5f * m->alpha * m->alpha,
                                  .fast = (m->flags & MATERIAL_FLAG_FAST_APPROX) != 0};
    return p;
}

#define MATERIAL_CASE_ROUGHDIFFUSE(X) \
    X(ROUGHDIFFUSE, roughdiffuse, RoughDiffuseParams, roughdiffuse_params(m), \
      roughdiffuse_eval(&P, K, lo, li, &q), roughdiffuse_sample(&P, K, lo, u0, u1, &wl, &q, &d), pnot(PINT(0)), \
      m->albedo)

#endif
