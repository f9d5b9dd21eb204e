/* A sphere ("sphere", pyopencl_rt/scene/shapes/sphere.py): centre c (params 0-2) and radius r
 * (param 3), its front outside.  Intersection: the stable quadratic of accel/intersect.h.  A hit
 * point is o + t d re-projected onto the surface, its error relative to |p| + |c| (pbrt-v4,
 * 6.8.5).  As an emitter it is sampled uniformly in the cone of directions that sees it from a
 * point outside, with p the ray's hit toward that direction (the cone keeps precision for small,
 * far spheres), and uniformly in area from a point inside (pdf by the area, as a triangle's).
 * Compiled with HAS_SHAPE_SPHERE. */
#ifndef PYOPENCL_RT_SPHERE_H
#define PYOPENCL_RT_SPHERE_H

#include "scene/shape_lanes.h"

#ifdef HAS_SHAPE_SPHERE
#define SPHERE_CENTER 0
#define SPHERE_RADIUS 3

RT_INLINE pint shape_intersect_sphere(SHAPE_INTERSECT_PARAMS)
{
    return intersect_sphere(o, d, pv3_splat(vload3(0, prm + SPHERE_CENTER)), PFLOAT(prm[SPHERE_RADIUS]), tmin, tmax,
                            t, live);
}

RT_INLINE pvec3 shape_point_sphere(SHAPE_POINT_PARAMS)
{
    const pvec3 c = SHAPE_V3(shapes, s, SPHERE_CENTER);
    const pvec3 p = pv3_add(c, pv3_scale(pv3_normalize(pv3_sub(pv3_add(o, pv3_scale(d, t)), c), sel),
                                         SHAPE_F(shapes, s, SPHERE_RADIUS)));
    *err = pv3_scale(pv3_add(pv3_abs(p), pv3_abs(c)), PFLOAT(HIT_GAMMA5));
    return p;
}

RT_INLINE pvec3 shape_normal_sphere(SHAPE_NORMAL_PARAMS)
{
    return pv3_div(pv3_sub(p, SHAPE_V3(shapes, s, SPHERE_CENTER)), SHAPE_F(shapes, s, SPHERE_RADIUS));
}

/* 1 - cos of the half-angle of the cone that sees a sphere of radius r from distance^2 dc2 > r^2
 * to its centre, as sin^2 / (1 + cos): no cancellation for a small, far sphere */
RT_INLINE pfloat sphere_one_minus_cos_max(pfloat r, pfloat dc2)
{
    const pfloat sin2 = pfmin(r * r / dc2, PFLOAT(1.0f));
    const pfloat cos_max = psqrt(pfmax(PFLOAT(0.0f), 1.0f - sin2));
    return sin2 / (1.0f + cos_max);
}

RT_INLINE pint shape_sample_sphere(SHAPE_SAMPLE_PARAMS)
{
    const pvec3 c = SHAPE_V3(shapes, s, SPHERE_CENTER);
    const pfloat r = SHAPE_F(shapes, s, SPHERE_RADIUS);
    const pvec3 to_c = pv3_sub(c, ref);
    const pfloat dc2 = pv3_dot(to_c, to_c);
    const pint outside = sel & (dc2 > r * r), inside = sel & pnot(dc2 > r * r);
    pint got = PINT(0);
    if (pany(outside)) {
        const pfloat dc = psqrt(dc2);
        const pvec3 axis = pv3_div(to_c, dc);
        const pfloat one_minus_cos = sphere_one_minus_cos_max(r, dc2);
        pvec3 t, b;
        make_onb(axis, &t, &b);
        const pvec3 w = pv3_normalize(to_world(sample_uniform_cone(ux, uy, 1.0f - one_minus_cos), t, b, axis), outside);
        pfloat th = pv3_dot(to_c, w); /* grazing the silhouette (no root): the tangent point */
        intersect_sphere(ref, w, c, r, PFLOAT(0.0f), PFLOAT(INFINITY), &th, outside);
        /* re-projected: error relative to |c| + r */
        const pvec3 p = pv3_add(c, pv3_scale(pv3_normalize(pv3_sub(pv3_add(ref, pv3_scale(w, th)), c), outside), r));
        const pvec3 err = pv3_scale(pv3_add(pv3_abs(p), pv3_abs(c)), PFLOAT(HIT_GAMMA5));
        const pvec3 n = pv3_normalize(pv3_sub(p, c), outside);
        const pvec3 Le = emitted(m, n, pv3_neg(w));
        light_sample_set(ls, outside, p, err, n, Le, 1.0f / (2.0f * PI_F * one_minus_cos));
        got = outside;
    }
    if (pany(inside)) {
        /* inside the sphere: uniform in area, seen from inside (its inner side) */
        const pvec3 dir = sample_uniform_sphere(ux, uy);
        const pvec3 p = pv3_add(c, pv3_scale(dir, r));
        const pvec3 err = pv3_scale(pv3_add(pv3_abs(p), pv3_abs(c)), PFLOAT(HIT_GAMMA5));
        const pvec3 to_ref = pv3_sub(ref, p);
        const pfloat dist2 = pv3_dot(to_ref, to_ref);
        const pfloat cos_l = pv3_dot(dir, to_ref) * (1.0f / psqrt(dist2));
        const pvec3 Le = emitted(m, dir, to_ref);
        const pvec3 n = pv3_sel(pv3_neg(dir), dir, cos_l > 0.0f);
        light_sample_set(ls, inside, p, err, n, Le, dist2 / (area * pabs(cos_l)));
        got = got | (inside & (cos_l != 0.0f));
    }
    return got;
}

/* the density of the cone from outside (inside: the area density, shape_light_pdf's default) */
RT_INLINE pfloat shape_pdf_sphere(SHAPE_PDF_PARAMS)
{
    const pvec3 to_c = pv3_sub(SHAPE_V3(shapes, s, SPHERE_CENTER), ref);
    const pfloat r = SHAPE_F(shapes, s, SPHERE_RADIUS);
    const pfloat dc2 = pv3_dot(to_c, to_c);
    return dc2 > r * r ? 1.0f / (2.0f * PI_F * sphere_one_minus_cos_max(r, dc2)) : pdf_area;
}

#define SHAPE_CASE_SPHERE(X) X(sphere, SPHERE)
#define SHAPE_PDF_CASE_SPHERE(X) X(sphere, SPHERE)
#endif

#endif
