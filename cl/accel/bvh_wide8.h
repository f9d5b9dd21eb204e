/* Traversal of the 8-wide BVH (pyopencl_rt/accel/bvh_wide.py, width=8) for AVX2 CPUs: closest hit
 * and any hit.
 *
 * The 4-wide traversal (bvh_wide.h) with eight lanes: eight child boxes per node in one float8
 * slab test and eight triangles per Tri8 packet in one float8 watertight test, one AVX2 register
 * each (as Embree's single-ray BVH8 kernels on AVX2).  cl/accel/traverse.h makes
 * bvh_closest_hit / bvh_any_hit these functions when BVH_WIDE8 is defined.
 *
 * Buffer: nodes (struct Wide8Node, 256 bytes = 8 float8s) then Tri8 packets (struct Tri8, 320 bytes
 * = 10 float8s), addressed in float8 units: a node is six float8s of child bounds (bmin_x, bmin_y,
 * bmin_z, bmax_x, bmax_y, bmax_z: lane i = child slot i), then int8 child and int8 count, with
 * bvh_wide.h's meaning (0 inner, > 0 leaf of count packets, -1 absent with an empty box).  A
 * packet is v0x, v0y, ..., v2z (float8 index 3 * vertex + axis), then int8 tri (-1 = padding lane,
 * NaN vertices).  The host makes every binary subtree of up to 8 triangles one leaf (one packet);
 * larger binary leaves (the SAH allows up to 64 triangles) span several packets.
 *
 * Stack: every 8-wide level descends three binary levels, so the depth is at most 20 and, with at
 * most 7 children pushed per node, WIDE8_STACK_SIZE = 144 entries cannot overflow (checked on the
 * host by validate_wide).  Entries are coded as in bvh_wide.h: a node offset is a multiple of 8
 * units and a slot is below 8, so a leaf's code -1 - (parent offset + slot) still decodes.
 */
#ifndef PYOPENCL_RT_BVH_WIDE8_H
#define PYOPENCL_RT_BVH_WIDE8_H

/* WideRay, wide_ray, SEL/VMIN/VMAX (any width), lowest_bit, bit_count, WIDE_CODE */
#include "accel/bvh_wide.h"

/* mask_bits8, any8, abs8, lane8: accel/masks.h */

/* Eight child boxes in one slab test: intersect_children4 with eight lanes (same arithmetic, same
 * conservative widening; see there and "Conservative on purpose" in intersect.h). */
RT_INLINE int8 intersect_children8(__global const float8 *node, const WideRay *r, float tmin, float tmax,
                                   float8 *enter)
{
    const float8 tnx = (node[r->nx] - r->o.x) * r->inv_d.x;
    const float8 tny = (node[r->ny] - r->o.y) * r->inv_d.y;
    const float8 tnz = (node[r->nz] - r->o.z) * r->inv_d.z;
    const float8 tfx = (node[3 - r->nx] - r->o.x) * r->inv_far.x;
    const float8 tfy = (node[5 - r->ny] - r->o.y) * r->inv_far.y;
    const float8 tfz = (node[7 - r->nz] - r->o.z) * r->inv_far.z;
    const float8 e = VMAX(VMAX(tnx, tny), VMAX(tnz, (float8)(tmin)));
    const float8 l = VMIN(VMIN(tfx, tfy), VMIN(tfz, (float8)(tmax)));
    *enter = e;
    return (e <= l) & (e < (float8)(INFINITY));
}

#ifdef cl_khr_fp64
/* The double-precision fallbacks of intersect_tri4 on four lanes at a time: double8 would pass
 * through PoCL's builtins with a non-AVX-512 ABI (a warning per call site, and calls). */
RT_INLINE float4 edge_double4(float4 a, float4 b, float4 c, float4 d)
{
    return convert_float4(convert_double4(a) * convert_double4(b) - convert_double4(c) * convert_double4(d));
}

