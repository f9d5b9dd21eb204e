/* Traversal of the 4-wide BVH (pyopencl_rt/accel/bvh_wide.py) for CPU devices: closest hit and any hit.
 *
 * cl/accel/traverse.h makes bvh_closest_hit / bvh_any_hit the wide versions below when BVH_WIDE is
 * defined (same arguments and Hit result, but the first buffer holds the wide BVH instead of
 * BVHNode records).  Hit.prim stays the index into
 * the binary BVH's reordered triangle array, so prim_ids[prim] and triangle_normal(tris, prim) work
 * unchanged; the tris buffer itself is not read by the traversal.
 *
 * PoCL runs every work-item as scalar code, so the SIMD width comes from inside one work-item:
 * four child boxes per node in one float4 slab test, four triangles per Tri4 packet in one
 * float4 watertight test (as Embree's single-ray BVH4 kernels do).
 *
 * Buffer: nodes (struct WideNode, 128 bytes = 8 float4s) then Tri4 packets (struct Tri4, 160
 * bytes = 10 float4s), addressed in float4 units.  A node is six float4s of child bounds
 * (bmin_x, bmin_y, bmin_z, bmax_x, bmax_y, bmax_z: lane i = child slot i), then int4 child and
 * int4 count: count 0 = inner node at float4 offset child, count > 0 = leaf of count packets
 * starting at float4 offset child, count -1 = no child (box min = +inf, max = -inf).  A packet is
 * v0x, v0y, v0z, v1x, ..., v2z (float4 index 3 * vertex + axis), then int4 tri (-1 = padding
 * lane, whose vertices are NaN).  The root node is at offset 0.
 *
 * Stack: every wide level descends two binary levels (bvh_wide.py), so the wide depth is at most
 * 30 and, with at most 3 children pushed per node, the stack (WIDE_STACK_SIZE = 96 entries) cannot
 * overflow (checked on the host by validate_wide).  An entry is 8 bytes, an int code and the child's entry distance:
 * code >= 0 is an inner node's offset; a leaf is code = -1 - (parent node offset + slot), its
 * packets then read from the parent's child/count.  The stack is kept small because PoCL holds a
 * private copy per work-item of a work-group (a 2.3 KB stack crashed groups of 4096).
 */
#ifndef PYOPENCL_RT_BVH_WIDE_H
#define PYOPENCL_RT_BVH_WIDE_H

#include "accel/bvh.h"
#include "accel/masks.h"

/* SEL, VMIN, VMAX, abs4, any4, mask_bits4, lowest_bit, bit_count: accel/masks.h */

/* ---------------------------------------------------------------------------------------------
 * Per-ray constants.
 *
 * Boxes: the slab test picks each axis's near and far plane by the sign of the direction (as
 * Embree does) instead of min/max per axis, so it is a load offset and not a compare-and-blend:
 * near plane of x is bmin_x (float4 0) when inv_d.x >= 0, else bmax_x (float4 3).  inv_d =
 * safe_rcp3(d) is finite and never 0, so (plane - o) * inv_d has the order of the planes and no
 * NaN (safe_rcp's clamp keeps a ray lying in a face's plane inside that slab, as in the binary
 * test).  An absent child's box (min = +inf, max = -inf) gives near = +inf, far = -inf on every
 * axis whatever the sign, so it is missed without a separate check (with min/max it would
 * become an infinite interval, which is why the binary code tests count >= 0).
 *
 * Triangles: the axes (kx, ky, kz) and shear of ray_shear(d) are applied to a packet by loading
 * float4 3 * vertex + k, again a load offset rather than a select per coordinate.
 * --------------------------------------------------------------------------------------------- */
typedef struct {
    float3 o, d, inv_d;
    float3 inv_far;          /* inv_d * SLAB_FAR_SCALE, for the far planes (intersect_children4) */
    int nx, ny, nz;          /* float4 index of the near plane per axis (far = 3 + near mod 6) */
    int kx, ky, kz;          /* ray_shear's permutation */
    float okx, oky, okz;     /* origin permuted */
    float sx, sy;            /* ray_shear's shear constants */
} WideRay;

/* safe_rcp (common.h) without its fabs/copysign calls: the same value bit for bit. */
RT_INLINE float wide_rcp(float x)
{
    const uint b = as_uint(x);
    const float clamped = as_float((b & 0x80000000u) | as_uint(RCP_MIN_INPUT)); /* copysign(RCP_MIN_INPUT, x) */
    return 1.0f / (as_float(b & 0x7fffffffu) < RCP_MIN_INPUT ? clamped : x);
}

