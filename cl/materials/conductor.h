/* Conductors: smooth ("mirror") and rough (microfacet) metal reflection ("conductor").
 *
 * Parameters (Material fields):
 *   alpha      the microfacet roughness alpha in [0, 1] (GGX: alpha = roughness^2 for the perceptual
 *              roughness of the scene format); below 1e-3 the surface is a perfect mirror (a delta
 *              lobe).  With MATERIAL_FLAG_ANISOTROPIC alpha is alpha_u, along the frame's tangent
 *              (dp/du made orthogonal to the shading normal, as Mitsuba's sh_frame.s), and alpha_v
 *              the roughness along the bitangent; the mirror then needs both below 1e-3
 *   flags      MATERIAL_FLAG_BECKMANN: the Beckmann distribution (else GGX / Trowbridge-Reitz);
 *              MATERIAL_FLAG_SEPARABLE: Mitsuba's separable shadowing-masking G1(wo) G1(wi)
 *              (else Smith's height-correlated G2, pbrt-v4's); microfacet.h, mf_*
 *   eta, k     complex index of refraction eta + i k per RGB channel (relative to the outside),
 *              e.g. gold (0.183, 0.421, 1.373) + i (3.424, 2.346, 1.770); exact unpolarised
 *              Fresnel reflectance (Mitsuba 3's fresnel_conductor)
 *   f0         used instead of eta, k when the material has MATERIAL_FLAG_CONDUCTOR_F0: the
 *              reflectance at normal incidence, Schlick's approximation F0 + (1 - F0)(1 - cos)^5.
 *              f0 = 1 is an ideal mirror (F = 1 at every angle).
 *
 * Lobes and densities, in the local frame (z = the normal on wo's side: the material is
 * two-sided, as pbrt-v4's conductor; Mitsuba's is black from behind unless wrapped in twosided):
 *   smooth:  wi = (-wo.x, -wo.y, wo.z) with weight F(cos_o); a delta lobe, so eval() is 0 and
 *            the sample is flagged delta (no pdf)
 *   rough:   f = D(h) G(wo, wi) F(wo.h) / (4 cos_o cos_i), h = normalize(wo + wi), both
 *            directions above the surface (Walter et al. 2007); sampled with the visible normals
 *            of wo (Heitz 2018 for GGX, Jakob 2014 for Beckmann):
 *            pdf = D_wo(h) / (4 wo.h), weight f cos_i / pdf = F G / G1(wo).  A sampled h that
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
#include "materials/record.h"

typedef struct {
    pvec3 f0, eta, k;
    Microfacet d;
    pint smooth;  /* mask: a mirror */
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
    pint ok = active & pnot(c->smooth | (wo.z <= 0.0f) | (wi.z <= 0.0f));
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    const pvec3 hs = pv3_add(wo, wi);
    const pfloat len2 = pv3_dot(hs, hs);
    const pvec3 h = pv3_scale(hs, microfacet_rsqrt(len2));
    const pfloat wh = pv3_dot(wo, h);
    ok &= (len2 > 1e-12f) & pnot(wh <= 0.0f);
    const pfloat d = mf_d(h, c->d.ax, c->d.ay, c->d.beckmann);
    const pfloat pdf_h = mf_vndf_pdf(wo, h, c->d.ax, c->d.ay, c->d.beckmann);
    const pfloat p = pdf_h / (4.0f * wh);
    const pvec3 f = pv3_scale(conductor_fresnel(c, wh), d * mf_g(&c->d, wo, wi, h) / (4.0f * wo.z));
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
    const pint smooth = up & c->smooth;
    const pint rough = up & pnot(smooth);
    pvec3 li = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    pfloat p = PFLOAT(0.0f), cos_f = wo.z;
    pint ok = PINT(0);
    pvec3 h = li;
    if (pany(rough)) {
        h = mf_sample_vndf(wo, c->d.ax, c->d.ay, c->d.beckmann, u0, u1, rough);
        const pfloat wh = pv3_dot(wo, h);
        li = pv3_sel(li, reflect_about(wo, h), rough);
        const pfloat pr = mf_vndf_pdf(wo, h, c->d.ax, c->d.ay, c->d.beckmann) / (4.0f * wh);
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
    /* F(cos_o) for the mirror; F(wo.h) G / G1(wo) for a microfacet sample */
    const pvec3 F = conductor_fresnel(c, cos_f);
    const pvec3 w = pv3_sel(F, pv3_scale(F, mf_g_over_g1(&c->d, wo, li, h)), rough);
    return pv3_sel(pv3_zero(), w, any_weight);
}

/* The parameters from the lanes' Material fields. */
RT_INLINE ConductorParams conductor_params(const MaterialLanes *m)
{
    ConductorParams c = {.f0 = m->specular, .eta = m->eta, .k = m->k,
                         .schlick = (m->flags & MATERIAL_FLAG_CONDUCTOR_F0) != 0};
    c.d = microfacet_params(m, &c.smooth);
    return c;
}

/* the albedo guide (dispatch.h, material_albedo_aov): the Fresnel reflectance at the viewing angle */
RT_INLINE pvec3 conductor_albedo(const MaterialLanes *m, pfloat cos_o)
{
    const ConductorParams c = conductor_params(m);
    return conductor_fresnel(&c, cos_o);
}

#define MATERIAL_CASE_CONDUCTOR(X) \
    X(CONDUCTOR, conductor, ConductorParams, conductor_params(m), conductor_eval(&P, K, lo, li, &q), \
      conductor_sample(&P, K, lo, u0, u1, &wl, &q, &d), pnot(material_smooth(m)), conductor_albedo(m, cos_o))

#endif
