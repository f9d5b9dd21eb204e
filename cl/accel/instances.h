/* Two-level instancing (compiled with HAS_INSTANCES): a top-level BVH (tlas, binary nodes of
 * bvh.h, traversed one ray at a time) over the world boxes of the instances; a leaf is a range of
 * `instances` (abi.INSTANCE), each naming its group's bottom-level BVH (in the device's layout, at
 * byte blas_offset of blas_nodes) and its group's first triangle in tris (tri_offset).  Entering
 * an instance moves the ray into the group's space (origin as a point, direction as a vector, not
 * made unit, so t is the world's t) and runs the ordinary traversal of traverse.h there; a hit's
 * prim is the group's triangle in tris (shared by every instance: materials, UVs, normals are
 * per group) and the instance is reported beside it.  Shading moves the hit back
 * (instance_to_world, below).  pyopencl_rt/accel/instances.py builds the buffers. */
#ifndef PYOPENCL_RT_INSTANCES_H
#define PYOPENCL_RT_INSTANCES_H

#include "accel/traverse.h"
#include "render/lanes.h"

/* a group's BVH root (binary nodes or a wide blob: both are read from where the pointer starts) */
#define BLAS_ROOT(base, off) ((__global const BVHNode *)((__global const char *)(base) + (off)))

RT_INLINE float3 xf_point1(__global const float *m, float3 p)
{
    return (float3)(m[0] * p.x + m[1] * p.y + m[2] * p.z + m[3], m[4] * p.x + m[5] * p.y + m[6] * p.z + m[7],
                    m[8] * p.x + m[9] * p.y + m[10] * p.z + m[11]);
}

RT_INLINE float3 xf_vector1(__global const float *m, float3 d)
{
    return (float3)(m[0] * d.x + m[1] * d.y + m[2] * d.z, m[4] * d.x + m[5] * d.y + m[6] * d.z,
                    m[8] * d.x + m[9] * d.y + m[10] * d.z);
}

/* Motion blur (HAS_MOTION, pbrt-v4's ActiveTransform): an instance moves by a translation over the
 * shutter, s dw at the ray's time sample u (s = clamp(a + b u, 0, 1): abi.INSTANCE), its 3x3 part
 * fixed, so that M(s)^-1 is M^-1 with the origin moved back by s M^-1 dw.  The TLAS boxes hold the
 * whole sweep (pyopencl_rt/accel/instances.py); the time is each ray's, passed as `time`. */
#ifdef HAS_MOTION
#define MOTION_TIME_PARAM , float time
#define MOTION_TIME_ARG(u) , u
RT_INLINE float instance_motion_share(__global const Instance *in, float u)
{
    return clamp(in->motion_world[3] + in->motion_object[3] * u, 0.0f, 1.0f);
}
/* the ray's origin in the group's space at its time */
#define OBJECT_ORIGIN(in, o) \
    (xf_point1((in)->world_to_object, o) - instance_motion_share(in, time) * vload3(0, (in)->motion_object))
#else
#define MOTION_TIME_PARAM
#define MOTION_TIME_ARG(u)
#define OBJECT_ORIGIN(in, o) xf_point1((in)->world_to_object, o)
#endif

/* The instances' closest hit in (tmin, hit->t): on a closer one *hit (prim: the triangle in tris)
 * and *inst (its index in `instances`) are replaced. */