RT_INLINE float4 plane_t_double4(float4 p0x, float4 p0y, float4 p0z, float4 p1x, float4 p1y, float4 p1z,
                                 float4 p2x, float4 p2y, float4 p2z, const WideRay *r, int4 *ok)
{
    const double4 q0x = convert_double4(p0x), q0y = convert_double4(p0y), q0z = convert_double4(p0z);
    const double4 f1x = convert_double4(p1x) - q0x, f1y = convert_double4(p1y) - q0y, f1z = convert_double4(p1z) - q0z;
    const double4 f2x = convert_double4(p2x) - q0x, f2y = convert_double4(p2y) - q0y, f2z = convert_double4(p2z) - q0z;
    const double4 mx = f1y * f2z - f1z * f2y, my = f1z * f2x - f1x * f2z, mz = f1x * f2y - f1y * f2x;
    const double4 dden = mx * (double)r->d.x + my * (double)r->d.y + mz * (double)r->d.z;
    const double4 dnum = mx * (q0x - (double)r->o.x) + my * (q0y - (double)r->o.y) + mz * (q0z - (double)r->o.z);
    *ok = convert_int4(dden != 0.0);
    return convert_float4(dnum / dden);
}
#endif

/* The planes of a Tri8's eight triangles: triangle_plane (intersect.h) on eight lanes, the same
 * arithmetic (n, the magnitudes of its products, the sliver flag). */
RT_INLINE int8 tri8_plane(__global const float8 *pk, float8 *nx, float8 *ny, float8 *nz, float8 *nabs_x,
                          float8 *nabs_y, float8 *nabs_z)
{
    const float8 p0x = pk[0], p0y = pk[1], p0z = pk[2];
    const float8 e1x = pk[3] - p0x, e1y = pk[4] - p0y, e1z = pk[5] - p0z;
    const float8 e2x = pk[6] - p0x, e2y = pk[7] - p0y, e2z = pk[8] - p0z;
    *nx = e1y * e2z - e1z * e2y;
    *ny = e1z * e2x - e1x * e2z;
    *nz = e1x * e2y - e1y * e2x;
    *nabs_x = abs8(e1y * e2z) + abs8(e1z * e2y);
    *nabs_y = abs8(e1z * e2x) + abs8(e1x * e2z);
    *nabs_z = abs8(e1x * e2y) + abs8(e1y * e2x);
    return abs8(*nx) + abs8(*ny) + abs8(*nz) < SLIVER_CANCELLATION * (*nabs_x + *nabs_y + *nabs_z);
}

/* Watertight test of eight triangles (one Tri8 packet): intersect_tri4 (bvh_wide.h) with eight
 * lanes, the same arithmetic in the same order, so that each lane gives intersect_triangle's
 * result bit for bit (tests/accel/test_bvh_wide.py compares every layout with the binary one).
 * See intersect_tri4 for why each step is as it is (no FMA, double precision for zero edge
 * functions and for slivers or a numerator in doubt, NaN padding lanes rejected by det != 0). */
