/* What an emitter's sample is (the LightSample that light_sample_all() fills, cl/render/lights.h) and
 * the radiance a surface emitter leaves: shared by the light types (cl/lights/) and the emissive
 * analytic shapes (cl/shapes/), which the shapes' intersection code includes before the lights. */
#ifndef PYOPENCL_RT_EMISSION_H
#define PYOPENCL_RT_EMISSION_H

#include "render/lanes.h"
#include "materials/record.h"

typedef struct {
    pvec3 p;     /* point on the light */
    pvec3 err;   /* bound on the rounding error of p, per coordinate (for the shadow ray's end) */
    pvec3 n;     /* unit normal of the light at p, on the emitting side facing the reference */
    pvec3 Le;    /* emitted radiance toward the reference point */
    pfloat pdf;  /* solid-angle density at the reference point (not including the pick pmf) */
    pfloat far;  /* > 0 for an infinitely distant light (directional, environment): n is then the
                  * unit direction toward it, far the shadow ray's length; 0 otherwise */
    pint delta;  /* mask of the delta lights' lanes (abi.DELTA_LIGHTS): Le is the
                  * contribution over pdf = 1, no MIS (BSDF sampling cannot hit it) */
    pint tex;    /* spot, projector, goniometric: the texture that multiplies Le at uv (textures.h), else -1 */
    pfloat tu, tv;
} LightSample;

/* ls's fields in the lanes of `sel` */
RT_INLINE void light_sample_set(LightSample *ls, pint sel, pvec3 p, pvec3 err, pvec3 n, pvec3 Le, pfloat pdf)
{
    ls->p = pv3_sel(ls->p, p, sel);
    ls->err = pv3_sel(ls->err, err, sel);
    ls->n = pv3_sel(ls->n, n, sel);
    ls->Le = pv3_sel(ls->Le, Le, sel);
    ls->pdf = sel ? pdf : ls->pdf;
}

/* Radiance leaving an emitter with material m at a point of geometric normal ng toward w. */
RT_INLINE pvec3 emitted(const MaterialLanes *m, pvec3 ng, pvec3 w)
{
    const pint dark = ((m->flags & MATERIAL_FLAG_TWO_SIDED) == 0) & (pv3_dot(ng, w) <= 0.0f);
    return pv3_sel(m->emission, pv3_zero(), dark);
}

#endif
