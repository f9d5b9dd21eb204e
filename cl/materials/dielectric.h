/* Dielectrics: smooth glass and rough (microfacet) glass ("dielectric").
 *
 * Parameters (Material fields):
 *   ior     index of refraction of the inside (the side the geometric normal points away from:
 *           a sphere's interior, the back of a triangle), relative to the outside (taken as 1).
 *           The relative index eta = eta_t / eta_i seen by wo is ior when wo is outside
 *           (front) and 1 / ior when it is inside.  ior = 1 is an invisible interface.
 *   alpha   microfacet roughness alpha in [0, 1]; below 1e-3 (or for ior = 1) the interface is
 *           smooth.  The distribution (GGX or Beckmann), anisotropy (alpha along the tangent,
 *           alpha_v along the bitangent) and shadowing-masking term are the conductor's
 *           (conductor.h: MATERIAL_FLAG_BECKMANN, MATERIAL_FLAG_ANISOTROPIC, MATERIAL_FLAG_SEPARABLE).
 *
 * Lobes, in the local frame with z = the normal on wo's side (wo.z >= 0):
 *   smooth:  reflection wi = (-wo.x, -wo.y, wo.z) with probability F = Fr(cos_o, eta) (exact
 *            unpolarised Fresnel; F = 1 beyond the critical angle: total internal reflection),
 *            weight 1; otherwise refraction by Snell's law, eta sin(theta_t) = sin(theta_o),
 *            weight 1 / eta^2.  Both are delta lobes: eval() is 0, the sample is flagged delta.
 *   rough:   (Walter et al. 2007; pbrt-v4's DielectricBxDF)
 *            reflection    f = D G F(wo.h) / (4 cos_o cos_i),  h = normalize(wo + wi)
 *            transmission  f = D G (1 - F(wo.h)) |wi.h| |wo.h| / (|cos_o cos_i| (eta wi.h + wo.h)^2),
 *                          h = +-normalize(wo + eta wi) facing z
 *            a visible normal h of wo is sampled (Heitz 2018), then reflection with probability
 *            F(wo.h), else refraction about h:
 *            pdf = D_wo(h) F / (4 wo.h)  or  D_wo(h) (1 - F) eta^2 |wi.h| / (eta wi.h + wo.h)^2,
 *            weights G / G1(wo) and G / (G1(wo) eta^2).  Samples that leave on the wrong side
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
 *
 * Over the lanes (cl/render/lanes.h): the distribution, eta and tint per lane; lanes outside `active`
 * give 0 (*pdf = 0, *delta = 0).
 */
#ifndef PYOPENCL_RT_DIELECTRIC_H
#define PYOPENCL_RT_DIELECTRIC_H

#include "materials/microfacet.h"
#include "materials/record.h"

/* mask: `smooth` (the distribution's lanes below the threshold) or an invisible interface */
RT_INLINE pint dielectric_is_smooth(pint smooth, pfloat eta)
{
    return smooth | (eta == 1.0f);
}

/* f * |cos_i| and *pdf for local wo (wo.z >= 0) and wi; eta = relative index seen by wo; d the
 * distribution, `smooth` its lanes that are smooth. */
