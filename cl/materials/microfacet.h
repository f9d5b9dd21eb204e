/* Shared pieces of the microfacet materials (conductor.h, dielectric.h, gltf.h).
 *
 * Distribution: isotropic GGX / Trowbridge-Reitz (Walter et al. 2007, "Microfacet Models for
 * Refraction through Rough Surfaces"), parameter alpha (the GGX alpha; alpha = roughness^2 for
 * the perceptual roughness of glTF / Disney):
 *
 *     D(h) = 1 / (pi alpha^2 cos^4(theta_h) (1 + tan^2(theta_h) / alpha^2)^2)   for cos(theta_h) > 0
 *
 * Masking: Smith, Lambda(w) = (-1 + sqrt(1 + alpha^2 tan^2(theta))) / 2, G1 = 1 / (1 + Lambda);
 * shadowing-masking G2 is the height-correlated form 1 / (1 + Lambda(wo) + Lambda(wi)) (Heitz
 * 2014, "Understanding the Masking-Shadowing Function"), as in pbrt-v4 and Mitsuba 3.
 *
 * Sampling: the distribution of visible normals D_wo(h) = G1(wo) max(0, wo.h) D(h) / cos(theta_o)
 * (Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT 7(4)), so the weight of
 * a reflected sample is F G2 / G1(wo) <= 1.  Jacobians: reflection dh/dwi = 1 / (4 |wi.h|);
 * refraction dh/dwi = eta^2 |wi.h| / (wo.h + eta wi.h)^2 (eta = eta_i-side / eta_o-side).
 *
 * Everything here works in the local frame: z = the shading normal on wo's side.  Below
 * MICROFACET_SMOOTH_ALPHA (1e-3, pbrt-v4's threshold) a material is treated as perfectly smooth
 * (a delta lobe): D would no longer be representable in float near its peak.
 */
#ifndef PYOPENCL_RT_MICROFACET_H
#define PYOPENCL_RT_MICROFACET_H

#include "render/sampling.h"

#define MICROFACET_SMOOTH_ALPHA 1e-3f

RT_INLINE int microfacet_is_smooth(float alpha) { return alpha < MICROFACET_SMOOTH_ALPHA; }

/* GGX D(h) for a unit h in the local frame; 0 for h.z <= 0.  Computed from tan^2 (not from
 * 1 - cos^2) so that narrow lobes keep their precision. */
RT_INLINE float ggx_d(float3 h, float alpha)
{
    if (h.z <= 0.0f) return 0.0f;
    const float cos2 = h.z * h.z;
    const float tan2 = (h.x * h.x + h.y * h.y) / cos2;
    const float a2 = alpha * alpha;
    const float e = 1.0f + tan2 / a2;
    const float d = 1.0f / (PI_F * a2 * cos2 * cos2 * e * e);
    return isfinite(d) ? d : 0.0f;
}

/* Smith Lambda(w) for GGX; w in the local frame (its sign of z does not matter).  Written as
 * a^2 t^2 / (1 + sqrt(1 + a^2 t^2)) / 2 to avoid cancellation; infinite for w.z == 0. */
RT_INLINE float ggx_lambda(float3 w, float alpha)
{
    const float cos2 = w.z * w.z;
    if (!(cos2 > 1e-30f)) return INFINITY;
    const float x = alpha * alpha * (w.x * w.x + w.y * w.y) / cos2;
    const float l = 0.5f * x / (1.0f + sqrt(1.0f + x));
    return isfinite(l) ? l : INFINITY;
}

RT_INLINE float ggx_g1(float3 w, float alpha) { return 1.0f / (1.0f + ggx_lambda(w, alpha)); }

