/* Phase functions, shared by the media (render/media.h) and the scattering coating of a layered BSDF
 * (materials/coatedconductor.h).  Directions as media.h: wi points back along the incoming ray, wo the
 * way the path goes on; each is normalised over the sphere, so its value is its pdf. */
#ifndef PYOPENCL_RT_PHASE_H
#define PYOPENCL_RT_PHASE_H

#include "render/lanes.h"
#include "render/sampling.h"

/* Henyey-Greenstein: (1 - g^2) / (4 pi (1 + g^2 + 2 g cos)^(3/2)) with cos = dot(wo, wi) (wi pointing
 * back): g > 0 peaks at wo = -wi, forward scattering (Mitsuba's eval_hg; pbrt-v4's HenyeyGreenstein). */
RT_INLINE pfloat phase_hg(pfloat g, pfloat cos_theta)
{
    const pfloat temp = pfmax(1.0f + g * g + 2.0f * g * cos_theta, PFLOAT(1e-20f));
    return (0.25f * INV_PI_F) * (1.0f - g * g) / (temp * psqrt(temp));
}

/* p(wo, wi) = its pdf, for PHASE_ISOTROPIC (1 / 4 pi) or PHASE_HG (g) */
RT_INLINE pfloat phase_eval_pg(pint phase, pfloat g, pvec3 wi, pvec3 wo)
{
    const pfloat hg = phase_hg(g, pv3_dot(wo, wi));
    return phase == PHASE_HG ? hg : PFLOAT(0.25f * INV_PI_F);
}

/* A direction wo for wi from the uniforms (u1, u2), as Mitsuba samples it: isotropic, its
 * square_to_uniform_sphere (z = 1 - 2 u2, phi = 2 pi u1); Henyey-Greenstein, the inverse CDF of the
 * cosine to the travel direction -wi from u1 (1 - 2 u1 for |g| < 2^-24), phi = 2 pi u2, in the frame of
 * wi (make_onb, Mitsuba's Frame3f).  *pdf = the phase function's value (the sample's weight is 1). */
RT_INLINE pvec3 phase_sample_pg(pint phase, pfloat g, pvec3 wi, pfloat u1, pfloat u2, pfloat *pdf)
{
    const pint hg = phase == PHASE_HG;
    pvec3 wo = pv3_zero();
    if (!pall(hg)) wo = sample_uniform_sphere(u2, u1);
    *pdf = PFLOAT(0.25f * INV_PI_F);
    if (pany(hg)) {
        const pfloat sqr_term = (1.0f - g * g) / (1.0f - g + 2.0f * g * u1);
        pfloat cos_theta = (1.0f + g * g - sqr_term * sqr_term) / (2.0f * g);
        cos_theta = pabs(g) < 0x1.0p-24f ? 1.0f - 2.0f * u1 : cos_theta;
        cos_theta = pclamp(cos_theta, -1.0f, 1.0f);
        const pfloat sin_theta = psqrt(pfmax(PFLOAT(0.0f), 1.0f - cos_theta * cos_theta));
        const pfloat phi = 2.0f * PI_F * u2;
        pvec3 t, b;
        make_onb(wi, &t, &b);
        const pvec3 v = pv3(sin_theta * pcos(phi), sin_theta * psin(phi), -cos_theta);
        wo = pv3_sel(wo, to_world(v, t, b, wi), hg);
        *pdf = hg ? phase_hg(g, -cos_theta) : *pdf;
    }
    return wo;
}

#endif
