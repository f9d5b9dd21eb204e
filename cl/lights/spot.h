/* A spot light ("spot", pyopencl_rt/scene/lights/spot.py): a point light at p whose intensity I
 * (on its axis, local +z) falls off with the angle theta from the axis.  With l = frame (ref - p)
 * the reference point in the light's frame and cos theta = l.z / |l|, Le = I f / dist^2 with
 * Mitsuba's f (spot.cpp): 1 for cos theta >= cos beam, (cutoff - acos(cos theta)) / (cutoff -
 * beam) down to the cutoff, 0 for cos theta <= cos cutoff; or pbrt-v4's (LIGHT_SPOT_SMOOTHSTEP):
 * smoothstep(cos cutoff, cos beam, cos theta); times the texture (if any) at (u, v) = 0.5 +
 * uv_scale (l.x / l.z, l.y / l.z), which cl/scene/textures.h applies from ls->tex / tu / tv.
 * A delta light.  Compiled with HAS_DELTA_LIGHTS. */
#ifndef PYOPENCL_RT_SPOT_H
#define PYOPENCL_RT_SPOT_H

#include "render/light_sample.h"

#ifdef HAS_DELTA_LIGHTS
RT_INLINE pint light_sample_spot(LIGHT_UNIT_PARAMS)
{
    const FramedPoint q = light_frame_point(lights, row, ref);
    const pfloat cos_t = q.l.z / pv3_length(q.l, sel);
    const pfloat cos_cut = LIGHT_F(lights, row, cone), cos_beam = LIGHT_F(lights, row + 1, cone);
    /* Mitsuba: linear in the angle between the beam width and the cutoff */
    const pfloat ramp = (LIGHT_F(lights, row + 2, cone) - pacos(pclamp(cos_t, -1.0f, 1.0f))) *
                        LIGHT_F(lights, row + 3, cone);
    pfloat fm = cos_t >= cos_beam ? PFLOAT(1.0f) : ramp;
    fm = cos_t > cos_cut ? fm : PFLOAT(0.0f);
    /* pbrt-v4: smoothstep in the cosine */
    const pfloat t = cos_beam == cos_cut ? (cos_t < cos_cut ? PFLOAT(0.0f) : PFLOAT(1.0f))
                                         : pclamp((cos_t - cos_cut) / (cos_beam - cos_cut), 0.0f, 1.0f);
    const pfloat fs = t * t * (3.0f - 2.0f * t);
    const pfloat f = ((LIGHT_I(lights, row, flags) & LIGHT_SPOT_SMOOTHSTEP) != 0) ? fs : fm;
    return light_sample_framed(ls, lights, row, sel, &q, f / q.dist2);
}
#define LIGHT_CASE_SPOT(X) X(spot, SPOT)
#endif

#endif