RT_INLINE int8 intersect_tri8(__global const float8 *pk, const WideRay *r, float tmin, float tmax,
                              float8 *t_out, float8 *U_out, float8 *V_out, float8 *W_out)
{
    const float8 Ax = pk[r->kx] - r->okx, Ay = pk[r->ky] - r->oky, Az = pk[r->kz] - r->okz;
    const float8 Bx = pk[3 + r->kx] - r->okx, By = pk[3 + r->ky] - r->oky, Bz = pk[3 + r->kz] - r->okz;
    const float8 Cx = pk[6 + r->kx] - r->okx, Cy = pk[6 + r->ky] - r->oky, Cz = pk[6 + r->kz] - r->okz;
    const float8 ax = Ax - r->sx * Az, ay = Ay - r->sy * Az;
    const float8 bx = Bx - r->sx * Bz, by = By - r->sy * Bz;
    const float8 cx = Cx - r->sx * Cz, cy = Cy - r->sy * Cz;
    float8 U = cx * by - cy * bx;
    float8 V = ax * cy - ay * cx;
    float8 W = bx * ay - by * ax;
#ifdef cl_khr_fp64
    const int8 zero = (U == 0.0f) | (V == 0.0f) | (W == 0.0f);
    if (any8(zero)) {
        U = SEL(U, (float8)(edge_double4(cx.lo, by.lo, cy.lo, bx.lo), edge_double4(cx.hi, by.hi, cy.hi, bx.hi)), zero);
        V = SEL(V, (float8)(edge_double4(ax.lo, cy.lo, ay.lo, cx.lo), edge_double4(ax.hi, cy.hi, ay.hi, cx.hi)), zero);
        W = SEL(W, (float8)(edge_double4(bx.lo, ay.lo, by.lo, ax.lo), edge_double4(bx.hi, ay.hi, by.hi, ax.hi)), zero);
    }
#endif
    const int8 mixed = ((U < 0.0f) | (V < 0.0f) | (W < 0.0f)) & ((U > 0.0f) | (V > 0.0f) | (W > 0.0f));
    const float8 det = U + V + W;
    const int8 inside = ~mixed & ((det < 0.0f) | (det > 0.0f)); /* det != 0, and false for NaN */
    if (!any8(inside))
        return inside;
    const float8 p0x = pk[0], p0y = pk[1], p0z = pk[2];
    float8 nx, ny, nz, nabs_x, nabs_y, nabs_z;
    const int8 sliver = tri8_plane(pk, &nx, &ny, &nz, &nabs_x, &nabs_y, &nabs_z);
    const float8 den = nx * r->d.x + ny * r->d.y + nz * r->d.z;
    const float8 ax0 = p0x - r->o.x, ay0 = p0y - r->o.y, az0 = p0z - r->o.z;
    const float8 num = nx * ax0 + ny * ay0 + nz * az0;
    const int8 doubt = abs8(num) <= NUM_DOUBT * (nabs_x * abs8(ax0) + nabs_y * abs8(ay0) + nabs_z * abs8(az0));
    float8 tt = num / den;
    int8 ok = den != 0.0f;
#ifdef cl_khr_fp64
    const int8 refine = inside & (sliver | doubt);
    if (any8(refine)) {
        const float8 p1x = pk[3], p1y = pk[4], p1z = pk[5], p2x = pk[6], p2y = pk[7], p2z = pk[8];
        int4 ok_lo, ok_hi;
        const float4 t_lo = plane_t_double4(p0x.lo, p0y.lo, p0z.lo, p1x.lo, p1y.lo, p1z.lo, p2x.lo, p2y.lo, p2z.lo, r, &ok_lo);
        const float4 t_hi = plane_t_double4(p0x.hi, p0y.hi, p0z.hi, p1x.hi, p1y.hi, p1z.hi, p2x.hi, p2y.hi, p2z.hi, r, &ok_hi);
        tt = SEL(tt, (float8)(t_lo, t_hi), refine);
        ok = SEL(ok, (int8)(ok_lo, ok_hi), refine);
    }
#else
    ok &= ~doubt;
#endif
    *t_out = tt; *U_out = U; *V_out = V; *W_out = W;
    return inside & ok & (tt > tmin) & (tt < tmax);
}

/* Closest hit of a leaf's packets: the nearest lane of each packet, the lowest lane among equal t
 * (the scalar loop's order: a later triangle replaces a hit only when strictly nearer). */
