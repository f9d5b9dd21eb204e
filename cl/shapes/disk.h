/* A disk ("disk", pyopencl_rt/scene/shapes/disk.py; Mitsuba 3's and pbrt-v4's full disk): the unit
 * disk x^2 + y^2 <= 1 of the plane z = 0, moved by an affine to_world (an ellipse under uneven
 * scales).  Params: to_world's rows (0-11), to_object's rows (12-23), the unit normal (24-26: to_world's
 * image of +z as a normal, flipped by flip_normals: the front) and the area (27).
 *
 * Intersection in object space (Mitsuba's disk): t = -o.z / d.z of the ray moved by to_object, a hit
 * where the point's x^2 + y^2 <= 1.  The hit point is to_world(x, y, 0), exactly in the plane up to
 * the transform's rounding, whose bound is the error (shape_affine_point).
 * As an emitter it is sampled uniformly in area (the concentric map), pdf dist^2 / (area |cos|),
 * one-sided unless its material is two-sided.  Compiled with HAS_SHAPE_DISK. */
#ifndef PYOPENCL_RT_DISK_H
#define PYOPENCL_RT_DISK_H

#include "scene/shape_lanes.h"

#ifdef HAS_SHAPE_DISK
#define DISK_TO_WORLD 0
#define DISK_TO_OBJECT 12
#define DISK_NORMAL 24

RT_INLINE pint shape_intersect_disk(SHAPE_INTERSECT_PARAMS)
{
    pvec3 ol, dl;
    shape_object_ray(prm, DISK_TO_OBJECT, o, d, &ol, &dl);
    const pfloat th = -ol.z / dl.z;
    const pfloat x = ol.x + th * dl.x, y = ol.y + th * dl.y;
    const pint hit = live & (dl.z != 0.0f) & (th > tmin) & (th < tmax) & (x * x + y * y <= 1.0f);
    *t = hit ? th : *t;
    return hit;
}

/* the disk's object-space (x, y) of the lanes' hits at t, and to_world of (x, y, 0) with its error */
RT_INLINE pvec3 shape_point_disk(SHAPE_POINT_PARAMS)
{
    const pvec3 w = pv3_add(o, pv3_scale(d, t));
    const pfloat x = pv3_dot(SHAPE_V3(shapes, s, DISK_TO_OBJECT), w) + SHAPE_F(shapes, s, DISK_TO_OBJECT + 3);
    const pfloat y = pv3_dot(SHAPE_V3(shapes, s, DISK_TO_OBJECT + 4), w) + SHAPE_F(shapes, s, DISK_TO_OBJECT + 7);
    (void)sel;
    return shape_affine_point(shapes, s, DISK_TO_WORLD, pv3(x, y, PFLOAT(0.0f)), err);
}

RT_INLINE pvec3 shape_normal_disk(SHAPE_NORMAL_PARAMS)
{
    (void)p;
    return SHAPE_V3(shapes, s, DISK_NORMAL);
}

RT_INLINE pint shape_sample_disk(SHAPE_SAMPLE_PARAMS)
{
    pfloat x, y;
    sample_concentric_disk(ux, uy, &x, &y);
    pvec3 err;
    const pvec3 p = shape_affine_point(shapes, s, DISK_TO_WORLD, pv3(x, y, PFLOAT(0.0f)), &err);
    return shape_area_sample(ls, sel, m, area, ref, p, err, SHAPE_V3(shapes, s, DISK_NORMAL));
}

#define SHAPE_CASE_DISK(X) X(disk, DISK)
#endif

#endif
