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

#include "accel/motion.h"
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

/* Motion blur (HAS_MOTION, pbrt-v4's ActiveTransform): a moving instance (its record's `motion` >= 0)
 * is at M(s) = T(s) R(s) S(s) (seen from its pivot) at a ray's time sample u, s = clamp(a + b u, 0, 1):
 * T and S interpolated linearly between the ends, R by slerp (abi.MOTION, pyopencl_rt/accel/motion.py).
 * Each ray that enters it moves into the group's space by M(s)^-1, computed there; the TLAS boxes
 * hold the whole way.  The time is each ray's (its path's), passed as `time`. */
#ifdef HAS_MOTION
#define MOTION_TIME_PARAM , __global const Motion *motions, float time
#define MOTION_TIME_ARG(u) , instance_motion, u

/* the ray (o, d) in the group's space of instance `in` at its time */
#define OBJECT_RAY(in, o, d, oo, od)                                                              \
    do {                                                                                            \
        if ((in)->motion >= 0) {                                                                    \
            float mm_[12], mw_[12];                                                                 \
            motion_matrices(motions + (in)->motion, time, mm_, mw_);                                \
            oo = xf_point_private(mw_, o);                                                          \
            od = xf_vector_private(mw_, d);                                                         \
        } else {                                                                                    \
            oo = xf_point1((in)->world_to_object, o);                                               \
            od = xf_vector1((in)->world_to_object, d);                                              \
        }                                                                                           \
    } while (0)
#else
#define MOTION_TIME_PARAM
#define MOTION_TIME_ARG(u)
#define OBJECT_RAY(in, o, d, oo, od) \
    do { oo = xf_point1((in)->world_to_object, o); od = xf_vector1((in)->world_to_object, d); } while (0)
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
                float3 oo, od;
                OBJECT_RAY(in, o, d, oo, od);
                Hit h = bvh_closest_hit(BLAS_ROOT(blas, in->blas_offset), tris + 3 * in->tri_offset, oo, od, tmin,
                                        hit->t);
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
                float3 oo, od;
                OBJECT_RAY(in, o, d, oo, od);
                if (bvh_any_hit(BLAS_ROOT(blas, in->blas_offset), tris + 3 * in->tri_offset, oo, od, tmin, tmax))
                    return 1;
            }
            go[side] = 0;
        }
        if (!bvh_next_any(n->child_left, n->child_right, go[0], go[1], stack_node, &sp, &idx)) return 0;
    }
}

/* -- shading: a hit found in a group's space, moved to the world, over lanes -------------------- */

/* The lanes' M (object to world) and M^-1 (world to object) as 3x4 rows, each entry over the lanes:
 * their instance records' (gathered), or, for a moving instance, its matrices at the lane's time */
typedef struct {
    pfloat o2w[12], w2o[12];
} LaneXf;

#ifdef HAS_MOTION
#define MOTION_LANES_PARAM , __global const Motion *motions, pfloat time
#define MOTION_LANES_ARG(u) , instance_motion, u
#else
#define MOTION_LANES_PARAM
#define MOTION_LANES_ARG(u)
#endif

RT_INLINE LaneXf lane_xf(__global const Instance *instances, pint inst, pint on MOTION_LANES_PARAM)
{
    __global const float *f = (__global const float *)instances;
    const pint i = inst * STRIDE_INDEX(Instance);
    LaneXf x;
    for (int k = 0; k < 12; ++k) {
        x.o2w[k] = pgather(f, i + FIELD_INDEX(Instance, object_to_world) + k);
        x.w2o[k] = pgather(f, i + FIELD_INDEX(Instance, world_to_object) + k);
    }
#ifdef HAS_MOTION
    for (int l = 0; l < PACKET_WIDTH; ++l) {
        if (!PLANE_I(on, l)) continue;
        __global const Instance *in = instances + PLANE_I(inst, l);
        if (in->motion < 0) continue;
        float m[12], w[12];
        motion_matrices(motions + in->motion, PLANE(time, l), m, w);
        for (int k = 0; k < 12; ++k) {
            PLANE(x.o2w[k], l) = m[k];
            PLANE(x.w2o[k], l) = w[k];
        }
    }
#endif
    return x;
}

/* the 3x4 matrix m (o2w or w2o of a LaneXf) times a point (w 1) or a vector (w 0) */
RT_INLINE pvec3 xf_apply(const pfloat *m, pvec3 p, pfloat w)
{
    pfloat r[3];
    for (int k = 0; k < 3; ++k) r[k] = m[4 * k] * p.x + m[4 * k + 1] * p.y + m[4 * k + 2] * p.z + m[4 * k + 3] * w;
    return pv3(r[0], r[1], r[2]);
}

/* M^-T n: column c of M^-1 dotted with n */
RT_INLINE pvec3 xf_normal(const LaneXf *x, pvec3 n)
{
    pfloat c[3];
    for (int k = 0; k < 3; ++k) c[k] = x->w2o[k] * n.x + x->w2o[4 + k] * n.y + x->w2o[8 + k] * n.z;
    return pv3(c[0], c[1], c[2]);
}

/* |m| e + |t| w: the absolute 3x4 matrix m times (e, w) */
RT_INLINE pvec3 xf_abs(const pfloat *m, pvec3 e, pfloat w)
{
    pfloat r[3];
    for (int k = 0; k < 3; ++k)
        r[k] = pabs(m[4 * k]) * e.x + pabs(m[4 * k + 1]) * e.y + pabs(m[4 * k + 2]) * e.z + pabs(m[4 * k + 3]) * w;
    return pv3(r[0], r[1], r[2]);
}

#define XF_GAMMA3 1.78813963e-07f /* 3 * 2^-24 / (1 - 3 * 2^-24), rounded up */

/* The lanes of `on`: the hit point p (error *err) found in the group's space, moved to the world.
 * The bound grows as pbrt-v4's Transform of a Point3fi does, (1 + g3)|M| err + g3 (|M||p| + |t|),
 * plus what the ray's move into the group's space rounded, g3 |M| (|M^-1||p_w| + |t'|) mapped back:
 * a spawned ray's origin, moved there again, stays on its side. */
RT_INLINE void instance_point_to_world(const LaneXf *x, pint on, pvec3 *p, pvec3 *err)
{
    const pvec3 pw = xf_apply(x->o2w, *p, PFLOAT(1.0f));
    const pvec3 e1 = pv3_add(pv3_scale(xf_abs(x->o2w, *err, PFLOAT(0.0f)), PFLOAT(1.0f + XF_GAMMA3)),
                             pv3_scale(xf_abs(x->o2w, pv3_abs(*p), PFLOAT(1.0f)), PFLOAT(XF_GAMMA3)));
    const pvec3 back = pv3_scale(xf_abs(x->w2o, pv3_abs(pw), PFLOAT(1.0f)), PFLOAT(XF_GAMMA3));
    const pvec3 e2 = xf_abs(x->o2w, back, PFLOAT(0.0f));
    *p = pv3_sel(*p, pw, on);
    *err = pv3_sel(*err, pv3_add(e1, e2), on);
}

#endif
