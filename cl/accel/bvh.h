/* Stack-based BVH traversal: closest hit and any hit.
 *
 * Node layout (struct BVHNode, generated from pyopencl_rt/device/abi.py, 64 bytes):
 *
 *     offset  0  float bmin_left[3]   int child_left     box of the left child, then its index
 *     offset 16  float bmax_left[3]   int count_left
 *     offset 32  float bmin_right[3]  int child_right
 *     offset 48  float bmax_right[3]  int count_right
 *
 * Each node holds the boxes of its two children (Aila & Laine 2009), so one 64-byte fetch tests
 * both children and picks the nearer.  For a child, count == 0 means an inner node whose index
 * is child; count > 0 means a leaf of triangles [child, child + count) of the reordered triangle
 * array; count == -1 means no child (its box is empty and never hit).  Node 0 is the root.
 *
 * Triangles are stored reordered, three float4 vertices each (48 bytes), so a leaf is a
 * contiguous range; prim_ids maps a reordered index back to the caller's face index.
 *
 * The builder caps the depth at 60, so the stack (BVH_STACK_SIZE = 64 entries) cannot overflow:
 * at most one entry is pushed per level.
 */
#ifndef PYOPENCL_RT_BVH_H
#define PYOPENCL_RT_BVH_H

#include "accel/intersect.h"

#define FAST_MIN(a, b) ((a) < (b) ? (a) : (b))
#define FAST_MAX(a, b) ((a) > (b) ? (a) : (b))

typedef struct {
    float t, u, v;
    int prim; /* reordered triangle index, PRIM_MISS; scene.h adds shapes */
} Hit;


RT_INLINE void intersect_leaf(float3 o, float3 d, RayShear sh, __global const float4 *tris, int first, int count,
                           float tmin, Hit *hit)
{
    for (int i = first; i < first + count; ++i) {
        float t, u, v;
        if (intersect_triangle(o, d, sh, tris[3 * i].xyz, tris[3 * i + 1].xyz, tris[3 * i + 2].xyz,
                               tmin, hit->t, &t, &u, &v)) {
            hit->t = t; hit->u = u; hit->v = v; hit->prim = i;
        }
    }
}

RT_INLINE int occluded_leaf(float3 o, float3 d, RayShear sh, __global const float4 *tris, int first, int count,
                         float tmin, float tmax)
{
    for (int i = first; i < first + count; ++i) {
        float t, u, v;
        if (intersect_triangle(o, d, sh, tris[3 * i].xyz, tris[3 * i + 1].xyz, tris[3 * i + 2].xyz,
                               tmin, tmax, &t, &u, &v))
            return 1;
    }
    return 0;
}

/* Both child boxes of a node in one 8-wide slab test (lanes 0-2: left child, 4-6: right).
 * The node is read as four aligned float4s: (bmin_left, child_left), (bmax_left, count_left),
 * (bmin_right, child_right), (bmax_right, count_right) -- the BVHNode layout above.
 * Sets *tl / *tr to the entry distances, INFINITY for a miss or an absent child. */
RT_INLINE void intersect_children(__global const float4 *node, float8 o8, float8 inv8, float tmin, float tmax,
                               float *tl, float *tr)
{
    const float4 q0 = node[0], q1 = node[1], q2 = node[2], q3 = node[3];
    /* lanes 3 and 7 repeat z: harmless (a vector literal, not shuffle2: no 32-byte vector passed to a
     * built-in, cl/cpu_builtins.h) */
    const float8 t0 = ((float8)(q0.xyz, q0.z, q2.xyz, q2.z) - o8) * inv8;
    const float8 t1 = ((float8)(q1.xyz, q1.z, q3.xyz, q3.z) - o8) * inv8;
    /* No operand here can be NaN (safe_rcp3 keeps inv_d finite; empty boxes give +-inf), so
     * the plain comparisons below equal fmin/fmax, without IEEE fmin's NaN handling, which
     * costs a compare-and-blend per call on x86. */
    const float8 tn = select(t1, t0, t0 < t1), tf = select(t0, t1, t0 < t1);
    const float enter_l = FAST_MAX(FAST_MAX(tn.s0, tn.s1), FAST_MAX(tn.s2, tmin));
    const float enter_r = FAST_MAX(FAST_MAX(tn.s4, tn.s5), FAST_MAX(tn.s6, tmin));
    const float leave_l = FAST_MIN(FAST_MIN(tf.s0, tf.s1), tf.s2) * SLAB_FAR_SCALE;
    const float leave_r = FAST_MIN(FAST_MIN(tf.s4, tf.s5), tf.s6) * SLAB_FAR_SCALE;
    *tl = (as_int(q1.w) >= 0 && enter_l <= FAST_MIN(leave_l, tmax)) ? enter_l : INFINITY;
    *tr = (as_int(q3.w) >= 0 && enter_r <= FAST_MIN(leave_r, tmax)) ? enter_r : INFINITY;
}

/* A ray's constants for the binary traversal: the watertight test's shear, and the slab test's
 * origin and inverse direction for both children at once (intersect_children) */
typedef struct {
    RayShear sh;
    float8 o8, inv8;
} BinaryRay;

