/* Conductors: smooth ("mirror") and rough (GGX microfacet) metal reflection ("conductor").
 *
 * Parameters (Material fields):
 *   alpha      GGX roughness alpha in [0, 1] (alpha = roughness^2 for the perceptual roughness
 *              of the scene format); below 1e-3 the surface is a perfect mirror (a delta lobe)
 *   eta, k     complex index of refraction eta + i k per RGB channel (relative to the outside),
 *              e.g. gold (0.183, 0.421, 1.373) + i (3.424, 2.346, 1.770); exact unpolarised
 *              Fresnel reflectance (Mitsuba 3's fresnel_conductor)
 *   f0         used instead of eta, k when the material has MATERIAL_FLAG_CONDUCTOR_F0: the
 *              reflectance at normal incidence, Schlick's approximation F0 + (1 - F0)(1 - cos)^5.
 *              f0 = 1 is an ideal mirror (F = 1 at every angle).
 *
 * Lobes and densities, in the local frame (z = the normal on wo's side: the material is
 * two-sided, as pbrt-v4's and Mitsuba 3's conductors seen from either side):
 *   smooth:  wi = (-wo.x, -wo.y, wo.z) with weight F(cos_o); a delta lobe, so eval() is 0 and
 *            the sample is flagged delta (no pdf)
 *   rough:   f = D(h) G2(wo, wi) F(wo.h) / (4 cos_o cos_i), h = normalize(wo + wi), both
 *            directions above the surface (Walter et al. 2007 with Smith height-correlated G2);
 *            sampled with the visible normals of wo (Heitz 2018):
 *            pdf = D_wo(h) / (4 wo.h), weight f cos_i / pdf = F G2 / G1(wo).  A sampled h that
 *            reflects wo below the surface fails (weight 0), so the pdf integrates to the
 *            probability of success (< 1), as in pbrt-v4 and Mitsuba 3.
 *
 * Single-scattering microfacets lose the energy of light that would scatter between microfacets:
 * a rough conductor with F = 1 reflects less than 1: its directional albedo averaged over the
 * hemisphere is 0.97 at alpha = 0.1, 0.92 at 0.2, 0.70 at 0.5 and 0.41 at 1 (GGX's long tails;
 * tests/scene/test_materials.py integrates these and checks a furnace render against them).
 *
 * Over the lanes (cl/render/lanes.h): ConductorParams holds each lane's parameters; lanes
 * outside `active` give 0 (*pdf = 0, *delta = 0).
 */
#ifndef PYOPENCL_RT_CONDUCTOR_H
#define PYOPENCL_RT_CONDUCTOR_H

#include "materials/microfacet.h"

typedef struct {
    pvec3 f0, eta, k;
    pfloat alpha;
    pint schlick; /* mask: Fresnel from f0 (Schlick), else from eta + i k */
} ConductorParams;

RT_INLINE pvec3 conductor_fresnel(const ConductorParams *c, pfloat cos_i)
{
    pvec3 f = pv3_zero();
    if (pany(pnot(c->schlick))) f = fresnel_conductor(cos_i, c->eta, c->k);
    if (pany(c->schlick)) f = pv3_sel(f, fresnel_schlick(c->f0, cos_i), c->schlick);
    return f;
}

/* f * cos_i and *pdf for local wo, wi (wo.z >= 0). */
RT_INLINE pvec3 conductor_eval(const ConductorParams *c, pint active, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    pint ok = active & pnot(microfacet_is_smooth(c->alpha) | (wo.z <= 0.0f) | (wi.z <= 0.0f));
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    const pvec3 hs = pv3_add(wo, wi);
    const pfloat len2 = pv3_dot(hs, hs);
    const pvec3 h = pv3_scale(hs, microfacet_rsqrt(len2));
    const pfloat wh = pv3_dot(wo, h);
    ok &= (len2 > 1e-12f) & pnot(wh <= 0.0f);
    const pfloat d = ggx_d(h, c->alpha);
    const pfloat pdf_h = ggx_vndf_pdf(wo, h, c->alpha);
    const pfloat p = pdf_h / (4.0f * wh);
    const pvec3 f = pv3_scale(conductor_fresnel(c, wh), d * ggx_g2(wo, wi, c->alpha) / (4.0f * wo.z));
    ok &= pisfinite(p) & pisfinite(f.x + f.y + f.z);
    *pdf = ok ? p : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), f, ok);
}

/* Samples wi from (u0, u1); returns f cos / pdf, sets *pdf (0 for a delta sample or a failure)
 * and *delta (mask).  *wi: the sampled direction, also where the sample failed after drawing
 * one; (0, 0, 1) where none was drawn (wo below the surface, lanes outside `active`). */
RT_INLINE pvec3 conductor_sample(const ConductorParams *c, pint active, pvec3 wo, pfloat u0, pfloat u1, pvec3 *wi,
                                 pfloat *pdf, pint *delta)
{
    const pint up = active & pnot(wo.z <= 0.0f);
    const pint smooth = up & microfacet_is_smooth(c->alpha);
    const pint rough = up & pnot(smooth);
    pvec3 li = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    pfloat p = PFLOAT(0.0f), cos_f = wo.z;
    pint ok = PINT(0);
    if (pany(rough)) {
        const pvec3 h = ggx_sample_vndf(wo, c->alpha, u0, u1, rough);
        const pfloat wh = pv3_dot(wo, h);
        li = pv3_sel(li, reflect_about(wo, h), rough);
        const pfloat pr = ggx_vndf_pdf(wo, h, c->alpha) / (4.0f * wh);
        ok = rough & pnot((li.z <= 0.0f) | (wh <= 0.0f)) & (pr > 0.0f) & pisfinite(pr);
        p = ok ? pr : p;
        cos_f = rough ? wh : cos_f;
    }
    li = pv3_sel(li, pv3(-wo.x, -wo.y, wo.z), smooth);
    *wi = li;
    *pdf = p;
    *delta = smooth;
    const pint any_weight = smooth | ok;
    if (!pany(any_weight)) return pv3_zero();
    /* F(cos_o) for the mirror; F(wo.h) G2 / G1(wo) for a microfacet sample */
    const pvec3 F = conductor_fresnel(c, cos_f);
    const pvec3 w = pv3_sel(F, pv3_scale(F, ggx_g2_over_g1(wo, li, c->alpha)), rough);
    return pv3_sel(pv3_zero(), w, any_weight);
}

#endif
