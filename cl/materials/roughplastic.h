/* Mitsuba 3's rough plastic ("roughplastic"): a diffuse base under a rough dielectric coat
 * (GGX or Beckmann microfacets), with Mitsuba's approximation of the internal scattering (Mitsuba
 * 3's src/bsdfs/roughplastic.cpp, after Weidlich & Wilkie 2007; the formulas are Mitsuba's, the
 * code ours).
 *
 * Parameters (Material fields):
 *   albedo       diffuse_reflectance d of the base
 *   specular     specular_reflectance s: scales the coat's reflection (1: physical)
 *   ior          eta = int_ior / ext_ior
 *   alpha        the distribution's alpha (isotropic), at least 1e-4 (Mitsuba clamps it so)
 *   flags        MATERIAL_FLAG_BECKMANN: Beckmann (else GGX); MATERIAL_FLAG_NONLINEAR
 *   table        T(cos): the coat's transmittance for light arriving from outside at cos(theta),
 *                64 values at cos = k / 63 interpolated linearly (Mitsuba's table: the integral
 *                over visible normals m of (1 - F(wo.m)) G1(wt, m), wt the refracted direction;
 *                computed on the host, pyopencl_rt/scene/materials/roughplastic.py)
 *   fdr          the coat's internal reflectance: the cosine-weighted hemispherical mean of its
 *                reflectance at 1 / eta (host, as Mitsuba)
 *   spec_weight  w = mean(s) / (mean(d) + mean(s)) (host)
 *
 * Model, in the local frame with z = the normal on wo's side (two-sided here; Mitsuba's is black
 * from behind), h = normalize(wo + wi), both directions above the surface:
 *   f cos_i = s F(wo.h) D(h) G1(wo, h) G1(wi, h) / (4 cos_o)
 *           + d' / eta^2 T(cos_o) T(cos_i) cos_i / pi,
 *   d' = d / (1 - fdr), or d / (1 - d fdr) with `nonlinear`; F the exact dielectric Fresnel
 *   reflectance, D and G1 those of cl/materials/microfacet.h's Mitsuba section.
 * Sampling: the specular lobe (visible normals of wo) with probability
 *   p_s = (1 - T(cos_o)) w / ((1 - T(cos_o)) w + T(cos_o)(1 - w)), else cosine-weighted;
 *   pdf = p_s D(h) G1(wo, h) / (4 cos_o) + (1 - p_s) cos_i / pi, weight f cos_i / pdf.  A
 *   microfacet sample reflected below the surface fails.
 *
 * Over the lanes (cl/render/lanes.h): RoughPlasticParams holds each lane's parameters and where
 * its table lies (`table`: the float index of the lane's Material.table in `records`); lanes
 * outside `active` give 0 (*pdf = 0, *delta = 0).
 */
#ifndef PYOPENCL_RT_ROUGHPLASTIC_H
#define PYOPENCL_RT_ROUGHPLASTIC_H

#include "materials/plastic.h"
#include "materials/record.h"

typedef struct {
    PlasticParams s; /* plastic's parameters (the smooth coating's) */
    pfloat alpha;
    pint beckmann; /* mask */
    __global const float *records;
    pint table;
} RoughPlasticParams;

/* T(cos), Mitsuba's lerp_gather over the 64 entries (every lane reads its own table) */
RT_INLINE pfloat roughplastic_transmittance(const RoughPlasticParams *p, pfloat cos_theta)
{
    const pfloat x = pclamp(cos_theta, 0.0f, 1.0f) * (float)(ROUGH_TRANSMITTANCE_RES - 1);
    pint i = convert_pint(x);
    i = i > ROUGH_TRANSMITTANCE_RES - 2 ? PINT(ROUGH_TRANSMITTANCE_RES - 2) : i;
    const pfloat v0 = pgather(p->records, p->table + i), v1 = pgather(p->records, p->table + i + 1);
    const pfloat t = x - convert_pfloat(i);
    return (v0 - v0 * t) + v1 * t;
}