RT_INLINE pvec3 dielectric_eval(const Microfacet *md, pint smooth, pfloat eta, pvec3 tint, pint active, pvec3 wo,
                                pvec3 wi, pfloat *pdf)
{
    const pfloat cos_o = wo.z, cos_i = wi.z;
    pint ok = active & pnot(dielectric_is_smooth(smooth, eta) | (cos_o <= 0.0f) | (cos_i == 0.0f));
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    const pint reflect = cos_i > 0.0f;
    const pfloat etap = reflect ? PFLOAT(1.0f) : eta;
    pvec3 h = pv3_add(wo, pv3_scale(wi, etap));
    const pfloat len2 = pv3_dot(h, h);
    ok &= len2 > 1e-12f;
    h = pv3_scale(h, microfacet_rsqrt(len2));
    h = pv3_sel(h, pv3_neg(h), h.z < 0.0f);
    const pfloat wh = pv3_dot(wo, h), ih = pv3_dot(wi, h);
    /* discard back-facing microfacets */
    ok &= pnot((wh <= 0.0f) | (ih * cos_i <= 0.0f));
    const pfloat F = fresnel_dielectric(wh, eta);
    const pfloat d = mf_d(h, md->ax, md->ay, md->beckmann);
    const pfloat g = mf_g(md, wo, wi, h);
    const pfloat pdf_h = mf_vndf_pdf(wo, h, md->ax, md->ay, md->beckmann);
    /* reflection */
    const pfloat f_r = d * g * F / (4.0f * cos_o);
    const pfloat p_r = pdf_h * F / (4.0f * wh);
    /* transmission */
    const pfloat den = wh + eta * ih; /* > 0: h is along wo + eta wi */
    const pfloat den2 = den * den;
    const pfloat f_t = d * g * (1.0f - F) * pabs(ih) * wh / (cos_o * den2);
    const pfloat p_t = pdf_h * (1.0f - F) * eta * eta * pabs(ih) / den2;
    ok &= reflect | (den2 > 0.0f);
    const pfloat f = reflect ? f_r : f_t, p = reflect ? p_r : p_t;
    ok &= pisfinite(f) & pisfinite(p) & (p >= 0.0f);
    *pdf = ok ? p : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), pv3_scale(tint, f), ok);
}

/* Samples wi from (u0, u1) (the microfacet normal) and u2 (reflection or refraction); returns
 * f |cos| / pdf, sets *pdf (0 for delta samples and failures) and *delta (mask).  *wi: the
 * sampled direction, also where the sample failed after drawing one; (0, 0, 1) where none was
 * drawn (wo below the surface, total internal reflection of a refraction, a back-facing
 * microfacet normal, lanes outside `active`). */
RT_INLINE pvec3 dielectric_sample(const Microfacet *md, pint smooth_d, pfloat eta, pvec3 tint, pint active, pvec3 wo,
                                  pfloat u0, pfloat u1, pfloat u2, pvec3 *wi, pfloat *pdf, pint *delta)
{
    const pint up = active & pnot(wo.z <= 0.0f);
    const pint smooth = dielectric_is_smooth(smooth_d, eta);
    const pint rough = up & pnot(smooth);
    /* the microfacet normal: the normal itself for the smooth interface */
    pvec3 h = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    if (pany(rough)) h = pv3_sel(h, mf_sample_vndf(wo, md->ax, md->ay, md->beckmann, u0, u1, rough), rough);
    const pfloat wh = pv3_dot(wo, h);
    const pint facing = smooth | pnot(wh <= 0.0f); /* rough: a back-facing h fails */
    const pfloat F = fresnel_dielectric(smooth ? wo.z : wh, eta);
    const pint refl = u2 < F;
    pvec3 t;
    const pint tok = refract_about(wo, h, eta, &t, up & facing & pnot(refl));
    const pvec3 r = pv3_sel(reflect_about(wo, h), pv3(-wo.x, -wo.y, wo.z), smooth);
    const pvec3 none = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    const pvec3 li = pv3_sel(none, pv3_sel(t, r, refl), up & facing & (refl | tok));
    const pint sd = up & smooth & (refl | tok); /* a delta sample */
    /* the smooth interface's weight: tint, or tint / eta^2 refracted */
    pvec3 w = pv3_sel(pv3_div(tint, eta * eta), tint, refl);
    pfloat p = PFLOAT(0.0f);
    pint ok = sd;
    if (pany(rough)) {
        const pfloat pdf_h = mf_vndf_pdf(wo, h, md->ax, md->ay, md->beckmann);
        const pfloat ih = pv3_dot(li, h);
        const pfloat den = wh + eta * ih;
        const pfloat pr = refl ? pdf_h * F / (4.0f * wh) : pdf_h * (1.0f - F) * eta * eta * pabs(ih) / (den * den);
        pfloat wr = mf_g_over_g1(md, wo, li, h);
        wr = refl ? wr : wr / (eta * eta);
        const pint rok = rough & facing & (refl ? pnot(li.z <= 0.0f) : tok & pnot(li.z >= 0.0f)) & (pr > 0.0f) &
                         pisfinite(pr) & pisfinite(wr);
        w = pv3_sel(w, pv3_scale(tint, wr), rough);
        p = rok ? pr : p;
        ok |= rok;
    }
    *wi = li;
    *pdf = p;
    *delta = sd;
    return pv3_sel(pv3_zero(), w, ok);
}