RT_INLINE void intersect_leaf8(__global const float8 *pk, int count, const WideRay *r, float tmin, Hit *hit)
{
    for (int p = 0; p < count; ++p, pk += TRI8_UNITS) {
        float8 t, U, V, W;
        const int8 m = intersect_tri8(pk, r, tmin, hit->t, &t, &U, &V, &W);
        if (!any8(m))
            continue;
        const float8 tm = SEL((float8)(INFINITY), t, m);
        const float4 h4 = VMIN(tm.lo, tm.hi);
        const float2 h2 = VMIN(h4.lo, h4.hi);
        const float best = FAST_MIN(h2.x, h2.y);
        const int k = lowest_bit(mask_bits8(tm == (float8)(best)));
        const float u = lane8(U, k), v = lane8(V, k), w = lane8(W, k);
        const float rcp = 1.0f / (u + v + w);
        hit->t = best;
        hit->u = v * rcp;
        hit->v = w * rcp;
        hit->prim = ((__global const int *)(pk + 9))[k];
    }
}

RT_INLINE int occluded_leaf8(__global const float8 *pk, int count, const WideRay *r, float tmin, float tmax)
{
    for (int p = 0; p < count; ++p, pk += TRI8_UNITS) {
        float8 t, U, V, W;
        if (any8(intersect_tri8(pk, r, tmin, tmax, &t, &U, &V, &W)))
            return 1;
    }
    return 0;
}

/* One compare-exchange stage on (key, lane id) pairs, as sort_stage in bvh_wide.h. */
RT_INLINE void sort_stage8(float8 *k, int8 *l, float8 pk, int8 pl, int8 lower)
{
    const int8 swap = SEL(*k < pk, pk < *k, lower);
    *k = SEL(*k, pk, swap);
    *l = SEL(*l, pl, swap);
}

/* Sorts eight keys ascending with their lane ids: Batcher's bitonic network, six stages, each lane
 * exchanging with lane i ^ 1, i ^ 2 or i ^ 4; `lower` marks the lanes keeping the smaller key. */
RT_INLINE void sort8(float8 *k, int8 *l)
{
    sort_stage8(k, l, (*k).s10325476, (*l).s10325476, (int8)(-1, 0, 0, -1, -1, 0, 0, -1));
    sort_stage8(k, l, (*k).s23016745, (*l).s23016745, (int8)(-1, -1, 0, 0, 0, 0, -1, -1));
    sort_stage8(k, l, (*k).s10325476, (*l).s10325476, (int8)(-1, 0, -1, 0, 0, -1, 0, -1));
    sort_stage8(k, l, (*k).s45670123, (*l).s45670123, (int8)(-1, -1, -1, -1, 0, 0, 0, 0));
    sort_stage8(k, l, (*k).s23016745, (*l).s23016745, (int8)(-1, -1, 0, 0, -1, -1, 0, 0));
    sort_stage8(k, l, (*k).s10325476, (*l).s10325476, (int8)(-1, 0, -1, 0, -1, 0, -1, 0));
}

RT_INLINE void wide8_decode(__global const float8 *base, int code, int *off, int *cnt)
{
    if (code >= 0) { *off = code; *cnt = 0; return; }
    const int ref = -1 - code;
    __global const float8 *parent = base + (ref & ~7);
    *off = ((__global const int *)(parent + 6))[ref & 7];
    *cnt = ((__global const int *)(parent + 7))[ref & 7];
}

/* Closest hit in (tmin, tmax), ordered as bvh_wide_closest_hit: the hit children of a node nearest
 * entry first (two compared directly, more through the sorting network), the others pushed far to
 * near, and a popped entry skipped when it was entered beyond the closest hit found since. */
/* The traversal of the subtree at (off, cnt) (a node: cnt 0; a leaf: cnt packets), closer than
 * hit->t; the packet traversal (bvh_packet.h) calls it for the few rays that enter a subtree. */
