/* What every light's sampling shares (cl/render/lights.h and the light types of cl/lights/): the
 * LightSample it fills, the gathers of the lanes' Light records, and the steps several types take
 * (the point seen in a light's frame, the far end of an infinitely distant light's shadow ray).
 *
 * A light type's sampling is one function of LIGHT_UNIT_PARAMS (cl/lights/<name>.h, paired by
 * name with pyopencl_rt/scene/lights/<name>.py where the host has a module for it): it fills ls in
 * the lanes of `sel` (its kind's lanes among the active ones; `row` each lane's record, in floats,
 * valid in every lane) and returns the lanes that got a sample.  Over the lanes each computes what
 * the one-path code computes for its lane, so every width gives the same bits.
 */
#ifndef PYOPENCL_RT_LIGHT_SAMPLE_H
#define PYOPENCL_RT_LIGHT_SAMPLE_H

#include "scene/scene.h"
#include "render/sampling.h"

typedef struct {
    pvec3 p;     /* point on the light */
    pvec3 err;   /* bound on the rounding error of p, per coordinate (for the shadow ray's end) */
    pvec3 n;     /* unit normal of the light at p, on the emitting side facing the reference */
    pvec3 Le;    /* emitted radiance toward the reference point */
    pfloat pdf;  /* solid-angle density at the reference point (not including the pick pmf) */
    pfloat far;  /* > 0 for an infinitely distant light (directional, environment): n is then the
                  * unit direction toward it, far the shadow ray's length; 0 otherwise */
    pint delta;  /* mask of the delta lights' lanes (point, directional, spot, projector): Le is the
                  * contribution over pdf = 1, no MIS (BSDF sampling cannot hit it) */
    pint tex;    /* spot, projector: the texture that multiplies Le at uv (textures.h), else -1 */
    pfloat tu, tv;
} LightSample;

/* The parameters of every light type's sampling, and the arguments that pass them on. */
#define LIGHT_UNIT_PARAMS                                                                           \
    MESH_PARAMS, __global const float *env_map, __global const float *env_cdf,                     \
        __global const Light *lights, pint light_index, pint row, pint sel, pvec3 ref, pfloat ux,   \
        pfloat uy, LightSample *ls
#define LIGHT_UNIT_ARGS MESH_ARGS, env_map, env_cdf, lights, light_index, row, sel, ref, ux, uy, ls

/* -- the fields of the lanes' records ----------------------------------------------------------- */

#define LIGHT_F(lights, row, field) pgather((__global const float *)(lights), (row) + FIELD_INDEX(Light, field))
#define LIGHT_I(lights, row, field) pgather_int((__global const int *)(lights), (row) + FIELD_INDEX(Light, field))
#define LIGHT_V3(lights, row, field)                                                                \
    pv3(LIGHT_F(lights, row, field), LIGHT_F(lights, (row) + 1, field), LIGHT_F(lights, (row) + 2, field))

/* ls's fields in the lanes of `sel` */
RT_INLINE void light_sample_set(LightSample *ls, pint sel, pvec3 p, pvec3 err, pvec3 n, pvec3 Le, pfloat pdf)
{
    ls->p = pv3_sel(ls->p, p, sel);
    ls->err = pv3_sel(ls->err, err, sel);
    ls->n = pv3_sel(ls->n, n, sel);
    ls->Le = pv3_sel(ls->Le, Le, sel);
    ls->pdf = sel ? pdf : ls->pdf;
}

/* Length of a shadow ray from ref that leaves the scene's bounding sphere (centre, radius: the
 * record's p and radius) of a directional or environment light. */
RT_INLINE pfloat light_far(pvec3 center, pfloat radius, pvec3 ref, pint live)
{
    return pfmax((pv3_length(pv3_sub(ref, center), live) + radius) * 1.01f, PFLOAT(1e-30f));
}

/* An infinitely distant light's sample in the lanes of `sel`: the unit direction n toward it,
 * radiance Le, density pdf, and the shadow ray's far end (ls->far). */
RT_INLINE void light_sample_far(LightSample *ls, __global const Light *lights, pint row, pint sel, pvec3 ref,
                                pvec3 n, pvec3 Le, pfloat pdf)
{
    const pfloat far_t = light_far(LIGHT_V3(lights, row, p), LIGHT_F(lights, row, radius), ref, sel);
    light_sample_set(ls, sel, pv3_add(ref, pv3_scale(n, far_t)), pv3_zero(), n, Le, pdf);
    ls->far = sel ? far_t : ls->far;
}

/* A light at the record's p with a frame (spot, projector): ref - p (*to_ref), its squared length
 * and length, ref in the light's frame (*l: the rows of `frame` applied) and the texture
 * coordinates 0.5 + uv_scale (l.x / l.z, l.y / l.z). */
RT_INLINE void light_frame_point(__global const Light *lights, pint row, pvec3 ref, pvec3 *to_ref, pfloat *dist2,
                                 pfloat *dist, pvec3 *l, pfloat *u, pfloat *v)
{
    const pvec3 p = LIGHT_V3(lights, row, p);
    *to_ref = pv3_sub(ref, p);
    *dist2 = pv3_dot(*to_ref, *to_ref);
    *dist = psqrt(*dist2);
    *l = pv3(pv3_dot(LIGHT_V3(lights, row, frame), *to_ref), pv3_dot(LIGHT_V3(lights, row + 3, frame), *to_ref),
             pv3_dot(LIGHT_V3(lights, row + 6, frame), *to_ref));
    const pfloat inv_z = 1.0f / l->z;
    *u = 0.5f + LIGHT_F(lights, row, uv_scale) * (l->x * inv_z);
    *v = 0.5f + LIGHT_F(lights, row + 1, uv_scale) * (l->y * inv_z);
}

/* A spot's or projector's sample (the lanes of `sel`): Le = rgb f from p toward ref, and its
 * texture at (u, v). */
RT_INLINE pint light_sample_framed(LightSample *ls, __global const Light *lights, pint row, pint sel, pvec3 to_ref,
                                   pfloat dist2, pfloat dist, pfloat f, pfloat u, pfloat v)
{
    light_sample_set(ls, sel, LIGHT_V3(lights, row, p), pv3_zero(), pv3_scale(to_ref, 1.0f / dist),
                     pv3_scale(LIGHT_V3(lights, row, rgb), f), PFLOAT(1.0f));
    ls->delta = ls->delta | sel;
    ls->tex = sel ? LIGHT_I(lights, row, texture) : ls->tex;
    ls->tu = sel ? u : ls->tu;
    ls->tv = sel ? v : ls->tv;
    return sel & (dist2 > 0.0f);
}

#endif