/* The constants of safe_rcp3(d) and ray_shear(d) (intersect.h), computed as they are there (same
 * values bit for bit) without the builtin calls (fabs, copysign, shuffle) PoCL leaves out of line. */
RT_INLINE WideRay wide_ray(float3 o, float3 d)
{
    WideRay r;
    r.o = o; r.d = d;
    r.inv_d = (float3)(wide_rcp(d.x), wide_rcp(d.y), wide_rcp(d.z));
    r.inv_far = r.inv_d * SLAB_FAR_SCALE;
    r.nx = r.inv_d.x >= 0.0f ? 0 : 3;
    r.ny = r.inv_d.y >= 0.0f ? 1 : 4;
    r.nz = r.inv_d.z >= 0.0f ? 2 : 5;
    const float ax = as_float(as_uint(d.x) & 0x7fffffffu), ay = as_float(as_uint(d.y) & 0x7fffffffu);
    const float az = as_float(as_uint(d.z) & 0x7fffffffu);
    const int kz = (ax > ay) ? ((ax > az) ? 0 : 2) : ((ay > az) ? 1 : 2);
    int kx = kz == 2 ? 0 : kz + 1;
    int ky = kx == 2 ? 0 : kx + 1;
    const float dz = comp3(d, kz);
    if (dz < 0.0f) { const int tmp = kx; kx = ky; ky = tmp; } /* keep the winding */
    r.kx = kx; r.ky = ky; r.kz = kz;
    r.okx = comp3(o, kx); r.oky = comp3(o, ky); r.okz = comp3(o, kz);
    r.sx = comp3(d, kx) / dz;
    r.sy = comp3(d, ky) / dz;
    return r;
}

/* Four child boxes in one slab test.  Returns the hit mask (-1 per hit lane) and the entry
 * distances in *enter.  Conservative as intersect_box (cl/accel/intersect.h, "Conservative on
 * purpose"): the far distances are widened by SLAB_FAR_SCALE and the host pads every box by 2^-20
 * of the scene's largest coordinate (bvh_wide.device_blob).  The widening is folded into the far
 * planes' inverse direction (inv_far), which rounds as much as widening each far distance does
 * (two roundings either way) and takes a multiply off the test's dependency chain; tmax joins the
 * minimum there.  No operand can be NaN (see above), so the plain comparisons of VMIN/VMAX equal
 * fmin/fmax without their NaN handling.  An entry distance of +inf counts as a miss, as INFINITY
 * is the binary test's miss value. */
RT_INLINE int4 intersect_children4(__global const float4 *node, const WideRay *r, float tmin, float tmax,
                                   float4 *enter)
{
    const float4 tnx = (node[r->nx] - r->o.x) * r->inv_d.x;
    const float4 tny = (node[r->ny] - r->o.y) * r->inv_d.y;
    const float4 tnz = (node[r->nz] - r->o.z) * r->inv_d.z;
    const float4 tfx = (node[3 - r->nx] - r->o.x) * r->inv_far.x;
    const float4 tfy = (node[5 - r->ny] - r->o.y) * r->inv_far.y;
    const float4 tfz = (node[7 - r->nz] - r->o.z) * r->inv_far.z;
    const float4 e = VMAX(VMAX(tnx, tny), VMAX(tnz, (float4)(tmin)));
    const float4 l = VMIN(VMIN(tfx, tfy), VMIN(tfz, (float4)(tmax)));
    *enter = e;
    return (e <= l) & (e < (float4)(INFINITY));
}

/* ---------------------------------------------------------------------------------------------
 * Watertight test of four triangles (one Tri4 packet): intersect_triangle (cl/accel/intersect.h) per
 * lane, with the same arithmetic in the same order, so each lane gives the scalar test's
 * result bit for bit:
 *  - FP_CONTRACT is off (common.h): the edge function of a shared edge must be the exact
 *    negation in both triangles, which a fused multiply-add would break.
 *  - An edge function that rounds to exactly 0 is recomputed in double precision (where the
 *    device has fp64), per lane: only the lanes with a zero take the double results, and the
 *    double path runs only when some lane needs it.
 *  - t comes from the plane equation n.(v0 - o) / n.d with n = (v1 - v0) x (v2 - v0), not from
 *    the paper's T = U*Az + V*Bz + W*Cz, which cancels catastrophically on long slivers (its sign
 *    flipped and rays left thin closed meshes from inside; tests/accel/test_traversal.py).  The plane
 *    equation is evaluated in the original x, y, z order, as dot() and cross() do.
 *  - Padding lanes have NaN vertices: U, V, W and det are NaN, and "det != 0" is written as
 *    det < 0 || det > 0, which is false for NaN, so they are rejected with the lanes the sign
 *    test rejects (and NaN == 0 is false: no double path; t > tmin && t < tmax would reject
 *    them too).  A packet whose four lanes are all rejected there returns before the plane
 *    equation, the common case.
 * Returns the hit mask; *t_out, *U_out, *V_out, *W_out hold the lanes' values.
 * --------------------------------------------------------------------------------------------- */
