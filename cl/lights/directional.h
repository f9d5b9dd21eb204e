/* A directional light ("directional", pyopencl_rt/scene/lights/directional.py): irradiance E (the
 * record's rgb) on a surface perpendicular to its direction of travel `dir`, from infinitely far:
 * Le = E toward -dir, a delta light (abi.DELTA_LIGHTS), its shadow ray leaving the scene's
 * bounding sphere (ls->far).  Compiled with HAS_DELTA_LIGHTS. */
#ifndef PYOPENCL_RT_DIRECTIONAL_H
#define PYOPENCL_RT_DIRECTIONAL_H

#include "render/light_sample.h"

#ifdef HAS_DELTA_LIGHTS
RT_INLINE pint light_sample_directional(LIGHT_UNIT_PARAMS)
{
    light_sample_far(ls, lights, row, sel, ref, pv3_neg(LIGHT_V3(lights, row, dir)), LIGHT_V3(lights, row, rgb),
                     PFLOAT(1.0f));
    return sel;
}
#define LIGHT_CASE_DIRECTIONAL(X) X(directional, DIRECTIONAL)
#endif

#endif