/* A thin sheet (MATERIAL_FLAG_THIN: Mitsuba's thindielectric): reflection with probability R = F + T^2 F /
 * (1 - F^2) (F = Fr(|cos_o|, eta), T = 1 - F: the sheet's inter-reflections summed), else straight through
 * (wi = -wo); both delta, weight tint.  No refraction: the path's eta_scale is unchanged (dielectric_eta 1). */
RT_INLINE pvec3 thin_dielectric_sample(pfloat eta, pvec3 tint, pint active, pvec3 wo, pfloat u2, pvec3 *wi,
                                       pfloat *pdf, pint *delta)
{
    pfloat r = fresnel_dielectric(pabs(wo.z), eta);
    const pfloat t = 1.0f - r;
    r = r < 1.0f ? r + t * t * r / (1.0f - r * r) : r;
    const pint refl = u2 < r;
    *wi = pv3_sel(pv3_neg(wo), pv3(-wo.x, -wo.y, wo.z), refl);
    *pdf = PFLOAT(0.0f);
    *delta = active;
    return pv3_sel(pv3_zero(), tint, active);
}

/* a dielectric's distribution and the relative index seen by wo (dielectric_eta) */
typedef struct {
    Microfacet d;
    pint smooth;
    pfloat eta;
} DielectricParams;

RT_INLINE DielectricParams dielectric_params(const MaterialLanes *m, pint front)
{
    DielectricParams p;
    p.d = microfacet_params(m, &p.smooth);
    p.eta = dielectric_eta(m, front);
    return p;
}

/* A dielectric's sample: it refracts, or (MATERIAL_FLAG_THIN, Mitsuba's thindielectric) a thin sheet
 * lets light through unbent or reflects it. */
RT_INLINE pvec3 dielectric_or_thin_sample(const MaterialLanes *m, const DielectricParams *p, pint active, pvec3 lo,
                                          pfloat u0, pfloat u1, pfloat u2, pvec3 *wl, pfloat *q, pint *d)
{
    pvec3 g = dielectric_sample(&p->d, p->smooth, p->eta, m->specular, active, lo, u0, u1, u2, wl, q, d);
    const pint thin = active & ((m->flags & MATERIAL_FLAG_THIN) != 0);
    if (pany(thin)) {
        pvec3 wt;
        pfloat qt;
        pint dt;
        g = pv3_sel(g, thin_dielectric_sample(m->ior, m->specular, thin, lo, u2, &wt, &qt, &dt), thin);
        *wl = pv3_sel(*wl, wt, thin);
        *q = thin ? qt : *q;
        *d = thin ? dt : *d;
    }
    return g;
}

#define MATERIAL_CASE_DIELECTRIC(X) \
    X(DIELECTRIC, dielectric, DielectricParams, dielectric_params(m, front), \
      dielectric_eval(&P.d, P.smooth, P.eta, m->specular, K, lo, li, &q), \
      dielectric_or_thin_sample(m, &P, K, lo, u0, u1, u2, &wl, &q, &d), \
      pnot(dielectric_is_smooth(material_smooth(m), m->ior)), m->specular)

#endif
