/* Lambertian diffuse reflection ("diffuse").
 *
 * f(wo, wi) = albedo / pi for wo and wi on the same side of the surface, 0 otherwise.  The
 * material is two-sided, as pbrt's DiffuseMaterial and Mitsuba's twosided(diffuse): the frame
 * is flipped to the side wo lies on.  Sampling is cosine-weighted (pdf = cos(theta_i) / pi), so
 * the sample weight f * cos / pdf is exactly the albedo.
 *
 * Parameters: albedo (linear RGB in [0, 1]).
 *
 * Over the lanes (cl/render/lanes.h), as every material: lanes outside `active` give 0 (and
 * *pdf = 0; diffuse_sample sets their *wi to n).
 */
#ifndef PYOPENCL_RT_DIFFUSE_H
#define PYOPENCL_RT_DIFFUSE_H

#include "render/sampling.h"

/* n is the unit normal on the side of wo.  Returns f * |cos(theta_i)|, sets *pdf. */
RT_INLINE pvec3 diffuse_eval(pvec3 albedo, pint active, pvec3 n, pvec3 wi, pfloat *pdf)
{
    const pfloat cos_i = pv3_dot(n, wi);
    const pint ok = active & pnot(cos_i <= 0.0f);
    *pdf = ok ? cos_i * INV_PI_F : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), pv3_scale(albedo, cos_i * INV_PI_F), ok);
}

/* Samples wi from (u0, u1); returns the weight f * cos / pdf (= albedo) and sets *pdf. */
RT_INLINE pvec3 diffuse_sample(pvec3 albedo, pint active, pvec3 n, pfloat u0, pfloat u1, pvec3 *wi, pfloat *pdf)
{
    pvec3 t, b;
    make_onb(n, &t, &b);
    const pvec3 h = sample_cosine_hemisphere(u0, u1);
    *wi = pv3_sel(n, pv3_normalize(to_world(h, t, b, n), active), active);
    const pfloat p = pdf_cosine_hemisphere(h.z);
    const pint ok = active & pnot(p <= 0.0f);
    *pdf = active ? p : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), albedo, ok);
}

/* Diffuse is shaded before the local frame (cl/materials/dispatch.h), and by every type not
 * compiled in: no case among the framed types. */
#define MATERIAL_CASE_DIFFUSE(X)

#endif
