/* What every light's sampling shares (cl/render/lights.h and the light types of cl/lights/): the
 * LightSample it fills, the gathers of the lanes' Light records, and the steps several types take
 * (the point seen in a light's frame, the far end of an infinitely distant light's shadow ray).
 *
 * A light type's sampling is one function of LIGHT_UNIT_PARAMS (cl/lights/<name>.h, paired by
 * name with pyopencl_rt/scene/lights/<name>.py where the host has a module for it): it fills ls in
 * the lanes of `sel` (its kind's lanes among the active ones; `row` each lane's record, in floats,
 * valid in every lane) and returns the lanes that got a sample.  Over the lanes each computes what
 * the one-path code computes for its lane, so every width gives the same bits.  ls->delta is the
 * dispatch's (cl/render/lights.h), from the ABI's DELTA_LIGHTS.
 */
#ifndef PYOPENCL_RT_LIGHT_SAMPLE_H
#define PYOPENCL_RT_LIGHT_SAMPLE_H

#include "scene/scene.h"
#include "render/sampling.h"
#include "render/emission.h"


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

/* A light at the record's p with a frame (spot, projector, goniometric), seen from ref: ref - p,
 * its squared length and length, ref in the light's frame (l: the rows of `frame` applied) and the
 * texture coordinates 0.5 + uv_scale (l.x / l.z, l.y / l.z). */
typedef struct {
    pvec3 to_ref, l;
    pfloat dist2, dist, u, v;
} FramedPoint;

RT_INLINE FramedPoint light_frame_point(__global const Light *lights, pint row, pvec3 ref)
{
    FramedPoint q;
    q.to_ref = pv3_sub(ref, LIGHT_V3(lights, row, p));
    q.dist2 = pv3_dot(q.to_ref, q.to_ref);
    q.dist = psqrt(q.dist2);
    q.l = pv3(pv3_dot(LIGHT_V3(lights, row, frame), q.to_ref), pv3_dot(LIGHT_V3(lights, row + 3, frame), q.to_ref),
              pv3_dot(LIGHT_V3(lights, row + 6, frame), q.to_ref));
    const pfloat inv_z = 1.0f / q.l.z;
    q.u = 0.5f + LIGHT_F(lights, row, uv_scale) * (q.l.x * inv_z);
    q.v = 0.5f + LIGHT_F(lights, row + 1, uv_scale) * (q.l.y * inv_z);
    return q;
}

/* A framed light's sample (the lanes of `sel`): Le = rgb f from p toward ref, and its texture at
 * (q->u, q->v). */
RT_INLINE pint light_sample_framed(LightSample *ls, __global const Light *lights, pint row, pint sel,
                                   const FramedPoint *q, pfloat f)
{
    light_sample_set(ls, sel, LIGHT_V3(lights, row, p), pv3_zero(), pv3_scale(q->to_ref, 1.0f / q->dist),
                     pv3_scale(LIGHT_V3(lights, row, rgb), f), PFLOAT(1.0f));
    ls->tex = sel ? LIGHT_I(lights, row, texture) : ls->tex;
    ls->tu = sel ? q->u : ls->tu;
    ls->tv = sel ? q->v : ls->tv;
    return sel & (q->dist2 > 0.0f);
}

#endif
