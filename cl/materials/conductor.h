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
 */
#ifndef PYOPENCL_RT_CONDUCTOR_H
#define PYOPENCL_RT_CONDUCTOR_H

#include "materials/microfacet.h"

typedef struct {
    float3 f0, eta, k;
    float alpha;
    int schlick; /* 1: Fresnel from f0 (Schlick), 0: from eta + i k */
} ConductorParams;

RT_INLINE float3 conductor_fresnel(const ConductorParams *c, float cos_i)
{
    return c->schlick ? fresnel_schlick(c->f0, cos_i) : fresnel_conductor(cos_i, c->eta, c->k);
}

/* f * cos_i and *pdf for local wo, wi (wo.z >= 0). */
RT_INLINE float3 conductor_eval(const ConductorParams *c, float3 wo, float3 wi, float *pdf)
{
    *pdf = 0.0f;
    if (microfacet_is_smooth(c->alpha) || wo.z <= 0.0f || wi.z <= 0.0f) return (float3)(0.0f);
    const float3 hs = wo + wi;
    const float len2 = dot(hs, hs);
    if (!(len2 > 1e-12f)) return (float3)(0.0f);
    const float3 h = hs * rsqrt(len2);
    const float wh = dot(wo, h);
    if (wh <= 0.0f) return (float3)(0.0f);
    const float d = ggx_d(h, c->alpha);
    const float pdf_h = ggx_vndf_pdf(wo, h, c->alpha);
    const float p = pdf_h / (4.0f * wh);
    const float3 f = conductor_fresnel(c, wh) * (d * ggx_g2(wo, wi, c->alpha) / (4.0f * wo.z));
    if (!isfinite(p) || !isfinite(f.x + f.y + f.z)) return (float3)(0.0f);
    *pdf = p;
    return f;
}

/* Samples wi from u (u.z unused); returns f cos / pdf, sets *pdf (0 for a delta sample or a
 * failure) and *delta. */
RT_INLINE float3 conductor_sample(const ConductorParams *c, float3 wo, float3 u, float3 *wi, float *pdf, int *delta)
{
    *pdf = 0.0f;
    *delta = 0;
    if (wo.z <= 0.0f) return (float3)(0.0f);
    if (microfacet_is_smooth(c->alpha)) {
        *wi = (float3)(-wo.x, -wo.y, wo.z);
        *delta = 1;
        return conductor_fresnel(c, wo.z);
    }
    const float3 h = ggx_sample_vndf(wo, c->alpha, u.xy);
    const float wh = dot(wo, h);
    *wi = reflect_about(wo, h);
    if (wi->z <= 0.0f || wh <= 0.0f) return (float3)(0.0f);
    const float p = ggx_vndf_pdf(wo, h, c->alpha) / (4.0f * wh);
    if (!(p > 0.0f) || !isfinite(p)) return (float3)(0.0f);
    *pdf = p;
    return conductor_fresnel(c, wh) * ggx_g2_over_g1(wo, *wi, c->alpha); /* F G2 / G1(wo) */
}

#endif
