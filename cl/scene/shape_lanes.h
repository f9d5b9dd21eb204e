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