/* Height-correlated Smith G2; 0 when either direction is grazing. */
RT_INLINE float ggx_g2(float3 wo, float3 wi, float alpha)
{
    return 1.0f / (1.0f + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
}

/* G2(wo, wi) / G1(wo) = (1 + Lambda_o) / (1 + Lambda_o + Lambda_i), the weight of a VNDF sample;
 * written so that a grazing wo (Lambda_o = inf) gives 1 and a grazing wi gives 0, never NaN. */
RT_INLINE float ggx_g2_over_g1(float3 wo, float3 wi, float alpha)
{
    const float lo = ggx_lambda(wo, alpha), li = ggx_lambda(wi, alpha);
    if (!isfinite(li)) return 0.0f;
    return 1.0f / (1.0f + li / (1.0f + lo));
}

/* Density of visible normals D_wo(h) = G1(wo) max(0, wo.h) D(h) / wo.z for wo.z > 0. */
RT_INLINE float ggx_vndf_pdf(float3 wo, float3 h, float alpha)
{
    const float wh = dot(wo, h);
    if (wo.z <= 0.0f || wh <= 0.0f) return 0.0f;
    const float denom = wo.z * (1.0f + ggx_lambda(wo, alpha)); /* wo.z / G1(wo) */
    if (!(denom > 0.0f) || !isfinite(denom)) return 0.0f;
    const float p = wh * ggx_d(h, alpha) / denom;
    return isfinite(p) ? p : 0.0f;
}

/* Heitz 2018, listing 1: a visible normal for wo (wo.z > 0) from u in [0, 1)^2.  The hemisphere
 * configuration: stretch wo, sample the projected disk (warped toward the visible half), lift,
 * unstretch. */
RT_INLINE float3 ggx_sample_vndf(float3 wo, float alpha, float2 u)
{
    const float3 vh = normalize((float3)(alpha * wo.x, alpha * wo.y, wo.z));
    const float lensq = vh.x * vh.x + vh.y * vh.y;
    const float3 t1 = lensq > 0.0f ? (float3)(-vh.y, vh.x, 0.0f) * rsqrt(lensq) : (float3)(1.0f, 0.0f, 0.0f);
    const float3 t2 = cross(vh, t1);
    const float r = sqrt(u.x);
    const float phi = 2.0f * PI_F * u.y;
    const float p1 = r * cos(phi);
    float p2 = r * sin(phi);
    const float s = 0.5f * (1.0f + vh.z);
    p2 = (1.0f - s) * sqrt(fmax(0.0f, 1.0f - p1 * p1)) + s * p2;
    const float3 nh = p1 * t1 + p2 * t2 + sqrt(fmax(0.0f, 1.0f - p1 * p1 - p2 * p2)) * vh;
    return normalize((float3)(alpha * nh.x, alpha * nh.y, fmax(1e-7f, nh.z)));
}

/* Mirror reflection of w about the unit h. */
RT_INLINE float3 reflect_about(float3 w, float3 h) { return 2.0f * dot(w, h) * h - w; }

/* Refraction of w (pointing away from the surface, w.h > 0) about the unit h into the medium of
 * relative index eta = eta_t / eta_i (the side opposite to w).  Returns 0 on total internal
 * reflection, else 1 with *wt set (unit, on the other side of h). */
RT_INLINE int refract_about(float3 w, float3 h, float eta, float3 *wt)
{
    const float cos_i = dot(w, h);
    const float sin2_t = fmax(0.0f, 1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) return 0;
    const float cos_t = sqrt(1.0f - sin2_t);
    *wt = normalize(-w / eta + (cos_i / eta - cos_t) * h);
    return 1;
}

/* Unpolarised Fresnel reflectance of a dielectric interface for light arriving at cos_i
 * (> 0: from the side with relative index eta = eta_t / eta_i; < 0: from the other side).
 * 1 beyond the critical angle.  pbrt-v4's FrDielectric. */
RT_INLINE float fresnel_dielectric(float cos_i, float eta)
{
    cos_i = clamp(cos_i, -1.0f, 1.0f);
    if (cos_i < 0.0f) { eta = 1.0f / eta; cos_i = -cos_i; }
    const float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) return 1.0f;
    const float cos_t = sqrt(fmax(0.0f, 1.0f - sin2_t));
    const float r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const float r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return clamp(0.5f * (r_par * r_par + r_perp * r_perp), 0.0f, 1.0f);
}

/* Unpolarised Fresnel reflectance of a conductor of complex index eta + i k (per channel,
 * relative to the outside medium) at cos_i in [0, 1]: the closed form of Mitsuba 3's
 * fresnel_conductor (after Born & Wolf). */
RT_INLINE float3 fresnel_conductor(float cos_i, float3 eta, float3 k)
{
    const float c = clamp(cos_i, 1e-7f, 1.0f);
    const float c2 = c * c, s2 = 1.0f - c2, s4 = s2 * s2;
    const float3 t1 = eta * eta - k * k - s2;
    const float3 a2b2 = sqrt(t1 * t1 + 4.0f * k * k * eta * eta);
    const float3 a = sqrt(fmax(0.5f * (a2b2 + t1), 0.0f));
    const float3 term1 = a2b2 + c2, term2 = 2.0f * c * a;
    const float3 rs = (term1 - term2) / fmax(term1 + term2, 1e-30f);
    const float3 term3 = a2b2 * c2 + s4, term4 = term2 * s2;
    const float3 rp = rs * (term3 - term4) / fmax(term3 + term4, 1e-30f);
    return clamp(0.5f * (rs + rp), 0.0f, 1.0f);
}

/* Schlick's approximation F0 + (1 - F0) (1 - cos)^5. */
RT_INLINE float3 fresnel_schlick(float3 f0, float cos_i)
{
    const float m = clamp(1.0f - cos_i, 0.0f, 1.0f);
    const float m2 = m * m;
    return f0 + (1.0f - f0) * (m2 * m2 * m);
}

RT_INLINE float fresnel_schlick1(float f0, float cos_i)
{
    const float m = clamp(1.0f - cos_i, 0.0f, 1.0f);
    const float m2 = m * m;
    return f0 + (1.0f - f0) * (m2 * m2 * m);
}

#endif
