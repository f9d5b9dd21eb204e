/* Dielectrics: smooth glass and rough (GGX microfacet) glass ("dielectric").
 *
 * Parameters (Material fields):
 *   ior     index of refraction of the inside (the side the geometric normal points away from:
 *           a sphere's interior, the back of a triangle), relative to the outside (taken as 1).
 *           The relative index eta = eta_t / eta_i seen by wo is ior when wo is outside
 *           (front) and 1 / ior when it is inside.  ior = 1 is an invisible interface.
 *   alpha   GGX roughness alpha in [0, 1]; below 1e-3 (or for ior = 1) the interface is smooth.
 *
 * Lobes, in the local frame with z = the normal on wo's side (wo.z >= 0):
 *   smooth:  reflection wi = (-wo.x, -wo.y, wo.z) with probability F = Fr(cos_o, eta) (exact
 *            unpolarised Fresnel; F = 1 beyond the critical angle: total internal reflection),
 *            weight 1; otherwise refraction by Snell's law, eta sin(theta_t) = sin(theta_o),
 *            weight 1 / eta^2.  Both are delta lobes: eval() is 0, the sample is flagged delta.
 *   rough:   (Walter et al. 2007; pbrt-v4's DielectricBxDF)
 *            reflection    f = D G2 F(wo.h) / (4 cos_o cos_i),  h = normalize(wo + wi)
 *            transmission  f = D G2 (1 - F(wo.h)) |wi.h| |wo.h| / (|cos_o cos_i| (eta wi.h + wo.h)^2),
 *                          h = +-normalize(wo + eta wi) facing z
 *            a visible normal h of wo is sampled (Heitz 2018), then reflection with probability
 *            F(wo.h), else refraction about h:
 *            pdf = D_wo(h) F / (4 wo.h)  or  D_wo(h) (1 - F) eta^2 |wi.h| / (eta wi.h + wo.h)^2,
 *            weights G2 / G1(wo) and G2 / (G1(wo) eta^2).  Samples that leave on the wrong side
 *            fail (weight 0); the pdf integrates to the probability of success.
 *
 * The 1 / eta^2 factor of transmission is pbrt-v4's and Mitsuba 3's for radiance transport
 * (radiance is compressed by eta^2 entering a denser medium), so f is reciprocal in the
 * generalised sense f(wi -> wo) = (eta_i / eta_o)^2 f(wo -> wi), eta_x being the index of the
 * side direction x lies on.  Energy (flux) is conserved: the refraction weight times eta^2, plus
 * the reflection weight, never exceeds 1, and a closed object of this material inside a
 * uniform emitter renders exactly the emitter's radiance.
 *
 *   tint    (the Material's specular field) multiplies both lobes; 1 for clear glass.
 */
#ifndef PYOPENCL_RT_DIELECTRIC_H
#define PYOPENCL_RT_DIELECTRIC_H

#include "materials/microfacet.h"

RT_INLINE int dielectric_is_smooth(float alpha, float eta)
{
    return microfacet_is_smooth(alpha) || eta == 1.0f;
}

/* f * |cos_i| and *pdf for local wo (wo.z >= 0) and wi; eta = relative index seen by wo. */
RT_INLINE float3 dielectric_eval(float alpha, float eta, float3 tint, float3 wo, float3 wi, float *pdf)
{
    *pdf = 0.0f;
    const float cos_o = wo.z, cos_i = wi.z;
    if (dielectric_is_smooth(alpha, eta) || cos_o <= 0.0f || cos_i == 0.0f) return (float3)(0.0f);
    const int reflect = cos_i > 0.0f;
    const float etap = reflect ? 1.0f : eta;
    float3 h = wo + etap * wi;
    const float len2 = dot(h, h);
    if (!(len2 > 1e-12f)) return (float3)(0.0f);
    h *= rsqrt(len2);
    if (h.z < 0.0f) h = -h;
    const float wh = dot(wo, h), ih = dot(wi, h);
    /* discard back-facing microfacets */
    if (wh <= 0.0f || ih * cos_i <= 0.0f) return (float3)(0.0f);
    const float F = fresnel_dielectric(wh, eta);
    const float d = ggx_d(h, alpha);
    const float g = ggx_g2(wo, wi, alpha);
    const float pdf_h = ggx_vndf_pdf(wo, h, alpha);
    float f, p;
    if (reflect) {
        f = d * g * F / (4.0f * cos_o);
        p = pdf_h * F / (4.0f * wh);
    } else {
        const float den = wh + eta * ih; /* > 0: h is along wo + eta wi */
        const float den2 = den * den;
        if (!(den2 > 0.0f)) return (float3)(0.0f);
        f = d * g * (1.0f - F) * fabs(ih) * wh / (cos_o * den2);
        p = pdf_h * (1.0f - F) * eta * eta * fabs(ih) / den2;
    }
    if (!isfinite(f) || !isfinite(p) || !(p >= 0.0f)) return (float3)(0.0f);
    *pdf = p;
    return tint * f;
}

/* Samples wi from u (u.xy: the microfacet normal, u.z: reflection or refraction); returns
 * f |cos| / pdf, sets *pdf (0 for delta samples and failures) and *delta. */
RT_INLINE float3 dielectric_sample(float alpha, float eta, float3 tint, float3 wo, float3 u, float3 *wi, float *pdf,
                                   int *delta)
{
    *pdf = 0.0f;
    *delta = 0;
    if (wo.z <= 0.0f) return (float3)(0.0f);
    if (dielectric_is_smooth(alpha, eta)) {
        const float F = fresnel_dielectric(wo.z, eta);
        *delta = 1;
        if (u.z < F) {
            *wi = (float3)(-wo.x, -wo.y, wo.z);
            return tint;
        }
        if (!refract_about(wo, (float3)(0.0f, 0.0f, 1.0f), eta, wi)) { *delta = 0; return (float3)(0.0f); }
        return tint / (eta * eta);
    }
    const float3 h = ggx_sample_vndf(wo, alpha, u.xy);
    const float wh = dot(wo, h);
    if (wh <= 0.0f) return (float3)(0.0f);
    const float F = fresnel_dielectric(wh, eta);
    const float pdf_h = ggx_vndf_pdf(wo, h, alpha);
    float p;
    float w;
    if (u.z < F) {
        *wi = reflect_about(wo, h);
        if (wi->z <= 0.0f) return (float3)(0.0f);
        p = pdf_h * F / (4.0f * wh);
        w = ggx_g2_over_g1(wo, *wi, alpha);
    } else {
        if (!refract_about(wo, h, eta, wi) || wi->z >= 0.0f) return (float3)(0.0f);
        const float ih = dot(*wi, h);
        const float den = wh + eta * ih;
        p = pdf_h * (1.0f - F) * eta * eta * fabs(ih) / (den * den);
        w = ggx_g2_over_g1(wo, -*wi, alpha) / (eta * eta);
    }
    if (!(p > 0.0f) || !isfinite(p) || !isfinite(w)) return (float3)(0.0f);
    *pdf = p;
    return tint * w;
}

#endif
