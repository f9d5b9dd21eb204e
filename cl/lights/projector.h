/* A projector ("projector", pyopencl_rt/scene/lights/projector.py): a pinhole at p projecting
 * (u, v) = 0.5 + uv_scale (l.x / l.z, l.y / l.z) for l = frame (ref - p), l.z > 0 and (u, v) in
 * [0, 1]^2 (0 elsewhere).  Mitsuba's (projector.cpp, LIGHT_PROJECTOR_COS3): Le = rgb tex(u, v) /
 * (l.z^2 cos) with cos = dir . (ref - p) / dist, so that the irradiance on the plane at z = 1 is
 * rgb tex (rgb = pi scale irradiance); pbrt-v4's: Le = rgb tex(u, v) / dist^2.  The texture is
 * applied by cl/scene/textures.h from ls->tex / tu / tv.  A delta light.  Compiled with
 * HAS_DELTA_LIGHTS. */
#ifndef PYOPENCL_RT_PROJECTOR_H
#define PYOPENCL_RT_PROJECTOR_H

#include "render/light_sample.h"

#ifdef HAS_DELTA_LIGHTS
RT_INLINE pint light_sample_projector(LIGHT_UNIT_PARAMS)
{
    const FramedPoint q = light_frame_point(lights, row, ref);
    const pint inside = (q.l.z > 0.0f) & (q.u >= 0.0f) & (q.u <= 1.0f) & (q.v >= 0.0f) & (q.v <= 1.0f);
    const pfloat cos_n = pv3_dot(LIGHT_V3(lights, row, dir), q.to_ref) / q.dist;
    const pfloat fp = ((LIGHT_I(lights, row, flags) & LIGHT_PROJECTOR_COS3) != 0) ? 1.0f / (q.l.z * q.l.z * cos_n)
                                                                                   : 1.0f / q.dist2;
    return light_sample_framed(ls, lights, row, sel, &q, inside ? fp : PFLOAT(0.0f));
}
#define LIGHT_CASE_PROJECTOR(X) X(projector, PROJECTOR)
#endif

#endif