RT_INLINE int4 intersect_tri4(__global const float4 *pk, const WideRay *r, float tmin, float tmax,
                              float4 *t_out, float4 *U_out, float4 *V_out, float4 *W_out)
{
    /* vertices relative to the origin, axes permuted to (kx, ky, kz): float4 3 * vertex + k */
    const float4 Ax = pk[r->kx] - r->okx, Ay = pk[r->ky] - r->oky, Az = pk[r->kz] - r->okz;
    const float4 Bx = pk[3 + r->kx] - r->okx, By = pk[3 + r->ky] - r->oky, Bz = pk[3 + r->kz] - r->okz;
    const float4 Cx = pk[6 + r->kx] - r->okx, Cy = pk[6 + r->ky] - r->oky, Cz = pk[6 + r->kz] - r->okz;
    const float4 ax = Ax - r->sx * Az, ay = Ay - r->sy * Az;
    const float4 bx = Bx - r->sx * Bz, by = By - r->sy * Bz;
    const float4 cx = Cx - r->sx * Cz, cy = Cy - r->sy * Cz;
    float4 U = cx * by - cy * bx;
    float4 V = ax * cy - ay * cx;
    float4 W = bx * ay - by * ax;
#ifdef cl_khr_fp64
    const int4 zero = (U == 0.0f) | (V == 0.0f) | (W == 0.0f);
    if (any4(zero)) {
        const double4 dax = convert_double4(ax), day = convert_double4(ay);
        const double4 dbx = convert_double4(bx), dby = convert_double4(by);
        const double4 dcx = convert_double4(cx), dcy = convert_double4(cy);
        U = SEL(U, convert_float4(dcx * dby - dcy * dbx), zero);
        V = SEL(V, convert_float4(dax * dcy - day * dcx), zero);
        W = SEL(W, convert_float4(dbx * day - dby * dax), zero);
    }
#endif
    const int4 mixed = ((U < 0.0f) | (V < 0.0f) | (W < 0.0f)) & ((U > 0.0f) | (V > 0.0f) | (W > 0.0f));
    const float4 det = U + V + W;
    const int4 inside = ~mixed & ((det < 0.0f) | (det > 0.0f)); /* det != 0, and false for NaN */
    if (!any4(inside)) /* the common case: the ray passes outside all four */
        return inside;
    /* plane equation, original axis order: n = (p1 - p0) x (p2 - p0), a = p0 - o */
    const float4 p0x = pk[0], p0y = pk[1], p0z = pk[2];
    const float4 e1x = pk[3] - p0x, e1y = pk[4] - p0y, e1z = pk[5] - p0z;
    const float4 e2x = pk[6] - p0x, e2y = pk[7] - p0y, e2z = pk[8] - p0z;
    const float4 nx = e1y * e2z - e1z * e2y;
    const float4 ny = e1z * e2x - e1x * e2z;
    const float4 nz = e1x * e2y - e1y * e2x;
    const float4 den = nx * r->d.x + ny * r->d.y + nz * r->d.z;
    const float4 ax0 = p0x - r->o.x, ay0 = p0y - r->o.y, az0 = p0z - r->o.z;
    const float4 num = nx * ax0 + ny * ay0 + nz * az0;
    /* Slivers and a numerator whose sign is in doubt: t in double, per lane, exactly as
     * intersect_triangle does (see its comment; SLIVER_CANCELLATION and NUM_DOUBT there). */
    const float4 nabs_x = abs4(e1y * e2z) + abs4(e1z * e2y);
    const float4 nabs_y = abs4(e1z * e2x) + abs4(e1x * e2z);
    const float4 nabs_z = abs4(e1x * e2y) + abs4(e1y * e2x);
    const int4 sliver = abs4(nx) + abs4(ny) + abs4(nz) < SLIVER_CANCELLATION * (nabs_x + nabs_y + nabs_z);
    const int4 doubt = abs4(num) <= NUM_DOUBT * (nabs_x * abs4(ax0) + nabs_y * abs4(ay0) + nabs_z * abs4(az0));
    float4 tt = num / den;
    int4 ok = den != 0.0f;
#ifdef cl_khr_fp64
    const int4 refine = inside & (sliver | doubt);
    if (any4(refine)) {
        const double4 q0x = convert_double4(p0x), q0y = convert_double4(p0y), q0z = convert_double4(p0z);
        const double4 f1x = convert_double4(pk[3]) - q0x, f1y = convert_double4(pk[4]) - q0y, f1z = convert_double4(pk[5]) - q0z;
        const double4 f2x = convert_double4(pk[6]) - q0x, f2y = convert_double4(pk[7]) - q0y, f2z = convert_double4(pk[8]) - q0z;
        const double4 mx = f1y * f2z - f1z * f2y, my = f1z * f2x - f1x * f2z, mz = f1x * f2y - f1y * f2x;
        const double4 dden = mx * (double)r->d.x + my * (double)r->d.y + mz * (double)r->d.z;
        const double4 dnum = mx * (q0x - (double)r->o.x) + my * (q0y - (double)r->o.y) + mz * (q0z - (double)r->o.z);
        tt = SEL(tt, convert_float4(dnum / dden), refine);
        ok = SEL(ok, convert_int4(dden != 0.0), refine);
    }
#else
    ok &= ~doubt;
#endif
    *t_out = tt; *U_out = U; *V_out = V; *W_out = W;
    return inside & ok & (tt > tmin) & (tt < tmax);
}

