/* What an analytic shape's unit (cl/shapes/<name>.h, paired by name with
 * pyopencl_rt/scene/shapes/<name>.py) is written against: the gathers of the lanes' Shape records
 * (abi.SHAPE: a type and a block of parameters that each type reads by its own names) and the
 * parameter lists of the five functions a unit defines:
 *
 *   shape_intersect_<name>  one shape (prm: its parameters) against the lanes' rays, closest root in
 *                           (tmin, tmax) where `live`: the mask of the lanes hit, *t set there
 *   shape_point_<name>      the hit point of each lane of `sel` on shape s at t, and its error bound
 *   shape_normal_<name>     the unit geometric normal there (the front side's)
 *   shape_sample_<name>     a sample of the shape as an area emitter seen from ref (fills ls in `sel`,
 *                           returns the lanes that got one); `area` the light record's
 *   shape_pdf_<name>        (optional, SHAPE_PDF_CASE_<NAME>) its solid-angle density where it is not
 *                           pdf_area, the uniform-area density seen from ref
 *
 * and the case SHAPE_CASE_<NAME>(X) X(name, NAME), inside the #ifdef HAS_SHAPE_<NAME> that compiles
 * it in.  cl/scene/shapes.h dispatches through the generated "shapes/units.h".  A unit computes over
 * the lanes what the one-path code computes for its lane, so every width gives the same bits. */
#ifndef PYOPENCL_RT_SHAPE_LANES_H
#define PYOPENCL_RT_SHAPE_LANES_H

#include "accel/intersect.h"
#include "render/sampling.h"
#include "render/emission.h"

/* a hit on shape s is prim PRIM_SHAPE_FIRST - s (abi.py) */
#define SHAPE_PRIM(s) (PRIM_SHAPE_FIRST - (s))
#define IS_SHAPE(prim) ((prim) <= PRIM_SHAPE_FIRST)
#define SHAPE_INDEX(prim) (PRIM_SHAPE_FIRST - (prim))

/* 5 * 2^-24 / (1 - 5 * 2^-24), rounded up: a bound on the relative error of a few float operations */
#define HIT_GAMMA5 2.98023259e-07f

/* parameter k of the lanes' shapes s, and the three from k */
#define SHAPE_F(shapes, s, k) \
    pgather((__global const float *)(shapes), (s) * STRIDE_INDEX(Shape) + FIELD_INDEX(Shape, params) + (k))
#define SHAPE_V3(shapes, s, k) \
    pv3_gather((__global const float *)(shapes), (s) * STRIDE_INDEX(Shape) + FIELD_INDEX(Shape, params) + (k))

/* row r of the 3 x 4 affine map m (private) applied to the lanes' point (w 1) or vector (w 0) v */
RT_INLINE pfloat shape_affine_row(const float *m, int r, pvec3 v, float w)
{
    return v.x * m[4 * r] + v.y * m[4 * r + 1] + v.z * m[4 * r + 2] + m[4 * r + 3] * w;
}

/* The lanes' rays (o, d) in a lane-uniform shape's object space: its to_object's rows at prm[at] */
RT_INLINE void shape_object_ray(__global const float *prm, int at, pvec3 o, pvec3 d, pvec3 *ol, pvec3 *dl)
{
    float m[12];
    for (int k = 0; k < 12; ++k) m[k] = prm[at + k];
    *ol = pv3(shape_affine_row(m, 0, o, 1.0f), shape_affine_row(m, 1, o, 1.0f), shape_affine_row(m, 2, o, 1.0f));
    *dl = pv3(shape_affine_row(m, 0, d, 0.0f), shape_affine_row(m, 1, d, 0.0f), shape_affine_row(m, 2, d, 0.0f));
}

/* The map at parameter k of the lanes' shapes s applied to their points q, and a bound on its
 * rounding per coordinate (a few ulps of |M| |q| + |translation|) */
RT_INLINE pvec3 shape_affine_point(__global const Shape *shapes, pint s, int k, pvec3 q, pvec3 *err)
{
    const pvec3 aq = pv3_abs(q);
    pvec3 p, e;
#define SHAPE_AFFINE_ROW(c, r)                                                                      \
    p.c = pv3_dot(SHAPE_V3(shapes, s, k + 4 * r), q) + SHAPE_F(shapes, s, k + 4 * r + 3);           \
    e.c = pv3_dot(pv3_abs(SHAPE_V3(shapes, s, k + 4 * r)), aq) + pabs(SHAPE_F(shapes, s, k + 4 * r + 3));
    SHAPE_AFFINE_ROW(x, 0)
    SHAPE_AFFINE_ROW(y, 1)
    SHAPE_AFFINE_ROW(z, 2)
#undef SHAPE_AFFINE_ROW
    *err = pv3_scale(e, PFLOAT(HIT_GAMMA5));
    return p;
}

/* ls in the lanes of `sel` for the point p (error err, geometric normal ng: the front's) of an emitter
 * of `area` sampled uniformly in area, seen from ref: pdf dist^2 / (area |cos|), the normal turned
 * toward ref, the radiance m emits that way; the lanes that got a sample */
RT_INLINE pint shape_area_sample(LightSample *ls, pint sel, const MaterialLanes *m, pfloat area, pvec3 ref, pvec3 p,
                                 pvec3 err, pvec3 ng)
{
    const pvec3 to_ref = pv3_sub(ref, p);
    const pfloat dist2 = pv3_dot(to_ref, to_ref);
    const pfloat cos_l = pv3_dot(ng, to_ref) * (1.0f / psqrt(dist2));
    const pvec3 n = pv3_sel(pv3_neg(ng), ng, cos_l > 0.0f);
    light_sample_set(ls, sel, p, err, n, emitted(m, ng, n), dist2 / (area * pabs(cos_l)));
    return sel & (cos_l != 0.0f) & (dist2 != 0.0f);
}

#define SHAPE_INTERSECT_PARAMS \
    __global const float *prm, pvec3 o, pvec3 d, pfloat tmin, pfloat tmax, pfloat *t, pint live
#define SHAPE_POINT_PARAMS \
    __global const Shape *shapes, pint s, pint sel, pvec3 o, pvec3 d, pfloat t, pvec3 *err
#define SHAPE_NORMAL_PARAMS __global const Shape *shapes, pint s, pint sel, pvec3 p
#define SHAPE_SAMPLE_PARAMS                                                                         \
    __global const Shape *shapes, pint s, pint sel, const MaterialLanes *m, pfloat area, pvec3 ref, \
        pfloat ux, pfloat uy, LightSample *ls
#define SHAPE_PDF_PARAMS __global const Shape *shapes, pint s, pvec3 ref, pfloat pdf_area

#endif