RT_INLINE void instances_closest_hit(__global const BVHNode *tlas, __global const Instance *instances,
                                     __global const BVHNode *blas, __global const float4 *tris, float3 o, float3 d,
                                     float tmin, Hit *hit, int *inst MOTION_TIME_PARAM)
{
    const BinaryRay r = binary_ray(o, d); /* the slab test's part: each instance's BLAS shears its own ray */
    int stack_node[BVH_STACK_SIZE];
    float stack_t[BVH_STACK_SIZE];
    int sp = 0, idx = 0;
    for (;;) {
        __global const BVHNode *n = tlas + idx;
        const int cl = n->count_left, cr = n->count_right;
        float tl, tr;
        intersect_children((__global const float4 *)n, r.o8, r.inv8, tmin, hit->t, &tl, &tr);
        for (int side = 0; side < 2; ++side) {
            const int cnt = side ? cr : cl;
            if ((side ? tr : tl) == INFINITY || cnt <= 0) continue;
            const int first = side ? n->child_right : n->child_left;
            for (int i = first; i < first + cnt; ++i) {
                __global const Instance *in = instances + i;
                Hit h = bvh_closest_hit(BLAS_ROOT(blas, in->blas_offset), tris + 3 * in->tri_offset,
                                        OBJECT_ORIGIN(in, o), xf_vector1(in->world_to_object, d), tmin, hit->t);
                if (h.prim != PRIM_MISS) {
                    *hit = h;
                    hit->prim += in->tri_offset;
                    *inst = i;
                }
            }
            if (side) tr = INFINITY; else tl = INFINITY;
        }
        if (!bvh_next_closest(n->child_left, n->child_right, tl, tr, hit->t, stack_node, stack_t, &sp, &idx)) return;
    }
}

/* Whether some instance blocks (tmin, tmax). */
RT_INLINE int instances_any_hit(__global const BVHNode *tlas, __global const Instance *instances,
                                __global const BVHNode *blas, __global const float4 *tris, float3 o, float3 d,
                                float tmin, float tmax MOTION_TIME_PARAM)
{
    const BinaryRay r = binary_ray(o, d); /* the slab test's part: each instance's BLAS shears its own ray */
    int stack_node[BVH_STACK_SIZE];
    int sp = 0, idx = 0;
    for (;;) {
        __global const BVHNode *n = tlas + idx;
        float tl, tr;
        intersect_children((__global const float4 *)n, r.o8, r.inv8, tmin, tmax, &tl, &tr);
        int go[2] = {tl != INFINITY, tr != INFINITY};
        for (int side = 0; side < 2; ++side) {
            const int cnt = side ? n->count_right : n->count_left;
            if (!go[side] || cnt <= 0) continue;
            const int first = side ? n->child_right : n->child_left;
            for (int i = first; i < first + cnt; ++i) {
                __global const Instance *in = instances + i;
                if (bvh_any_hit(BLAS_ROOT(blas, in->blas_offset), tris + 3 * in->tri_offset,
                                OBJECT_ORIGIN(in, o), xf_vector1(in->world_to_object, d), tmin, tmax))
                    return 1;
            }
            go[side] = 0;
        }
        if (!bvh_next_any(n->child_left, n->child_right, go[0], go[1], stack_node, &sp, &idx)) return 0;
    }
}

/* -- shading: a hit found in a group's space, moved to the world, over lanes -------------------- */

/* row r of the 3x4 matrix at float `field` of the lanes' instance records, applied to (x, y, z, w) */
RT_INLINE pfloat xf_row(__global const Instance *instances, pint inst, int field, int r, pvec3 p, pfloat w)
{
    __global const float *f = (__global const float *)instances;
    const pint i = inst * STRIDE_INDEX(Instance) + field + 4 * r;
    return pgather(f, i) * p.x + pgather(f, i + 1) * p.y + pgather(f, i + 2) * p.z + pgather(f, i + 3) * w;
}

/* the lanes' M (field object_to_world) or M^-1 (world_to_object) times a point (w 1) or a vector (w 0) */
RT_INLINE pvec3 xf_lanes(__global const Instance *instances, pint inst, int field, pvec3 p, pfloat w)
{
    return pv3(xf_row(instances, inst, field, 0, p, w), xf_row(instances, inst, field, 1, p, w),
               xf_row(instances, inst, field, 2, p, w));
}

/* M^-T n: column c of M^-1 dotted with n */
RT_INLINE pvec3 xf_normal_lanes(__global const Instance *instances, pint inst, pvec3 n)
{
    __global const float *f = (__global const float *)instances;
    const pint i = inst * STRIDE_INDEX(Instance) + FIELD_INDEX(Instance, world_to_object);
    pfloat c[3];
    for (int k = 0; k < 3; ++k)
        c[k] = pgather(f, i + k) * n.x + pgather(f, i + 4 + k) * n.y + pgather(f, i + 8 + k) * n.z;
    return pv3(c[0], c[1], c[2]);
}

