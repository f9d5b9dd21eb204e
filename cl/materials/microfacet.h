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
 *
 * Over the lanes (cl/render/lanes.h): every function computes all lanes; where the scalar
 * formulation returned early, a mask selects the early value instead.  `live` (of the functions
 * that normalize) is the mask of the lanes whose result is used: only those take the rescaling
 * fallback of pv3_normalize.  Tests: tests/scene/test_materials.py.
 */
#ifndef PYOPENCL_RT_MICROFACET_H
#define PYOPENCL_RT_MICROFACET_H

#include "render/sampling.h"

#define MICROFACET_SMOOTH_ALPHA 1e-3f

/* mask */
RT_INLINE pint microfacet_is_smooth(pfloat alpha) { return alpha < MICROFACET_SMOOTH_ALPHA; }

/* 1 / sqrt(x), as cpu_builtins.h's rsqrt (the scalar code's rsqrt on the CPU) */
RT_INLINE pfloat microfacet_rsqrt(pfloat x) { return 1.0f / psqrt(x); }

/* GGX D(h) for a unit h in the local frame; 0 for h.z <= 0.  Computed from tan^2 (not from
 * 1 - cos^2) so that narrow lobes keep their precision. */
RT_INLINE pfloat ggx_d(pvec3 h, pfloat alpha)
{
    const pfloat cos2 = h.z * h.z;
    const pfloat tan2 = (h.x * h.x + h.y * h.y) / cos2;
    const pfloat a2 = alpha * alpha;
    const pfloat e = 1.0f + tan2 / a2;
    const pfloat d = 1.0f / (PI_F * a2 * cos2 * cos2 * e * e);
    return ((h.z <= 0.0f) | pnot(pisfinite(d))) ? PFLOAT(0.0f) : d;
}

/* Smith Lambda(w) for GGX; w in the local frame (its sign of z does not matter).  Written as
 * a^2 t^2 / (1 + sqrt(1 + a^2 t^2)) / 2 to avoid cancellation; infinite for w.z == 0. */
RT_INLINE pfloat ggx_lambda(pvec3 w, pfloat alpha)
{
    const pfloat cos2 = w.z * w.z;
    const pfloat x = alpha * alpha * (w.x * w.x + w.y * w.y) / cos2;
    const pfloat l = 0.5f * x / (1.0f + psqrt(1.0f + x));
    return ((cos2 > 1e-30f) & pisfinite(l)) ? l : PFLOAT(INFINITY);
}

RT_INLINE pfloat ggx_g1(pvec3 w, pfloat alpha) { return 1.0f / (1.0f + ggx_lambda(w, alpha)); }

/* Height-correlated Smith G2; 0 when either direction is grazing. */
RT_INLINE pfloat ggx_g2(pvec3 wo, pvec3 wi, pfloat alpha)
{
    return 1.0f / (1.0f + ggx_lambda(wo, alpha) + ggx_lambda(wi, alpha));
}

/* G2(wo, wi) / G1(wo) = (1 + Lambda_o) / (1 + Lambda_o + Lambda_i), the weight of a VNDF sample;
 * written so that a grazing wo (Lambda_o = inf) gives 1 and a grazing wi gives 0, never NaN. */
RT_INLINE pfloat ggx_g2_over_g1(pvec3 wo, pvec3 wi, pfloat alpha)
{
    const pfloat lo = ggx_lambda(wo, alpha), li = ggx_lambda(wi, alpha);
    return pisfinite(li) ? 1.0f / (1.0f + li / (1.0f + lo)) : PFLOAT(0.0f);
}

/* Density of visible normals D_wo(h) = G1(wo) max(0, wo.h) D(h) / wo.z for wo.z > 0. */
RT_INLINE pfloat ggx_vndf_pdf(pvec3 wo, pvec3 h, pfloat alpha)
{
    const pfloat wh = pv3_dot(wo, h);
    const pfloat denom = wo.z * (1.0f + ggx_lambda(wo, alpha)); /* wo.z / G1(wo) */
    const pfloat p = wh * ggx_d(h, alpha) / denom;
    const pint fail = (wo.z <= 0.0f) | (wh <= 0.0f) | pnot(denom > 0.0f) | pnot(pisfinite(denom)) | pnot(pisfinite(p));
    return fail ? PFLOAT(0.0f) : p;
}

/* Heitz 2018, listing 1: a visible normal for wo (wo.z > 0) from (u0, u1) in [0, 1)^2.  The
 * hemisphere configuration: stretch wo, sample the projected disk (warped toward the visible
 * half), lift, unstretch. */
RT_INLINE pvec3 ggx_sample_vndf(pvec3 wo, pfloat alpha, pfloat u0, pfloat u1, pint live)
{
    const pvec3 vh = pv3_normalize(pv3(alpha * wo.x, alpha * wo.y, wo.z), live);
    const pfloat lensq = vh.x * vh.x + vh.y * vh.y;
    const pfloat rl = microfacet_rsqrt(lensq);
    const pvec3 t1 = pv3_sel(pv3(PFLOAT(1.0f), PFLOAT(0.0f), PFLOAT(0.0f)), pv3(-vh.y * rl, vh.x * rl, 0.0f * rl),
                             lensq > 0.0f);
    const pvec3 t2 = pv3_cross(vh, t1);
    const pfloat r = psqrt(u0);
    const pfloat phi = 2.0f * PI_F * u1;
    const pfloat p1 = r * pcos(phi);
    pfloat p2 = r * psin(phi);
    const pfloat s = 0.5f * (1.0f + vh.z);
    p2 = (1.0f - s) * psqrt(pfmax(PFLOAT(0.0f), 1.0f - p1 * p1)) + s * p2;
    const pvec3 nh = pv3_add(pv3_add(pv3_scale(t1, p1), pv3_scale(t2, p2)),
                             pv3_scale(vh, psqrt(pfmax(PFLOAT(0.0f), 1.0f - p1 * p1 - p2 * p2))));
    return pv3_normalize(pv3(alpha * nh.x, alpha * nh.y, pfmax(PFLOAT(1e-7f), nh.z)), live);
}

