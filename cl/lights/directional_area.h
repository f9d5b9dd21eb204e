/* A directional area light ("directional_area": Mitsuba 3's directionalarea on a triangle, made
 * by pyopencl_rt/render/lights.py from an emissive face whose material has
 * emission_directional): a triangle emitting only along its geometric normal n, its flux per unit
 * area the radiance value rgb, all along n, as Mitsuba's particle tracer emits it.  The one point
 * of it that lights ref is ref's projection along -n onto its plane, when that lies inside it and
 * ref in front: Le = rgb there, a delta light (a parallel beam: no falloff); elsewhere no sample.
 * Mitsuba's path tracer does not sample it at all (its directionalarea.cpp leaves that to be done
 * "with a flat surface"); this is that.  Compiled with HAS_DELTA_LIGHTS. */
#ifndef PYOPENCL_RT_DIRECTIONAL_AREA_H
#define PYOPENCL_RT_DIRECTIONAL_AREA_H

#include "render/light_sample.h"

#ifdef HAS_DELTA_LIGHTS
RT_INLINE pint light_sample_directional_area(LIGHT_UNIT_PARAMS)
{
    const pint i = sel ? LIGHT_I(lights, row, prim) : PINT(0);
    const pvec3 p0 = tri_vertex(MESH_ARGS, i, 0), p1 = tri_vertex(MESH_ARGS, i, 1), p2 = tri_vertex(MESH_ARGS, i, 2);
    const pvec3 e1 = pv3_sub(p1, p0), e2 = pv3_sub(p2, p0), to_ref = pv3_sub(ref, p0);
    const pvec3 n = pv3_normalize(pv3_cross(e1, e2), sel);
    const pfloat h = pv3_dot(to_ref, n); /* ref's height above the plane, on the emitting side */
    const pvec3 q = pv3_sub(to_ref, pv3_scale(n, h)); /* the projection, from p0 */
    /* its barycentrics (b1, b2) from the normal equations of q = b1 e1 + b2 e2 */
    const pfloat d11 = pv3_dot(e1, e1), d12 = pv3_dot(e1, e2), d22 = pv3_dot(e2, e2);
    const pfloat q1 = pv3_dot(q, e1), q2 = pv3_dot(q, e2);
    const pfloat det = d11 * d22 - d12 * d12;
    const pint ok = sel & (h > 0.0f) & (det > 0.0f);
    const pfloat inv = 1.0f / (ok ? det : PFLOAT(1.0f));
    const pfloat b1 = (d22 * q1 - d12 * q2) * inv, b2 = (d11 * q2 - d12 * q1) * inv;
    const pint inside = ok & (b1 >= 0.0f) & (b2 >= 0.0f) & (b1 + b2 <= 1.0f);
    pvec3 err;
    const pvec3 p = triangle_point(p0, p1, p2, b1, b2, &err);
    light_sample_set(ls, sel, p, err, n, LIGHT_V3(lights, row, rgb), PFLOAT(1.0f));
    return inside;
}
#define LIGHT_CASE_DIRECTIONAL_AREA(X) X(directional_area, DIRECTIONAL_AREA)
#endif

#endif