/* |M| e + |t|: row r of the absolute 3x4 matrix at `field` times (e, w) */
RT_INLINE pvec3 xf_abs_lanes(__global const Instance *instances, pint inst, int field, pvec3 e, pfloat w)
{
    __global const float *f = (__global const float *)instances;
    const pint i = inst * STRIDE_INDEX(Instance) + field;
    pfloat r[3];
    for (int k = 0; k < 3; ++k)
        r[k] = pabs(pgather(f, i + 4 * k)) * e.x + pabs(pgather(f, i + 4 * k + 1)) * e.y +
               pabs(pgather(f, i + 4 * k + 2)) * e.z + pabs(pgather(f, i + 4 * k + 3)) * w;
    return pv3(r[0], r[1], r[2]);
}

#define XF_GAMMA3 1.78813963e-07f /* 3 * 2^-24 / (1 - 3 * 2^-24), rounded up */

/* The lanes of `on` (inst valid there): the hit point p (error *err) found in the group's space,
 * moved to the world.  The bound grows as pbrt-v4's Transform of a Point3fi does, (1 + g3)|M| err
 * + g3 (|M||p| + |t|), plus what the ray's move into the group's space rounded, g3 |M| (|M^-1||p_w|
 * + |t'|) mapped back: a spawned ray's origin, moved there again, stays on its side. */
#ifdef HAS_MOTION
/* the lanes' motion at their time samples u: s dw (world) and s M^-1 dw (the group's space) */
RT_INLINE void instance_motion_lanes(__global const Instance *instances, pint inst, pfloat u, pvec3 *world,
                                     pvec3 *object)
{
    __global const float *f = (__global const float *)instances;
    const pint w = inst * STRIDE_INDEX(Instance) + FIELD_INDEX(Instance, motion_world);
    const pint o = inst * STRIDE_INDEX(Instance) + FIELD_INDEX(Instance, motion_object);
    const pfloat s = pclamp(pgather(f, w + 3) + pgather(f, o + 3) * u, 0.0f, 1.0f);
    *world = pv3_scale(pv3(pgather(f, w), pgather(f, w + 1), pgather(f, w + 2)), s);
    *object = pv3_scale(pv3(pgather(f, o), pgather(f, o + 1), pgather(f, o + 2)), s);
}
#define MOTION_LANES_PARAM , pfloat time
#define MOTION_LANES_ARG(u) , u
#else
#define MOTION_LANES_PARAM
#define MOTION_LANES_ARG(u)
#endif

RT_INLINE void instance_point_to_world(__global const Instance *instances, pint inst, pint on, pvec3 *p,
                                       pvec3 *err MOTION_LANES_PARAM)
{
    const int O2W = FIELD_INDEX(Instance, object_to_world), W2O = FIELD_INDEX(Instance, world_to_object);
    pvec3 pw = xf_lanes(instances, inst, O2W, *p, PFLOAT(1.0f));
    pvec3 e1 = pv3_add(pv3_scale(xf_abs_lanes(instances, inst, O2W, *err, PFLOAT(0.0f)), PFLOAT(1.0f + XF_GAMMA3)),
                       pv3_scale(xf_abs_lanes(instances, inst, O2W, pv3_abs(*p), PFLOAT(1.0f)), PFLOAT(XF_GAMMA3)));
    pvec3 back = pv3_scale(xf_abs_lanes(instances, inst, W2O, pv3_abs(pw), PFLOAT(1.0f)), PFLOAT(XF_GAMMA3));
#ifdef HAS_MOTION
    /* moved by s dw, one more rounding each way (here, and the ray's origin moved back by s M^-1 dw) */
    pvec3 dw, dobj;
    instance_motion_lanes(instances, inst, time, &dw, &dobj);
    pw = pv3_add(pw, dw);
    e1 = pv3_add(e1, pv3_scale(pv3_add(pv3_abs(pw), pv3_abs(dw)), PFLOAT(XF_GAMMA3)));
    back = pv3_add(back, pv3_scale(pv3_abs(dobj), PFLOAT(2.0f * XF_GAMMA3)));
#endif
    const pvec3 e2 = xf_abs_lanes(instances, inst, O2W, back, PFLOAT(0.0f));
    *p = pv3_sel(*p, pw, on);
    *err = pv3_sel(*err, pv3_add(e1, e2), on);
}

#endif
