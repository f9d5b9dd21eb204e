/* A cylinder ("cylinder", pyopencl_rt/scene/shapes/cylinder.py; Mitsuba 3's and pbrt-v4's open tube):
 * the unit tube x^2 + y^2 = 1, 0 <= z <= 1, without caps, moved by an affine to_world that keeps it a
 * right circular tube (the loaders give other maps' tubes as triangles).  Params: to_world's rows (0-11), to_object's
 * rows (12-23), the side that is its front (24: +1 outside, -1 inside, flip_normals) and the area
 * (25).
 *
 * Intersection in object space with the stable quadratic of the sphere's (accel/intersect.h) in x
 * and y: the nearer root in (tmin, tmax) whose z lies in [0, 1], else the farther.  The hit point
 * is the object-space point moved back onto the tube (x, y scaled to radius 1) and to the world,
 * with its error (shape_affine_point); the normal is M^-T (x, y, 0) (to_object's rows),
 * times the front's sign.  As an emitter it is sampled uniformly in area (phi and z uniform: a
 * right circular tube keeps areas in proportion), pdf dist^2 / (area |cos|).  Compiled with HAS_SHAPE_CYLINDER. */
#ifndef PYOPENCL_RT_CYLINDER_H
#define PYOPENCL_RT_CYLINDER_H

#include "scene/shape_lanes.h"

#ifdef HAS_SHAPE_CYLINDER
#define CYLINDER_TO_WORLD 0
#define CYLINDER_TO_OBJECT 12
#define CYLINDER_SIDE 24

RT_INLINE pint shape_intersect_cylinder(SHAPE_INTERSECT_PARAMS)
{
    pvec3 ol, dl;
    shape_object_ray(prm, CYLINDER_TO_OBJECT, o, d, &ol, &dl);
    const pfloat ox = ol.x, oy = ol.y, oz = ol.z, dx = dl.x, dy = dl.y, dz = dl.z;
    const pfloat a = dx * dx + dy * dy;
    const pint moving = a > 0.0f; /* a ray along the axis never meets the tube */
    const pfloat a_safe = moving ? a : PFLOAT(1.0f);
    const pfloat bh = ox * dx + oy * dy;
    const pfloat cc = ox * ox + oy * oy - 1.0f;
    /* the discriminant as a (1 - l)(1 + l), l the distance of the ray's closest approach to the axis */
    const pfloat lx = ox - dx * (bh / a_safe), ly = oy - dy * (bh / a_safe);
    const pfloat l = psqrt(lx * lx + ly * ly);
    const pfloat disc = a * (1.0f - l) * (1.0f + l);
    const pfloat q = -(bh + pcopysign(psqrt(pfmax(disc, PFLOAT(0.0f))), bh));
    const pint tangent = q == 0.0f;
    const pfloat r0 = tangent ? PFLOAT(0.0f) : q / a_safe, r1 = tangent ? PFLOAT(0.0f) : cc / q;
    const pfloat t0 = r0 > r1 ? r1 : r0, t1 = r0 > r1 ? r0 : r1;
    const pfloat z0 = oz + t0 * dz, z1 = oz + t1 * dz;
    const pint near = (t0 > tmin) & (t0 < tmax) & (z0 >= 0.0f) & (z0 <= 1.0f);
    const pint far = (t1 > tmin) & (t1 < tmax) & (z1 >= 0.0f) & (z1 <= 1.0f);
    const pint hit = live & moving & (disc >= 0.0f) & (near | far);
    *t = hit ? (near ? t0 : t1) : *t;
    return hit;
}

/* the lanes' object-space point q at t (x, y on the unit circle) and its image p with the error */
RT_INLINE pvec3 cylinder_local(__global const Shape *shapes, pint s, pvec3 o, pvec3 d, pfloat t, pint sel)
{
    const pvec3 w = pv3_add(o, pv3_scale(d, t));
    pvec3 q = pv3(pv3_dot(SHAPE_V3(shapes, s, CYLINDER_TO_OBJECT), w) + SHAPE_F(shapes, s, CYLINDER_TO_OBJECT + 3),
                  pv3_dot(SHAPE_V3(shapes, s, CYLINDER_TO_OBJECT + 4), w) + SHAPE_F(shapes, s, CYLINDER_TO_OBJECT + 7),
                  pv3_dot(SHAPE_V3(shapes, s, CYLINDER_TO_OBJECT + 8), w) + SHAPE_F(shapes, s, CYLINDER_TO_OBJECT + 11));
    const pfloat r = psqrt(q.x * q.x + q.y * q.y);
    const pint ok = sel & (r > 0.0f);
    q.x = ok ? q.x / r : PFLOAT(1.0f);
    q.y = ok ? q.y / r : PFLOAT(0.0f);
    return q;
}

/* the front's unit normal at object-space q: M^-T (x, y, 0), whose world component i is
 * M^-1[0][i] x + M^-1[1][i] y (to_object's rows), signed */
RT_INLINE pvec3 cylinder_normal(__global const Shape *shapes, pint s, pvec3 q, pint sel)
{
    const pvec3 w = pv3_add(pv3_scale(SHAPE_V3(shapes, s, CYLINDER_TO_OBJECT), q.x),
                            pv3_scale(SHAPE_V3(shapes, s, CYLINDER_TO_OBJECT + 4), q.y));
    return pv3_scale(pv3_normalize(w, sel), SHAPE_F(shapes, s, CYLINDER_SIDE));
}

RT_INLINE pvec3 shape_point_cylinder(SHAPE_POINT_PARAMS)
{
    return shape_affine_point(shapes, s, CYLINDER_TO_WORLD, cylinder_local(shapes, s, o, d, t, sel), err);
}

RT_INLINE pvec3 shape_normal_cylinder(SHAPE_NORMAL_PARAMS)
{
    /* p back in object space (its x, y on the unit circle) */
    const pvec3 q = cylinder_local(shapes, s, p, pv3_zero(), PFLOAT(0.0f), sel);
    return cylinder_normal(shapes, s, q, sel);
}

RT_INLINE pint shape_sample_cylinder(SHAPE_SAMPLE_PARAMS)
{
    pfloat sin_phi, cos_phi;
    psincos(2.0f * PI_F * ux, &sin_phi, &cos_phi);
    const pvec3 q = pv3(cos_phi, sin_phi, uy);
    pvec3 err;
    const pvec3 p = shape_affine_point(shapes, s, CYLINDER_TO_WORLD, q, &err);
    return shape_area_sample(ls, sel, m, area, ref, p, err, cylinder_normal(shapes, s, q, sel));
}

#define SHAPE_CASE_CYLINDER(X) X(cylinder, CYLINDER)
#endif

#endif