RT_INLINE float lane4(float4 v, int k) { return k == 0 ? v.s0 : (k == 1 ? v.s1 : (k == 2 ? v.s2 : v.s3)); }

/* Closest hit of a leaf's packets: the nearest lane of each packet (the lowest lane among equal
 * t, i.e. the scalar loop's order: a later triangle replaces a hit only when strictly nearer). */
RT_INLINE void intersect_leaf4(__global const float4 *pk, int count, const WideRay *r, float tmin, Hit *hit)
{
    for (int p = 0; p < count; ++p, pk += TRI4_UNITS) {
        float4 t, U, V, W;
        const int4 m = intersect_tri4(pk, r, tmin, hit->t, &t, &U, &V, &W);
        if (!any4(m))
            continue;
        const float4 tm = SEL((float4)(INFINITY), t, m);
        const float best = FAST_MIN(FAST_MIN(tm.s0, tm.s1), FAST_MIN(tm.s2, tm.s3));
        const int k = tm.s0 == best ? 0 : (tm.s1 == best ? 1 : (tm.s2 == best ? 2 : 3));
        const float det = lane4(U, k) + lane4(V, k) + lane4(W, k);
        const float rcp = 1.0f / det;
        hit->t = best;
        hit->u = lane4(V, k) * rcp;
        hit->v = lane4(W, k) * rcp;
        hit->prim = ((__global const int *)(pk + 9))[k];
    }
}

RT_INLINE int occluded_leaf4(__global const float4 *pk, int count, const WideRay *r, float tmin, float tmax)
{
    for (int p = 0; p < count; ++p, pk += TRI4_UNITS) {
        float4 t, U, V, W;
        if (any4(intersect_tri4(pk, r, tmin, tmax, &t, &U, &V, &W)))
            return 1;
    }
    return 0;
}

/* One compare-exchange stage of a 4-lane sorting network on (key, lane id) pairs: each lane has
 * a partner (pk, pl are the keys and ids permuted accordingly); lanes flagged in `lower` keep
 * the smaller key of their pair, the others the larger.  Both lanes of a pair take the same
 * decision (swap iff the upper key is strictly smaller), so the ids stay a permutation. */
RT_INLINE void sort_stage(float4 *k, int4 *l, float4 pk, int4 pl, int4 lower)
{
    const int4 swap = SEL(*k < pk, pk < *k, lower);
    *k = SEL(*k, pk, swap);
    *l = SEL(*l, pl, swap);
}

/* Sorts keys ascending with their lane ids: the network (0,1)(2,3), (0,2)(1,3), (1,2). */
RT_INLINE void sort4(float4 *k, int4 *l)
{
    sort_stage(k, l, (*k).s1032, (*l).s1032, (int4)(-1, 0, -1, 0));
    sort_stage(k, l, (*k).s2301, (*l).s2301, (int4)(-1, -1, 0, 0));
    sort_stage(k, l, (*k).s0213, (*l).s0213, (int4)(0, -1, 0, 0));
}