RT_INLINE BinaryRay binary_ray(float3 o, float3 d)
{
    BinaryRay r;
    r.sh = ray_shear(d);
    const float3 inv_d = safe_rcp3(d);
    r.o8 = (float8)(o, o.z, o, o.z);
    r.inv8 = (float8)(inv_d, inv_d.z, inv_d, inv_d.z);
    return r;
}

/* The next node of a closest-hit traversal (this file's, and the instances' top level,
 * accel/instances.h) once a node's children are tested: tl, tr their entry distances (INFINITY
 * where not entered, or where a leaf is done).  The nearer entered child, the farther one pushed
 * with its distance; with neither, the next node popped, skipping the nodes entered beyond the
 * closest hit t found since they were pushed.  Returns 0 when the stack is empty: the end. */
RT_INLINE int bvh_next_closest(int left, int right, float tl, float tr, float t, int *stack_node, float *stack_t,
                               int *sp, int *idx)
{
    if (tl != INFINITY && tr != INFINITY) {
        if (tl <= tr) { stack_node[*sp] = right; stack_t[*sp] = tr; *idx = left; }
        else          { stack_node[*sp] = left;  stack_t[*sp] = tl; *idx = right; }
        ++*sp;
        return 1;
    }
    if (tl != INFINITY) { *idx = left; return 1; }
    if (tr != INFINITY) { *idx = right; return 1; }
    while (*sp > 0) {
        --*sp;
        if (stack_t[*sp] <= t) { *idx = stack_node[*sp]; return 1; }
    }
    return 0;
}

/* The same for an any-hit traversal: the children to enter in any order, no distances. */
RT_INLINE int bvh_next_any(int left, int right, int go_left, int go_right, int *stack_node, int *sp, int *idx)
{
    if (go_left && go_right) { stack_node[(*sp)++] = right; *idx = left; return 1; }
    if (go_left) { *idx = left; return 1; }
    if (go_right) { *idx = right; return 1; }
    if (*sp == 0) return 0;
    *idx = stack_node[--*sp];
    return 1;
}

/* Closest hit in (tmin, tmax).  hit.prim = PRIM_MISS when nothing is hit. */
RT_INLINE Hit bvh_closest_hit(__global const BVHNode *nodes, __global const float4 *tris,
                           float3 o, float3 d, float tmin, float tmax)
{
    Hit hit; hit.t = tmax; hit.u = 0.0f; hit.v = 0.0f; hit.prim = PRIM_MISS;
    const BinaryRay r = binary_ray(o, d);
    int stack_node[BVH_STACK_SIZE], sp = 0, idx = 0;
    float stack_t[BVH_STACK_SIZE];
    for (;;) {
        __global const BVHNode *n = nodes + idx;
        const int cl = n->count_left, cr = n->count_right;
        /* an absent child (count -1) has an empty box, min=+inf > max=-inf, which the slab
         * test's fmin/fmax would turn into an infinite interval: intersect_children skips it */
        float tl, tr;
        intersect_children((__global const float4 *)n, r.o8, r.inv8, tmin, hit.t, &tl, &tr);
        if (tl != INFINITY && cl > 0) { intersect_leaf(o, d, r.sh, tris, n->child_left, cl, tmin, &hit); tl = INFINITY; }
        if (tr != INFINITY && cr > 0) { intersect_leaf(o, d, r.sh, tris, n->child_right, cr, tmin, &hit); tr = INFINITY; }
        if (!bvh_next_closest(n->child_left, n->child_right, tl, tr, hit.t, stack_node, stack_t, &sp, &idx))
            return hit;
    }
}

/* Any hit in (tmin, tmax): returns 1 as soon as one triangle is hit. */
RT_INLINE int bvh_any_hit(__global const BVHNode *nodes, __global const float4 *tris,
                       float3 o, float3 d, float tmin, float tmax)
{
    const BinaryRay r = binary_ray(o, d);
    int stack_node[BVH_STACK_SIZE], sp = 0, idx = 0;
    for (;;) {
        __global const BVHNode *n = nodes + idx;
        float tl, tr;
        intersect_children((__global const float4 *)n, r.o8, r.inv8, tmin, tmax, &tl, &tr);
        int go_left = tl != INFINITY, go_right = tr != INFINITY;
        if (go_left && n->count_left > 0) {
            if (occluded_leaf(o, d, r.sh, tris, n->child_left, n->count_left, tmin, tmax)) return 1;
            go_left = 0;
        }
        if (go_right && n->count_right > 0) {
            if (occluded_leaf(o, d, r.sh, tris, n->child_right, n->count_right, tmin, tmax)) return 1;
            go_right = 0;
        }
        if (!bvh_next_any(n->child_left, n->child_right, go_left, go_right, stack_node, &sp, &idx)) return 0;
    }
}

/* Unit geometric normal (v1 - v0) x (v2 - v0) of reordered triangle i (Embree's orientation). */
RT_INLINE float3 triangle_normal(__global const float4 *tris, int i)
{
    const float3 p0 = tris[3 * i].xyz, p1 = tris[3 * i + 1].xyz, p2 = tris[3 * i + 2].xyz;
    return normalize(cross(p1 - p0, p2 - p0));
}

#endif
