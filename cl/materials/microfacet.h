/* Shared pieces of the microfacet materials (conductor.h, dielectric.h, gltf.h, and the Mitsuba types).
 *
 * gltf.h's distribution (conductor.h and dielectric.h use the general one below, mf_*): isotropic
 * GGX / Trowbridge-Reitz (Walter et al. 2007, "Microfacet Models for
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

/* Heitz 2018, listing 1: a visible normal for wo (wo.z > 0) from (u0, u1) in [0, 1)^2, for the
 * distribution stretched by (ax, ay) (isotropic: ax = ay = alpha).  The hemisphere configuration:
 * stretch wo, sample the projected disk (warped toward the visible half), lift, unstretch. */
RT_INLINE pvec3 ggx_sample_vndf_aniso(pvec3 wo, pfloat ax, pfloat ay, pfloat u0, pfloat u1, pint live)
{
    const pvec3 vh = pv3_normalize(pv3(ax * wo.x, ay * wo.y, wo.z), live);
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
    return pv3_normalize(pv3(ax * nh.x, ay * nh.y, pfmax(PFLOAT(1e-7f), nh.z)), live);
}

RT_INLINE pvec3 ggx_sample_vndf(pvec3 wo, pfloat alpha, pfloat u0, pfloat u1, pint live)
{
    return ggx_sample_vndf_aniso(wo, alpha, alpha, u0, u1, live);
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


/* -- Mitsuba 3's microfacet distribution (include/mitsuba/render/microfacet.h), as the Mitsuba
 * types (roughplastic.h, principled.h, principledthin.h) use it: GGX or Beckmann, anisotropic
 * (alpha_x along the tangent, alpha_y along the bitangent), with Smith's *separable*
 * shadowing-masking G = G1(wo, m) G1(wi, m) (not the height-correlated G2 above).  conductor.h and
 * dielectric.h use it through a Microfacet record, with either masking term (mf_g).
 *
 *   GGX       D(m) = 1 / (pi ax ay ((m.x / ax)^2 + (m.y / ay)^2 + m.z^2)^2),
 *             G1(v, m) = 2 / (1 + sqrt(1 + (ax^2 v.x^2 + ay^2 v.y^2) / v.z^2))
 *   Beckmann  D(m) = exp(-((m.x / ax)^2 + (m.y / ay)^2) / m.z^2) / (pi ax ay m.z^4),
 *             G1 by Mitsuba's rational fit in a = 1 / (alpha tan(theta_v)):
 *             (3.535 a + 2.181 a^2) / (1 + 2.276 a + 2.577 a^2) for a < 1.6, else 1
 * D is 0 where D cos(theta_m) <= 1e-20; G1 is 1 at normal incidence and 0 where v sees the back
 * of m (v.m v.z <= 0).  Visible normals (D_v(m) = G1(v, m) |v.m| D(m) / v.z) are sampled with
 * Heitz 2018 stretched to ax, ay for GGX and with Mitsuba's numerical inversion of the Beckmann
 * slope distribution (Jakob 2014, "An Improved Visible Normal Sampling Routine for the Beckmann
 * Distribution"; three Newton steps, Giles' erfinv) for Beckmann. */

/* Giles 2010, "Approximating the erfinv function" (single precision) */
RT_INLINE pfloat perfinv(pfloat x)
{
    const pfloat w0 = -plog((1.0f - x) * (1.0f + x));
    const pint low = w0 < 5.0f;
    const pfloat w = low ? w0 - 2.5f : psqrt(w0) - 3.0f;
    pfloat p = low ? PFLOAT(2.81022636e-08f) : PFLOAT(-0.000200214257f);
    p = (low ? PFLOAT(3.43273939e-07f) : PFLOAT(0.000100950558f)) + p * w;
    p = (low ? PFLOAT(-3.5233877e-06f) : PFLOAT(0.00134934322f)) + p * w;
    p = (low ? PFLOAT(-4.39150654e-06f) : PFLOAT(-0.00367342844f)) + p * w;
    p = (low ? PFLOAT(0.00021858087f) : PFLOAT(0.00573950773f)) + p * w;
    p = (low ? PFLOAT(-0.00125372503f) : PFLOAT(-0.0076224613f)) + p * w;
    p = (low ? PFLOAT(-0.00417768164f) : PFLOAT(0.00943887047f)) + p * w;
    p = (low ? PFLOAT(0.246640727f) : PFLOAT(1.00167406f)) + p * w;
    p = (low ? PFLOAT(1.50140941f) : PFLOAT(2.83297682f)) + p * w;
    return p * x;
}

RT_INLINE pfloat mf_d(pvec3 m, pfloat ax, pfloat ay, pint beckmann)
{
    const pfloat c2 = m.z * m.z;
    const pfloat x = m.x / ax, y = m.y / ay;
    const pfloat s = x * x + y * y + c2;
    pfloat r = 1.0f / (PI_F * ax * ay * (s * s));
    if (pany(beckmann)) r = beckmann ? pexp(-(x * x + y * y) / c2) / (PI_F * ax * ay * (c2 * c2)) : r;
    return r * m.z > 1e-20f ? r : PFLOAT(0.0f);
}

RT_INLINE pfloat mf_g1(pvec3 v, pvec3 m, pfloat ax, pfloat ay, pint beckmann)
{
    const pfloat xy = (ax * v.x) * (ax * v.x) + (ay * v.y) * (ay * v.y);
    const pfloat t2 = xy / (v.z * v.z);
    pfloat r = 2.0f / (1.0f + psqrt(1.0f + t2));
    if (pany(beckmann)) {
        const pfloat a = 1.0f / psqrt(t2), a2 = a * a;
        r = beckmann ? (a >= 1.6f ? PFLOAT(1.0f) : (3.535f * a + 2.181f * a2) / (1.0f + 2.276f * a + 2.577f * a2)) : r;
    }
    r = xy == 0.0f ? PFLOAT(1.0f) : r;
    return pv3_dot(v, m) * v.z <= 0.0f ? PFLOAT(0.0f) : r;
}

/* The density of visible normals of v (v.z > 0), Mitsuba's pdf(): D(m) G1(v, m) |v.m| / v.z */
RT_INLINE pfloat mf_vndf_pdf(pvec3 v, pvec3 m, pfloat ax, pfloat ay, pint beckmann)
{
    return mf_d(m, ax, ay, beckmann) * mf_g1(v, m, ax, ay, beckmann) * pabs(pv3_dot(v, m)) / v.z;
}

/* Smith's Lambda(v) of the same distribution (G1 = 1 / (1 + Lambda) away from the side test):
 * GGX (-1 + sqrt(1 + (ax^2 v.x^2 + ay^2 v.y^2) / v.z^2)) / 2, written without cancellation;
 * Beckmann the Lambda of Mitsuba's rational G1 fit, (1 - 1.259 a + 0.396 a^2) / (3.535 a + 2.181 a^2)
 * for a = 1 / (alpha tan(theta_v)) < 1.6, else 0.  Infinite for v.z == 0. */
RT_INLINE pfloat mf_lambda(pvec3 v, pfloat ax, pfloat ay, pint beckmann)
{
    const pfloat cos2 = v.z * v.z;
    const pfloat t2 = ((ax * v.x) * (ax * v.x) + (ay * v.y) * (ay * v.y)) / cos2;
    pfloat l = 0.5f * t2 / (1.0f + psqrt(1.0f + t2));
    if (pany(beckmann)) {
        const pfloat a = 1.0f / psqrt(t2), a2 = a * a;
        const pfloat lb = a >= 1.6f ? PFLOAT(0.0f) : (1.0f - 1.259f * a + 0.396f * a2) / (3.535f * a + 2.181f * a2);
        l = beckmann ? lb : l;
    }
    return ((cos2 > 1e-30f) & pisfinite(l)) ? l : PFLOAT(INFINITY);
}

/* A rough conductor's or dielectric's distribution, per lane: alpha_x along the frame's tangent,
 * alpha_y along its bitangent (each at least 1e-4, Mitsuba's floor), Beckmann or GGX, and the
 * shadowing-masking term: Smith's height-correlated G2 = 1 / (1 + Lambda(wo) + Lambda(wi))
 * (pbrt-v4; the default) or, where `separable`, Mitsuba's G1(wo, m) G1(wi, m). */
typedef struct {
    pfloat ax, ay;
    pint beckmann, separable; /* masks */
} Microfacet;

/* G(wo, wi) for the microfacet normal m (both directions on m's front, which the callers check) */
RT_INLINE pfloat mf_g(const Microfacet *d, pvec3 wo, pvec3 wi, pvec3 m)
{
    pfloat g = 1.0f / (1.0f + mf_lambda(wo, d->ax, d->ay, d->beckmann) + mf_lambda(wi, d->ax, d->ay, d->beckmann));
    if (pany(d->separable))
        g = d->separable ? mf_g1(wo, m, d->ax, d->ay, d->beckmann) * mf_g1(wi, m, d->ax, d->ay, d->beckmann) : g;
    return g;
}

/* The weight G / G1(wo) of a visible-normal sample m of wo leaving along wi: (1 + Lambda_o) /
 * (1 + Lambda_o + Lambda_i) (1 for a grazing wo, 0 for a grazing wi, never NaN), or G1(wi, m)
 * where separable (Mitsuba's roughconductor / roughdielectric weight) */
RT_INLINE pfloat mf_g_over_g1(const Microfacet *d, pvec3 wo, pvec3 wi, pvec3 m)
{
    const pfloat lo = mf_lambda(wo, d->ax, d->ay, d->beckmann), li = mf_lambda(wi, d->ax, d->ay, d->beckmann);
    pfloat g = pisfinite(li) ? 1.0f / (1.0f + li / (1.0f + lo)) : PFLOAT(0.0f);
    if (pany(d->separable)) g = d->separable ? mf_g1(wi, m, d->ax, d->ay, d->beckmann) : g;
    return g;
}

/* The Beckmann slopes of visible normals for alpha = 1 at cos_theta (Mitsuba's sample_visible_11) */
RT_INLINE void mf_beckmann_slopes(pfloat cos_theta, pfloat u0, pfloat u1, pfloat *sx, pfloat *sy)
{
    const pfloat tan_theta = psqrt(pfmax(PFLOAT(0.0f), 1.0f - cos_theta * cos_theta)) / cos_theta;
    const pfloat cot_theta = 1.0f / tan_theta;
    const pfloat maxval = perf(cot_theta);
    u0 = pclamp(u0, 1e-6f, 1.0f - 1e-6f);
    u1 = pclamp(u1, 1e-6f, 1.0f - 1e-6f);
    pfloat x = maxval - (maxval + 1.0f) * perf(psqrt(-plog(u0)));
    u0 = u0 * (1.0f + maxval + 0.564189583547756f * tan_theta * pexp(-cot_theta * cot_theta));
    for (int i = 0; i < 3; ++i) {
        const pfloat slope = perfinv(x);
        const pfloat value = 1.0f + x + 0.564189583547756f * tan_theta * pexp(-slope * slope) - u0;
        const pfloat derivative = 1.0f - slope * tan_theta;
        x = x - value / derivative;
    }
    *sx = perfinv(x);
    *sy = perfinv(2.0f * u1 - 1.0f);
}

/* A visible normal of v (v.z > 0) from (u0, u1) in [0, 1)^2 */
RT_INLINE pvec3 mf_sample_vndf(pvec3 v, pfloat ax, pfloat ay, pint beckmann, pfloat u0, pfloat u1, pint live)
{
    const pint ggx = live & pnot(beckmann), bk = live & beckmann;
    pvec3 m = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    if (pany(ggx)) m = pv3_sel(m, ggx_sample_vndf_aniso(v, ax, ay, u0, u1, ggx), ggx); /* Heitz 2018 */
    if (pany(bk)) { /* Mitsuba: stretch, slopes for alpha 1, rotate, unstretch */
        const pvec3 vp = pv3_normalize(pv3(ax * v.x, ay * v.y, v.z), bk);
        const pfloat s2 = vp.x * vp.x + vp.y * vp.y;
        const pfloat inv = 1.0f / psqrt(s2);
        const pint flat = s2 <= 4.0f * 5.9604645e-8f;
        const pfloat cos_phi = flat ? PFLOAT(1.0f) : pclamp(vp.x * inv, -1.0f, 1.0f);
        const pfloat sin_phi = flat ? PFLOAT(0.0f) : pclamp(vp.y * inv, -1.0f, 1.0f);
        pfloat sx, sy;
        mf_beckmann_slopes(vp.z, u0, u1, &sx, &sy);
        const pfloat tx = (cos_phi * sx - sin_phi * sy) * ax, ty = (sin_phi * sx + cos_phi * sy) * ay;
        m = pv3_sel(m, pv3_normalize(pv3(-tx, -ty, PFLOAT(1.0f)), bk), bk);
    }
    return m;
}

#endif
