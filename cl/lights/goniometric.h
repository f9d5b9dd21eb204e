/* A goniometric light ("goniometric", pyopencl_rt/scene/lights/goniometric.py; pbrt-v4's
 * GoniometricLight): a point light at p whose intensity varies with the direction, I(w) = rgb
 * Y(w), Y a profile over the sphere stored as pbrt's equal-area square image (Clarberg's
 * octahedral mapping, EqualAreaSphereToSquare), looked up at its nearest texel.  w is ref's
 * direction from p in the light's frame (the record's `frame` rows: pbrt's light space with y and
 * z swapped, so the profile's pole is the light's local +y), normalised; Le = rgb Y(w) / dist^2.
 * The profile is the record's texture (ls->tex at (u, v), applied by cl/scene/textures.h; nearest
 * and clamped, as pbrt's LookupNearest); without one, Y = 1 (a point light).  A delta light.
 * Compiled with HAS_DELTA_LIGHTS. */
#ifndef PYOPENCL_RT_GONIOMETRIC_H
#define PYOPENCL_RT_GONIOMETRIC_H

#include "render/light_sample.h"

#ifdef HAS_DELTA_LIGHTS
/* pbrt-v4's EqualAreaSphereToSquare of the unit d, (u, v) in [0, 1]^2; atan(b) 2 / pi by its
 * 6th-degree minimax polynomial. */
RT_INLINE void equal_area_sphere_to_square(pvec3 d, pfloat *u, pfloat *v)
{
    const pfloat x = pabs(d.x), y = pabs(d.y), z = pabs(d.z);
    const pfloat r = psqrt(pfmax(1.0f - z, PFLOAT(0.0f)));
    const pfloat a = pfmax(x, y), b0 = pfmin(x, y);
    const pfloat b = a == 0.0f ? PFLOAT(0.0f) : b0 / (a == 0.0f ? PFLOAT(1.0f) : a);
    pfloat phi = 0.406758566246788489601959989e-5f +
                 b * (0.636226545274016134946890922156f +
                      b * (0.61572017898280213493197203466e-2f +
                           b * (-0.247333733281268944196501420480f +
                                b * (0.881770664775316294736387951347e-1f +
                                     b * (0.419038818029165735901852432784e-1f +
                                          b * -0.251390972343483509333252996350e-1f)))));
    phi = x < y ? 1.0f - phi : phi;
    const pfloat vn = phi * r, un = r - vn;
    const pint south = d.z < 0.0f; /* the southern hemisphere mirrored */
    const pfloat us = south ? 1.0f - vn : un, vs = south ? 1.0f - un : vn;
    *u = 0.5f * (pcopysign(us, d.x) + 1.0f);
    *v = 0.5f * (pcopysign(vs, d.y) + 1.0f);
}

RT_INLINE pint light_sample_goniometric(LIGHT_UNIT_PARAMS)
{
    FramedPoint q = light_frame_point(lights, row, ref);
    equal_area_sphere_to_square(pv3_normalize(q.l, sel), &q.u, &q.v);
    return light_sample_framed(ls, lights, row, sel, &q, 1.0f / q.dist2);
}
#define LIGHT_CASE_GONIOMETRIC(X) X(goniometric, GONIOMETRIC)
#endif

#endif