/* Stack code of child slot k of the node at offset off (see the top of this file). */
#define WIDE_CODE(off, k) (count[k] == 0 ? child[k] : -1 - ((off) + (k)))

RT_INLINE void wide_decode(__global const float4 *base, int code, int *off, int *cnt)
{
    if (code >= 0) { *off = code; *cnt = 0; return; }
    const int ref = -1 - code;
    __global const float4 *parent = base + (ref & ~7);
    *off = ((__global const int *)(parent + 6))[ref & 7];
    *cnt = ((__global const int *)(parent + 7))[ref & 7];
}

/* Closest hit in (tmin, tmax).  hit.prim = PRIM_MISS when nothing is hit.  Ordered traversal: the hit
 * children of a node are visited nearest entry first (the others pushed far to near), leaves
 * included, and a popped entry is skipped when it was entered beyond the closest hit since. */
RT_INLINE Hit bvh_wide_closest_hit(__global const void *bvh, __global const float4 *tris,
                                   float3 o, float3 d, float tmin, float tmax)
{
    __global const float4 *base = (__global const float4 *)bvh;
    Hit hit; hit.t = tmax; hit.u = 0.0f; hit.v = 0.0f; hit.prim = PRIM_MISS;
    const WideRay r = wide_ray(o, d);
    int stack_code[WIDE_STACK_SIZE];
    float stack_t[WIDE_STACK_SIZE];
    int sp = 0;
    int off = 0, cnt = 0; /* the root node */
    for (;;) {
        if (cnt == 0) {
            __global const float4 *node = base + off;
            float4 enter;
            const int4 m = intersect_children4(node, &r, tmin, hit.t, &enter);
            const int bits = mask_bits4(m);
            if (bits) {
                __global const int *child = (__global const int *)(node + 6);
                __global const int *count = (__global const int *)(node + 7);
                if ((bits & (bits - 1)) == 0) { /* one child: no sorting */
                    const int k = lowest_bit(bits);
                    off = child[k]; cnt = count[k];
                    continue;
                }
                float4 key = SEL((float4)(INFINITY), enter, m); /* misses sort last */
                int4 lane = (int4)(0, 1, 2, 3);
                sort4(&key, &lane);
                const int n = bit_count(bits);
                /* push the others far to near */
                if (n == 4) { stack_code[sp] = WIDE_CODE(off, lane.s3); stack_t[sp] = key.s3; ++sp; }
                if (n >= 3) { stack_code[sp] = WIDE_CODE(off, lane.s2); stack_t[sp] = key.s2; ++sp; }
                stack_code[sp] = WIDE_CODE(off, lane.s1); stack_t[sp] = key.s1; ++sp;
                off = child[lane.s0]; cnt = count[lane.s0];
                continue;
            }
        } else {
            intersect_leaf4(base + off, cnt, &r, tmin, &hit);
        }
        /* pop, skipping entries entered beyond the closest hit found since they were pushed */
        for (;;) {
            if (sp == 0) return hit;
            --sp;
            if (stack_t[sp] <= hit.t) { wide_decode(base, stack_code[sp], &off, &cnt); break; }
        }
    }
}

/* Any hit in (tmin, tmax): returns 1 as soon as one triangle is hit (children in slot order). */
RT_INLINE int bvh_wide_any_hit(__global const void *bvh, __global const float4 *tris,
                               float3 o, float3 d, float tmin, float tmax)
{
    __global const float4 *base = (__global const float4 *)bvh;
    const WideRay r = wide_ray(o, d);
    int stack_code[WIDE_STACK_SIZE];
    int sp = 0;
    int off = 0, cnt = 0;
    for (;;) {
        if (cnt == 0) {
            __global const float4 *node = base + off;
            float4 enter;
            const int4 m = intersect_children4(node, &r, tmin, tmax, &enter);
            int bits = mask_bits4(m);
            if (bits) {
                __global const int *child = (__global const int *)(node + 6);
                __global const int *count = (__global const int *)(node + 7);
                const int k = lowest_bit(bits);
                for (bits &= bits - 1; bits; bits &= bits - 1)
                    stack_code[sp++] = WIDE_CODE(off, lowest_bit(bits));
                off = child[k]; cnt = count[k];
                continue;
            }
        } else if (occluded_leaf4(base + off, cnt, &r, tmin, tmax)) {
            return 1;
        }
        if (sp == 0) return 0;
        --sp;
        wide_decode(base, stack_code[sp], &off, &cnt);
    }
}

#endif
