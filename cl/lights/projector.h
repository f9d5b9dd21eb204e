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
    pvec3 to_ref, l;
    pfloat dist2, dist, u, v;
    light_frame_point(lights, row, ref, &to_ref, &dist2, &dist, &l, &u, &v);
    const pint flags = LIGHT_I(lights, row, flags);
    const pint inside = (l.z > 0.0f) & (u >= 0.0f) & (u <= 1.0f) & (v >= 0.0f) & (v <= 1.0f);
    const pfloat cos_n = pv3_dot(LIGHT_V3(lights, row, dir), to_ref) / dist;
    const pfloat fp = ((flags & LIGHT_PROJECTOR_COS3) != 0) ? 1.0f / (l.z * l.z * cos_n) : 1.0f / dist2;
    return light_sample_framed(ls, lights, row, sel, to_ref, dist2, dist, inside ? fp : PFLOAT(0.0f), u, v);
}
#define LIGHT_CASE_PROJECTOR(X) X(projector, PROJECTOR)
#else
#define LIGHT_CASE_PROJECTOR(X)
#endif

#endif