/* f * cos_i and *pdf for local wo, wi, given t_o = T(wo.z) and the specular probability ps */
RT_INLINE pvec3 roughplastic_eval_given(const RoughPlasticParams *p, pint ok, pvec3 wo, pvec3 wi, pfloat t_o,
                                        pfloat ps, pfloat *pdf)
{
    const pfloat cos_o = wo.z, cos_i = wi.z;
    const pvec3 h = pv3_normalize(pv3_add(wo, wi), ok);
    const pfloat d = mf_d(h, p->alpha, p->alpha, p->beckmann);
    const pfloat g1o = mf_g1(wo, h, p->alpha, p->alpha, p->beckmann);
    const pfloat g = g1o * mf_g1(wi, h, p->alpha, p->alpha, p->beckmann);
    const pfloat F = fresnel_dielectric(pv3_dot(wo, h), p->s.eta);
    const pvec3 spec = pv3_scale(p->s.specular, F * d * g / (4.0f * cos_o));
    const pfloat t_i = roughplastic_transmittance(p, cos_i);
    const pfloat inv_eta2 = 1.0f / (p->s.eta * p->s.eta);
    const pvec3 diff = pv3_scale(plastic_internal(p->s.diffuse, p->s.fdr, p->s.nonlinear),
                                 INV_PI_F * inv_eta2 * cos_i * t_o * t_i);
    const pvec3 f = pv3_add(spec, diff);
    const pfloat q = d * g1o / (4.0f * cos_o) * ps + (1.0f - ps) * cos_i * INV_PI_F;
    const pint good = ok & pisfinite(f.x + f.y + f.z) & pisfinite(q) & (q >= 0.0f);
    *pdf = good ? q : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), f, good);
}

RT_INLINE pvec3 roughplastic_eval(const RoughPlasticParams *p, pint active, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    const pint ok = active & (wo.z > 0.0f) & (wi.z > 0.0f);
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    const pfloat t_o = roughplastic_transmittance(p, wo.z);
    return roughplastic_eval_given(p, ok, wo, wi, t_o, plastic_spec_prob(1.0f - t_o, t_o, p->s.spec_weight), pdf);
}

/* Samples wi: u2 picks the lobe, (u0, u1) the direction.  Returns f cos / pdf, sets *pdf and
 * *delta (always 0).  *wi: the sampled direction, also where the sample failed after drawing
 * one; (0, 0, 1) where none was drawn (wo below the surface, lanes outside `active`). */
RT_INLINE pvec3 roughplastic_sample(const RoughPlasticParams *p, pint active, pvec3 wo, pfloat u0, pfloat u1,
                                    pfloat u2, pvec3 *wi, pfloat *pdf, pint *delta)
{
    const pint up = active & (wo.z > 0.0f);
    const pfloat t_o = roughplastic_transmittance(p, wo.z);
    const pfloat ps = plastic_spec_prob(1.0f - t_o, t_o, p->s.spec_weight);
    const pint spec = up & (u2 < ps);
    const pint diffuse = up & pnot(spec);
    pvec3 li = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    if (pany(spec)) {
        const pvec3 m = mf_sample_vndf(wo, p->alpha, p->alpha, p->beckmann, u0, u1, spec);
        li = pv3_sel(li, reflect_about(wo, m), spec);
    }
    if (pany(diffuse)) li = pv3_sel(li, sample_cosine_hemisphere(u0, u1), diffuse);
    const pint drawn = up & (li.z > 0.0f);
    *wi = li;
    *delta = PINT(0);
    *pdf = PFLOAT(0.0f);
    if (!pany(drawn)) return pv3_zero();
    pfloat q;
    const pvec3 f = roughplastic_eval_given(p, drawn, wo, li, t_o, ps, &q);
    const pvec3 w = pv3_div(f, q);
    const pint ok = drawn & (q > 0.0f) & pisfinite(w.x + w.y + w.z);
    *pdf = ok ? q : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), w, ok);
}

/* plastic's parameters and the rough coating's (its transmittance table lies in the record) */
RT_INLINE RoughPlasticParams roughplastic_params(const MaterialLanes *m)
{
    const RoughPlasticParams p = {.s = plastic_params(m), .alpha = pfmax(m->alpha, PFLOAT(1e-4f)),
                                  .beckmann = (m->flags & MATERIAL_FLAG_BECKMANN) != 0, .records = m->records,
                                  .table = m->rec + FIELD_INDEX(Material, table)};
    return p;
}

#define MATERIAL_CASE_ROUGHPLASTIC(X) \
    X(ROUGHPLASTIC, roughplastic, RoughPlasticParams, roughplastic_params(m), roughplastic_eval(&P, K, lo, li, &q), \
      roughplastic_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d), pnot(PINT(0)), m->albedo)

#endif
