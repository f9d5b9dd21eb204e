/* A point light ("point", pyopencl_rt/scene/lights/point.py): intensity I [W/sr] (the record's
 * rgb) at p, Le = I / dist^2 toward ref.  A delta light (abi.DELTA_LIGHTS): pdf 1 and MIS weight 1
 * (BSDF sampling never hits it).  Compiled with HAS_DELTA_LIGHTS. */
#ifndef PYOPENCL_RT_POINT_H
#define PYOPENCL_RT_POINT_H

#include "render/light_sample.h"

#ifdef HAS_DELTA_LIGHTS
RT_INLINE pint light_sample_point(LIGHT_UNIT_PARAMS)
{
    const pvec3 p = LIGHT_V3(lights, row, p);
    const pvec3 to_ref = pv3_sub(ref, p);
    const pfloat dist2 = pv3_dot(to_ref, to_ref);
    light_sample_set(ls, sel, p, pv3_zero(), pv3_scale(to_ref, 1.0f / psqrt(dist2)),
                     pv3_div(LIGHT_V3(lights, row, rgb), dist2), PFLOAT(1.0f));
    return sel & (dist2 > 0.0f);
}
#define LIGHT_CASE_POINT(X) X(point, POINT)
#endif

#endif
