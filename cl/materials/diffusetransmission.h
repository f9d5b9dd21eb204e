/* Diffuse reflection and transmission ("diffusetransmission"): pbrt-v4's DiffuseTransmissionBxDF, a
 * thin sheet (paper, a lampshade, leaves) that scatters Lambertian on both sides.
 *
 * Parameters (Material fields): albedo the reflectance R, and T, the transmittance, at DT_TRANSMITTANCE
 * of its block in `table` (pyopencl_rt/scene/materials/diffusetransmission.py; linear RGB in [0, 1]).
 *
 *   f(wo, wi) = R / pi with wo and wi on the same side, T / pi on opposite sides (no refraction: the
 *   relative index is 1)
 *   sampled cosine-weighted on wo's side with probability pr = max(R) / (max(R) + max(T)), else on
 *   the other side: pdf = |cos_i| / pi times pr or 1 - pr; the weight is R / pr or T / (1 - pr)
 *
 * Two-sided.  Where R and T are both 0 it scatters nothing (weight and pdf 0).  Over the lanes
 * (cl/render/lanes.h), in the local frame of the dispatch (wo.z >= 0); lanes outside `active` give 0.
 */
#ifndef PYOPENCL_RT_DIFFUSETRANSMISSION_H
#define PYOPENCL_RT_DIFFUSETRANSMISSION_H

#include "materials/record.h"
#include "render/sampling.h"

typedef struct {
    pvec3 r, t;
    pfloat pr; /* the probability of sampling reflection; -1 where R and T are 0 */
} DiffuseTransmissionParams;

#define DT_TRANSMITTANCE 0 /* Material.table entries 0, 1, 2 */

RT_INLINE DiffuseTransmissionParams diffusetransmission_params(const MaterialLanes *m)
{
    DiffuseTransmissionParams p = {.r = m->albedo,
                                   .t = pv3_gather(m->records, m->rec + FIELD_INDEX(Material, table) + DT_TRANSMITTANCE)};
    const pfloat mr = pv3_max3(p.r), mt = pv3_max3(p.t);
    p.pr = mr + mt > 0.0f ? mr / (mr + mt) : PFLOAT(-1.0f);
    return p;
}

/* f * |cos_i| and *pdf for local wo (wo.z >= 0) and wi on either side */
RT_INLINE pvec3 diffusetransmission_eval(const DiffuseTransmissionParams *p, pint active, pvec3 wo, pvec3 wi,
                                         pfloat *pdf)
{
    const pint ok = active & (wo.z > 0.0f) & (wi.z != 0.0f) & (p->pr >= 0.0f);
    const pint same = wi.z > 0.0f;
    const pfloat c = pabs(wi.z);
    *pdf = ok ? c * INV_PI_F * (same ? p->pr : 1.0f - p->pr) : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), pv3_scale(pv3_sel(p->t, p->r, same), c * INV_PI_F), ok);
}

/* u2 picks the side, (u0, u1) the cosine-weighted direction; the weight f |cos| / pdf */
RT_INLINE pvec3 diffusetransmission_sample(const DiffuseTransmissionParams *p, pint active, pvec3 wo, pfloat u0,
                                           pfloat u1, pfloat u2, pvec3 *wi, pfloat *pdf, pint *delta)
{
    const pvec3 h = sample_cosine_hemisphere(u0, u1);
    const pint refl = u2 < p->pr;
    const pint ok = active & (wo.z > 0.0f) & (h.z > 0.0f) & (p->pr >= 0.0f);
    *wi = pv3(h.x, h.y, refl ? h.z : -h.z);
    *delta = PINT(0);
    *pdf = ok ? pdf_cosine_hemisphere(h.z) * (refl ? p->pr : 1.0f - p->pr) : PFLOAT(0.0f);
    const pvec3 w = pv3_sel(pv3_div(p->t, ok ? 1.0f - p->pr : PFLOAT(1.0f)),
                            pv3_div(p->r, ok ? p->pr : PFLOAT(1.0f)), refl);
    return pv3_sel(pv3_zero(), w, ok);
}

#define MATERIAL_CASE_DIFFUSETRANSMISSION(X) \
    X(DIFFUSETRANSMISSION, diffusetransmission, DiffuseTransmissionParams, diffusetransmission_params(m), \
      diffusetransmission_eval(&P, K, lo, li, &q), diffusetransmission_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d), \
      pnot(PINT(0)), m->albedo)

#endif
