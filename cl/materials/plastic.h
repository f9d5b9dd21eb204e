/* Mitsuba 3's smooth plastic ("plastic"): a diffuse base under a smooth dielectric coat, with the
 * internal scattering between them summed in closed form (Mitsuba 3's src/bsdfs/plastic.cpp; the
 * formulas are Mitsuba's, this code is ours).
 *
 * Parameters (Material fields):
 *   albedo       diffuse_reflectance d of the base (RGB in [0, 1])
 *   specular     specular_reflectance s: scales the coat's mirror reflection (1: physical)
 *   ior          eta = int_ior / ext_ior, the coat's relative index
 *   fdr          fdr_int, the coat's diffuse Fresnel reflectance seen from inside (computed on
 *                the host: Mitsuba's fresnel_diffuse_reflectance(1 / eta))
 *   spec_weight  w = mean(s) / (mean(d) + mean(s)) (computed on the host, as Mitsuba does)
 *   flags        MATERIAL_FLAG_NONLINEAR: Mitsuba's `nonlinear`
 *
 * Model, in the local frame with z = the normal on wo's side (two-sided, as every material here;
 * Mitsuba's plastic is black from behind), F(c) = the exact dielectric Fresnel reflectance at
 * eta, F_o = F(cos_o), F_i = F(cos_i):
 *   specular  a delta lobe: the mirror direction with weight s F_o
 *   diffuse   f cos_i = d' / eta^2 (1 - F_o) (1 - F_i) cos_i / pi,
 *             d' = d / (1 - fdr)  (the light trapped under the coat, scattered again; with
 *             `nonlinear`, d / (1 - d fdr), which darkens and saturates the colour)
 * Sampling: the specular lobe with probability p_s = F_o w / (F_o w + (1 - F_o)(1 - w)), else
 * the cosine-weighted diffuse lobe; eval() and the pdf cover the diffuse lobe, pdf =
 * (1 - p_s) cos_i / pi.  Both lobes need wo and wi above the surface.
 *
 * Over the lanes (cl/render/lanes.h): PlasticParams holds each lane's parameters; lanes outside
 * `active` give 0 (*pdf = 0, *delta = 0).
 */
#ifndef PYOPENCL_RT_PLASTIC_H
#define PYOPENCL_RT_PLASTIC_H

#include "materials/microfacet.h"
#include "materials/record.h"

typedef struct {
    pvec3 diffuse, specular;
    pfloat eta, fdr, spec_weight;
    pint nonlinear; /* mask */
} PlasticParams;

/* d / (1 - fdr), or d / (1 - d fdr) with `nonlinear`: the base seen through the internal
 * reflections (shared with roughplastic.h) */
RT_INLINE pvec3 plastic_internal(pvec3 d, pfloat fdr, pint nonlinear)
{
    return pv3(d.x / (1.0f - (nonlinear ? d.x * fdr : fdr)), d.y / (1.0f - (nonlinear ? d.y * fdr : fdr)),
               d.z / (1.0f - (nonlinear ? d.z * fdr : fdr)));
}

/* the probability of the specular lobe from the coat's reflectance r and transmittance t (F_o
 * and 1 - F_o, or 1 - T and T for the rough coat) and the weight w: r w / (r w + t (1 - w)); w
 * where both vanish */
RT_INLINE pfloat plastic_spec_prob(pfloat r, pfloat t, pfloat w)
{
    const pfloat ps = r * w, pd = t * (1.0f - w);
    const pfloat sum = ps + pd;
    return sum > 0.0f ? ps / sum : w;
}

/* the diffuse lobe's f pi: d' (1 - F_o)(1 - F_i) / eta^2 (both cosines > 0) */
RT_INLINE pvec3 plastic_diffuse(const PlasticParams *p, pfloat cos_o, pfloat cos_i)
{
    const pfloat f_o = fresnel_dielectric(cos_o, p->eta), f_i = fresnel_dielectric(cos_i, p->eta);
    const pfloat inv_eta2 = 1.0f / (p->eta * p->eta);
    return pv3_scale(plastic_internal(p->diffuse, p->fdr, p->nonlinear), inv_eta2 * (1.0f - f_o) * (1.0f - f_i));
}

/* f * cos_i and *pdf (of the diffuse lobe) for local wo, wi. */
RT_INLINE pvec3 plastic_eval(const PlasticParams *p, pint active, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    const pint ok = active & (wo.z > 0.0f) & (wi.z > 0.0f);
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    const pfloat f_o = fresnel_dielectric(wo.z, p->eta);
    const pfloat ps = plastic_spec_prob(f_o, 1.0f - f_o, p->spec_weight);
    const pvec3 f = pv3_scale(plastic_diffuse(p, wo.z, wi.z), wi.z * INV_PI_F);
    const pfloat q = (1.0f - ps) * wi.z * INV_PI_F;
    const pint good = ok & pisfinite(f.x + f.y + f.z) & pisfinite(q);
    *pdf = good ? q : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), f, good);
}

/* Samples wi: u2 picks the lobe, (u0, u1) the diffuse direction.  Returns f cos / pdf; sets
 * *pdf (0 for the delta mirror and failures) and *delta (mask).  *wi: (0, 0, 1) where nothing
 * was drawn (wo below the surface, lanes outside `active`). */
RT_INLINE pvec3 plastic_sample(const PlasticParams *p, pint active, pvec3 wo, pfloat u0, pfloat u1, pfloat u2,
                               pvec3 *wi, pfloat *pdf, pint *delta)
{
    const pint up = active & (wo.z > 0.0f);
    const pfloat f_o = fresnel_dielectric(wo.z, p->eta);
    const pfloat ps = plastic_spec_prob(f_o, 1.0f - f_o, p->spec_weight);
    const pint spec = up & (u2 < ps);
    const pint diffuse = up & pnot(spec);
    pvec3 li = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    if (pany(diffuse)) li = pv3_sel(li, sample_cosine_hemisphere(u0, u1), diffuse);
    li = pv3_sel(li, pv3(-wo.x, -wo.y, wo.z), spec);
    const pint drawn = diffuse & (li.z > 0.0f);
    pvec3 r = pv3_zero();
    pfloat q = PFLOAT(0.0f);
    if (pany(drawn)) {
        const pfloat pd = 1.0f - ps;
        q = pd * li.z * INV_PI_F;
        const pvec3 w = pv3_div(plastic_diffuse(p, wo.z, li.z), pd);
        const pint ok = drawn & (q > 0.0f) & pisfinite(w.x + w.y + w.z);
        r = pv3_sel(r, w, ok);
        q = ok ? q : PFLOAT(0.0f);
    }
    if (pany(spec)) r = pv3_sel(r, pv3_scale(p->specular, f_o / ps), spec);
    *wi = li;
    *pdf = q;
    *delta = spec;
    return r;
}

/* The parameters from the lanes' Material fields. */
RT_INLINE PlasticParams plastic_params(const MaterialLanes *m)
{
    const PlasticParams p = {.diffuse = m->albedo, .specular = m->specular, .eta = m->ior, .fdr = m->fdr,
                             .spec_weight = m->spec_weight, .nonlinear = (m->flags & MATERIAL_FLAG_NONLINEAR) != 0};
    return p;
}

#define MATERIAL_CASE_PLASTIC(X) \
    X(PLASTIC, plastic, PlasticParams, plastic_params(m), plastic_eval(&P, K, lo, li, &q), \
      plastic_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d), pnot(PINT(0)), m->albedo)

#endif
