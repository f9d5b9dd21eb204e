/* The analytic shapes (spheres, disks, tubes: cl/shapes/<name>.h each) as the kernels see them: their own
 * BVH (shape_nodes, accel/bvh.h's node layout; a leaf holds one shape, child its index), traversed
 * after the triangles' for the lanes of a packet, and the dispatch of a hit's point, normal and
 * emitter sample to each lane's type.  One BVH per kind of primitive, as Embree's scenes keep one
 * per geometry type: the triangle layouts stay as they are, and a shape type is a unit that the
 * generated "shapes/units.h" includes and lists (SHAPE_CASES).  Compiled with HAS_SHAPES. */
#ifndef PYOPENCL_RT_SHAPES_H
#define PYOPENCL_RT_SHAPES_H

#include "accel/bvh.h"
#include "scene/shape_lanes.h"
#include "shapes/units.h"

#define SHAPE_TYPE(shapes, s) \
    pgather_int((__global const int *)(shapes), (s) * STRIDE_INDEX(Shape) + FIELD_INDEX(Shape, type))

/* one shape, whatever its type, against the lanes' rays (shape_intersect_<name>) */
RT_INLINE pint shape_intersect(__global const Shape *shapes, int s, pvec3 o, pvec3 d, pfloat tmin, pfloat tmax,
                               pfloat *t, pint live)
{
    __global const float *prm = shapes[s].params;
    const int type = shapes[s].type;
    pint h = PINT(0);
#define SHAPE_INTERSECT_CASE(name, NAME) \
    if (type == SHAPE_##NAME) h = shape_intersect_##name(prm, o, d, tmin, tmax, t, live);
    SHAPE_CASES(SHAPE_INTERSECT_CASE)
#undef SHAPE_INTERSECT_CASE
    (void)prm;
    return h;
}

/* The lanes whose ray enters the box (lo, hi) in (0, tmax) (tmax < 0: an idle lane); inv the safe
 * reciprocal of the direction, so no operand is NaN; the far side grows as the triangles' test does */
RT_INLINE pint shape_box(__global const float4 *box, pvec3 o, pvec3 inv, pfloat tmax)
{
    const float4 lo = box[0], hi = box[1];
    const pfloat x0 = (lo.x - o.x) * inv.x, x1 = (hi.x - o.x) * inv.x;
    const pfloat y0 = (lo.y - o.y) * inv.y, y1 = (hi.y - o.y) * inv.y;
    const pfloat z0 = (lo.z - o.z) * inv.z, z1 = (hi.z - o.z) * inv.z;
    const pfloat enter = pfmax(pfmax(pfmin(x0, x1), pfmin(y0, y1)), pfmax(pfmin(z0, z1), PFLOAT(0.0f)));
    const pfloat leave = pfmin(pfmin(pfmax(x0, x1), pfmax(y0, y1)), pfmax(z0, z1)) * SLAB_FAR_SCALE;
    return enter <= pfmin(leave, tmax);
}

/* The shapes' BVH walked for the lanes of `live`: with any_hit 0 their closest hits nearer than *t
 * (*t and *prim set where one is), with 1 whether some shape lies before *t (the walk ends when every
 * lane is blocked); returns the lanes that found one.  The builder keeps the depth under
 * BVH_STACK_SIZE (accel/shape_bvh.py). */
RT_INLINE pint shapes_walk(__global const BVHNode *shape_nodes, __global const Shape *shapes, pvec3 o, pvec3 d,
                           pint live, pfloat *t, pint *prim, const int any_hit)
{
    const pvec3 inv = pv3(psafe_rcp(d.x), psafe_rcp(d.y), psafe_rcp(d.z));
    int stack[BVH_STACK_SIZE], sp = 0, idx = 0;
    pint found = PINT(0);
    for (;;) {
        __global const BVHNode *n = shape_nodes + idx;
        __global const float4 *q = (__global const float4 *)n;
        const pint open = any_hit ? live & pnot(found) : live;
        if (any_hit && !pany(open)) return found;
        int go[2] = {0, 0}; /* the inner children some lane enters (leaves are done here) */
        for (int side = 0; side < 2; ++side) {
            const int count = side ? n->count_right : n->count_left;
            if (count < 0 || !pany(shape_box(q + 2 * side, o, inv, open ? *t : PFLOAT(-1.0f)))) continue;
            if (count == 0) { go[side] = 1; continue; }
            const int s = side ? n->child_right : n->child_left;
            pfloat th = *t;
            const pint h = shape_intersect(shapes, s, o, d, PFLOAT(0.0f), *t, &th, open);
            if (!any_hit) {
                *t = h ? th : *t;
                *prim = h ? PINT(SHAPE_PRIM(s)) : *prim;
            }
            found |= h;
        }
        if (!bvh_next_any(n->child_left, n->child_right, go[0], go[1], stack, &sp, &idx)) return found;
    }
}

/* The lanes of prim on a shape (the mask returned), each one's shape *s and its type *type (no
 * gather where no lane is on one) */
RT_INLINE pint shape_lanes(__global const Shape *shapes, pint prim, pint *s, pint *type)
{
    const pint shape = IS_SHAPE(prim);
    *s = PINT(0);
    *type = PINT(-1);
    if (pany(shape)) {
        *s = shape ? SHAPE_INDEX(prim) : PINT(0);
        *type = SHAPE_TYPE(shapes, *s);
    }
    return shape;
}

/* The lanes' hit points on shapes (prim: IS_SHAPE lanes; others keep *p, *err) */
RT_INLINE void shape_hit_point(__global const Shape *shapes, pint prim, pvec3 o, pvec3 d, pfloat t, pvec3 *p,
                               pvec3 *err)
{
    pint s, type;
    const pint shape = shape_lanes(shapes, prim, &s, &type);
#define SHAPE_POINT_CASE(name, NAME)                                                                \
    if (pany(shape & (type == SHAPE_##NAME))) {                                                     \
        const pint sel = shape & (type == SHAPE_##NAME);                                            \
        pvec3 e;                                                                                    \
        const pvec3 q = shape_point_##name(shapes, s, sel, o, d, t, &e);                            \
        *err = pv3_sel(*err, e, sel);                                                               \
        *p = pv3_sel(*p, q, sel);                                                                   \
    }
    SHAPE_CASES(SHAPE_POINT_CASE)
#undef SHAPE_POINT_CASE
    (void)s;
}

/* The lanes' unit geometric normals on shapes at p (others keep *n) */
RT_INLINE void shape_hit_normal(__global const Shape *shapes, pint prim, pvec3 p, pvec3 *n)
{
    pint s, type;
    const pint shape = shape_lanes(shapes, prim, &s, &type);
#define SHAPE_NORMAL_CASE(name, NAME)                                                               \
    if (pany(shape & (type == SHAPE_##NAME)))                                                       \
        *n = pv3_sel(*n, shape_normal_##name(shapes, s, shape & (type == SHAPE_##NAME), p), shape & (type == SHAPE_##NAME));
    SHAPE_CASES(SHAPE_NORMAL_CASE)
#undef SHAPE_NORMAL_CASE
    (void)s;
}

/* A sample of the emissive shapes s of the lanes of `sel` seen from ref (m: their materials, area:
 * their light records'): the lanes that got one, ls filled in there */
RT_INLINE pint shape_light_sample(__global const Shape *shapes, pint s, pint sel, const MaterialLanes *m, pfloat area,
                                  pvec3 ref, pfloat ux, pfloat uy, LightSample *ls)
{
    const pint type = SHAPE_TYPE(shapes, s);
    pint got = PINT(0);
#define SHAPE_SAMPLE_CASE(name, NAME)                                                               \
    {                                                                                               \
        const pint in = sel & (type == SHAPE_##NAME);                                               \
        if (pany(in)) got = got | shape_sample_##name(shapes, s, in, m, area, ref, ux, uy, ls);    \
    }
    SHAPE_CASES(SHAPE_SAMPLE_CASE)
#undef SHAPE_SAMPLE_CASE
    (void)type;
    return got;
}

/* The density shape_light_sample had for a point seen from ref on the lanes' shapes s (`sel`),
 * given pdf_area, the uniform-area one: each type's own where it samples otherwise */
RT_INLINE pfloat shape_light_pdf(__global const Shape *shapes, pint s, pint sel, pvec3 ref, pfloat pdf_area)
{
    const pint type = SHAPE_TYPE(shapes, s);
    pfloat pdf = pdf_area;
#define SHAPE_PDF_CASE(name, NAME)                                                                  \
    {                                                                                               \
        const pint in = sel & (type == SHAPE_##NAME);                                               \
        if (pany(in)) pdf = in ? shape_pdf_##name(shapes, s, ref, pdf_area) : pdf;                 \
    }
    SHAPE_PDF_CASES(SHAPE_PDF_CASE)
#undef SHAPE_PDF_CASE
    (void)type;
    return pdf;
}

#endif
