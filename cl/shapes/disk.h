/* A disk ("disk", pyopencl_rt/scene/shapes/disk.py; Mitsuba 3's and pbrt-v4's full disk): the unit
 * disk x^2 + y^2 <= 1 of the plane z = 0, moved by an affine to_world (an ellipse under uneven
 * scales).  Params: to_world's rows (0-11), to_object's rows (12-23), the unit normal (24-26: to_world's
 * image of +z as a normal, flipped by flip_normals: the front) and the area (27).
 *
 * Intersection in object space (Mitsuba's disk): t = -o.z / d.z of the ray moved by to_object, a hit
 * where the point's x^2 + y^2 <= 1.  The hit point is to_world(x, y, 0), exactly in the plane up to
 * the transform's rounding, whose bound is the error (a few ulps of |M| |(x, y, 0)| + |translation|).
 * As an emitter it is sampled uniformly in area (the concentric map), pdf dist^2 / (area |cos|),
 * one-sided unless its material is two-sided.  Compiled with HAS_SHAPE_DISK. */
#ifndef PYOPENCL_RT_DISK_H
#define PYOPENCL_RT_DISK_H

#include "scene/shape_lanes.h"

#ifdef HAS_SHAPE_DISK
#define DISK_TO_WORLD 0
#define DISK_TO_OBJECT 12
#define DISK_NORMAL 24

/* row r of a 3x4 affine map at params[at] applied to the point (w 1) or vector (w 0) v, lane-uniform */
RT_INLINE pfloat disk_row(const float *m, int r, pvec3 v, float w)
{
    return v.x * m[4 * r] + v.y * m[4 * r + 1] + v.z * m[4 * r + 2] + m[4 * r + 3] * w;
}

RT_INLINE pint shape_intersect_disk(SHAPE_INTERSECT_PARAMS)
{
    float m[12];
    for (int k = 0; k < 12; ++k) m[k] = prm[DISK_TO_OBJECT + k];
    const pfloat oz = disk_row(m, 2, o, 1.0f), dz = disk_row(m, 2, d, 0.0f);
    const pfloat th = -oz / dz;
    const pfloat x = disk_row(m, 0, o, 1.0f) + th * disk_row(m, 0, d, 0.0f);
    const pfloat y = disk_row(m, 1, o, 1.0f) + th * disk_row(m, 1, d, 0.0f);
    const pint hit = live & (dz != 0.0f) & (th > tmin) & (th < tmax) & (x * x + y * y <= 1.0f);
    *t = hit ? th : *t;
    return hit;
}

/* the disk's object-space (x, y) of the lanes' hits at t, and to_world of it with its error */
RT_INLINE pvec3 shape_point_disk(SHAPE_POINT_PARAMS)
{
    const pvec3 q = pv3_add(o, pv3_scale(d, t));
    pvec3 r[3], w[3];
    for (int k = 0; k < 3; ++k) {
        r[k] = SHAPE_V3(shapes, s, DISK_TO_OBJECT + 4 * k);
        w[k] = SHAPE_V3(shapes, s, DISK_TO_WORLD + 4 * k);
    }
    const pfloat x = pv3_dot(r[0], q) + SHAPE_F(shapes, s, DISK_TO_OBJECT + 3);
    const pfloat y = pv3_dot(r[1], q) + SHAPE_F(shapes, s, DISK_TO_OBJECT + 7);
    const pvec3 tr = pv3(SHAPE_F(shapes, s, DISK_TO_WORLD + 3), SHAPE_F(shapes, s, DISK_TO_WORLD + 7),
                         SHAPE_F(shapes, s, DISK_TO_WORLD + 11));
    const pvec3 cx = pv3(w[0].x, w[1].x, w[2].x), cy = pv3(w[0].y, w[1].y, w[2].y);
    const pvec3 p = pv3_add(pv3_add(pv3_scale(cx, x), pv3_scale(cy, y)), tr);
    *err = pv3_scale(pv3_add(pv3_add(pv3_abs(pv3_scale(cx, x)), pv3_abs(pv3_scale(cy, y))), pv3_abs(tr)),
                     PFLOAT(HIT_GAMMA5));
    (void)sel;
    return p;
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
    const pvec3 cx = pv3(SHAPE_F(shapes, s, DISK_TO_WORLD), SHAPE_F(shapes, s, DISK_TO_WORLD + 4),
                         SHAPE_F(shapes, s, DISK_TO_WORLD + 8));
    const pvec3 cy = pv3(SHAPE_F(shapes, s, DISK_TO_WORLD + 1), SHAPE_F(shapes, s, DISK_TO_WORLD + 5),
                         SHAPE_F(shapes, s, DISK_TO_WORLD + 9));
    const pvec3 tr = pv3(SHAPE_F(shapes, s, DISK_TO_WORLD + 3), SHAPE_F(shapes, s, DISK_TO_WORLD + 7),
                         SHAPE_F(shapes, s, DISK_TO_WORLD + 11));
    const pvec3 p = pv3_add(pv3_add(pv3_scale(cx, x), pv3_scale(cy, y)), tr);
    const pvec3 err = pv3_scale(pv3_add(pv3_add(pv3_abs(pv3_scale(cx, x)), pv3_abs(pv3_scale(cy, y))), pv3_abs(tr)),
                                PFLOAT(HIT_GAMMA5));
    const pvec3 ng = SHAPE_V3(shapes, s, DISK_NORMAL);
    const pvec3 to_ref = pv3_sub(ref, p);
    const pfloat dist2 = pv3_dot(to_ref, to_ref);
    const pfloat cos_l = pv3_dot(ng, to_ref) * (1.0f / psqrt(dist2));
    const pvec3 n = pv3_sel(pv3_neg(ng), ng, cos_l > 0.0f);
    light_sample_set(ls, sel, p, err, n, emitted(m, ng, n), dist2 / (area * pabs(cos_l)));
    return sel & (cos_l != 0.0f) & (dist2 != 0.0f);
}

#define SHAPE_CASE_DISK(X) X(disk, DISK)
#endif

#endif