/* Mirror reflection of w about the unit h. */
RT_INLINE pvec3 reflect_about(pvec3 w, pvec3 h) { return pv3_sub(pv3_scale(h, 2.0f * pv3_dot(w, h)), w); }

/* Refraction of w (pointing away from the surface, w.h > 0) about the unit h into the medium of
 * relative index eta = eta_t / eta_i (the side opposite to w).  Returns the mask of the lanes
 * refracted (not totally internally reflected); *wt (unit, on the other side of h) is set in
 * every lane but meaningful only in those. */
RT_INLINE pint refract_about(pvec3 w, pvec3 h, pfloat eta, pvec3 *wt, pint live)
{
    const pfloat cos_i = pv3_dot(w, h);
    const pfloat sin2_t = pfmax(PFLOAT(0.0f), 1.0f - cos_i * cos_i) / (eta * eta);
    const pint ok = pnot(sin2_t >= 1.0f);
    const pfloat cos_t = psqrt(1.0f - sin2_t);
    *wt = pv3_normalize(pv3_add(pv3_div(pv3_neg(w), eta), pv3_scale(h, cos_i / eta - cos_t)), live & ok);
    return ok;
}

/* Unpolarised Fresnel reflectance of a dielectric interface for light arriving at cos_i
 * (> 0: from the side with relative index eta = eta_t / eta_i; < 0: from the other side).
 * 1 beyond the critical angle.  pbrt-v4's FrDielectric. */
RT_INLINE pfloat fresnel_dielectric(pfloat cos_i, pfloat eta)
{
    cos_i = pclamp(cos_i, -1.0f, 1.0f);
    const pint inside = cos_i < 0.0f;
    eta = inside ? 1.0f / eta : eta;
    cos_i = inside ? -cos_i : cos_i;
    const pfloat sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    const pfloat cos_t = psqrt(pfmax(PFLOAT(0.0f), 1.0f - sin2_t));
    const pfloat r_par = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    const pfloat r_perp = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    return sin2_t >= 1.0f ? PFLOAT(1.0f) : pclamp(0.5f * (r_par * r_par + r_perp * r_perp), 0.0f, 1.0f);
}

/* One channel of fresnel_conductor: c = cos_i clamped, c2 = c^2, s2 = 1 - c2, s4 = s2^2. */
RT_INLINE pfloat fresnel_conductor1(pfloat c, pfloat c2, pfloat s2, pfloat s4, pfloat eta, pfloat k)
{
    const pfloat t1 = eta * eta - k * k - s2;
    const pfloat a2b2 = psqrt(t1 * t1 + 4.0f * k * k * eta * eta);
    const pfloat a = psqrt(pfmax(0.5f * (a2b2 + t1), PFLOAT(0.0f)));
    const pfloat term1 = a2b2 + c2, term2 = 2.0f * c * a;
    const pfloat rs = (term1 - term2) / pfmax(term1 + term2, PFLOAT(1e-30f));
    const pfloat term3 = a2b2 * c2 + s4, term4 = term2 * s2;
    const pfloat rp = rs * (term3 - term4) / pfmax(term3 + term4, PFLOAT(1e-30f));
    return pclamp(0.5f * (rs + rp), 0.0f, 1.0f);
}

/* Unpolarised Fresnel reflectance of a conductor of complex index eta + i k (per channel,
 * relative to the outside medium) at cos_i in [0, 1]: the closed form of Mitsuba 3's
 * fresnel_conductor (after Born & Wolf). */
RT_INLINE pvec3 fresnel_conductor(pfloat cos_i, pvec3 eta, pvec3 k)
{
    const pfloat c = pclamp(cos_i, 1e-7f, 1.0f);
    const pfloat c2 = c * c, s2 = 1.0f - c2, s4 = s2 * s2;
    return pv3(fresnel_conductor1(c, c2, s2, s4, eta.x, k.x), fresnel_conductor1(c, c2, s2, s4, eta.y, k.y),
               fresnel_conductor1(c, c2, s2, s4, eta.z, k.z));
}

/* Schlick's approximation F0 + (1 - F0) (1 - cos)^5. */
RT_INLINE pfloat fresnel_schlick1(pfloat f0, pfloat cos_i)
{
    const pfloat m = pclamp(1.0f - cos_i, 0.0f, 1.0f);
    const pfloat m2 = m * m;
    return f0 + (1.0f - f0) * (m2 * m2 * m);
}

RT_INLINE pvec3 fresnel_schlick(pvec3 f0, pfloat cos_i)
{
    const pfloat m = pclamp(1.0f - cos_i, 0.0f, 1.0f);
    const pfloat m2 = m * m;
    const pfloat m5 = m2 * m2 * m;
    return pv3(f0.x + (1.0f - f0.x) * m5, f0.y + (1.0f - f0.y) * m5, f0.z + (1.0f - f0.z) * m5);
}

#endif