RT_INLINE void wide8_closest_from(__global const float8 *base, const WideRay *rp, float tmin, Hit *hitp, int off,
                                  int cnt)
{
    const WideRay r = *rp;
    Hit hit = *hitp;
    int stack_code[WIDE8_STACK_SIZE];
    float stack_t[WIDE8_STACK_SIZE];
    int sp = 0;
    for (;;) {
        if (cnt == 0) {
            __global const float8 *node = base + off;
            float8 enter;
            const int8 m = intersect_children8(node, &r, tmin, hit.t, &enter);
            int bits = mask_bits8(m);
            if (bits) {
                __global const int *child = (__global const int *)(node + 6);
                __global const int *count = (__global const int *)(node + 7);
                const int k0 = lowest_bit(bits);
                bits &= bits - 1;
                if (bits == 0) { /* one child */
                    off = child[k0]; cnt = count[k0];
                    continue;
                }
                if ((bits & (bits - 1)) == 0) { /* two children: push the farther */
                    const int k1 = lowest_bit(bits);
                    const float t0 = lane8(enter, k0), t1 = lane8(enter, k1);
                    const int near = t1 < t0 ? k1 : k0, far = t1 < t0 ? k0 : k1;
                    stack_code[sp] = WIDE_CODE(off, far); stack_t[sp] = FAST_MAX(t0, t1); ++sp;
                    off = child[near]; cnt = count[near];
                    continue;
                }
                float8 key = SEL((float8)(INFINITY), enter, m); /* misses sort last */
                int8 lane = (int8)(0, 1, 2, 3, 4, 5, 6, 7);
                sort8(&key, &lane);
                const float *ks = (const float *)&key;
                const int *ls = (const int *)&lane;
                for (int j = bit_count(bits); j >= 1; --j) { /* bits holds n - 1 children: push far to near */
                    stack_code[sp] = WIDE_CODE(off, ls[j]); stack_t[sp] = ks[j]; ++sp;
                }
                off = child[ls[0]]; cnt = count[ls[0]];
                continue;
            }
        } else {
            intersect_leaf8(base + off, cnt, &r, tmin, &hit);
        }
        for (;;) {
            if (sp == 0) { *hitp = hit; return; }
            --sp;
            if (stack_t[sp] <= hit.t) { wide8_decode(base, stack_code[sp], &off, &cnt); break; }
        }
    }
}

RT_INLINE Hit bvh_wide8_closest_hit(__global const void *bvh, __global const float4 *tris,
                                    float3 o, float3 d, float tmin, float tmax)
{
    Hit hit; hit.t = tmax; hit.u = 0.0f; hit.v = 0.0f; hit.prim = PRIM_MISS;
    const WideRay r = wide_ray(o, d);
    wide8_closest_from((__global const float8 *)bvh, &r, tmin, &hit, 0, 0); /* from the root */
    return hit;
}

/* Any hit in (tmin, tmax): returns 1 as soon as one triangle is hit (children in slot order). */
RT_INLINE int wide8_any_from(__global const float8 *base, const WideRay *rp, float tmin, float tmax, int off, int cnt)
{
    const WideRay r = *rp;
    int stack_code[WIDE8_STACK_SIZE];
    int sp = 0;
    for (;;) {
        if (cnt == 0) {
            __global const float8 *node = base + off;
            float8 enter;
            int bits = mask_bits8(intersect_children8(node, &r, tmin, tmax, &enter));
            if (bits) {
                __global const int *child = (__global const int *)(node + 6);
                __global const int *count = (__global const int *)(node + 7);
                const int k = lowest_bit(bits);
                for (bits &= bits - 1; bits; bits &= bits - 1)
                    stack_code[sp++] = WIDE_CODE(off, lowest_bit(bits));
                off = child[k]; cnt = count[k];
                continue;
            }
        } else if (occluded_leaf8(base + off, cnt, &r, tmin, tmax)) {
            return 1;
        }
        if (sp == 0) return 0;
        --sp;
        wide8_decode(base, stack_code[sp], &off, &cnt);
    }
}

RT_INLINE int bvh_wide8_any_hit(__global const void *bvh, __global const float4 *tris,
                                float3 o, float3 d, float tmin, float tmax)
{
    const WideRay r = wide_ray(o, d);
    return wide8_any_from((__global const float8 *)bvh, &r, tmin, tmax, 0, 0); /* from the root */
}

#endif
