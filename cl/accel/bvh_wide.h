/* Traversal of the 4-wide BVH (pyopencl_rt/accel/bvh_wide.py) for CPU devices: closest hit and any hit.
 * The traversal itself is written once over the node width (bvh_wide.tpl.h): this file makes its
 * 4-wide instance (bvh_wide_closest_hit4, ...) and holds what both widths share (the ray
 * constants, stack codes, double-precision fallbacks); bvh_wide8.h makes the 8-wide one.
 *
 * cl/accel/traverse.h makes bvh_closest_hit / bvh_any_hit the wide versions when BVH_WIDE is
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

/* SEL, VMIN, VMAX, abs4, any4, mask_bits4, lane4 (and their 8-lane forms), lowest_bit, bit_count:
 * accel/masks.h */

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

/* Stack code of child slot k of the node at offset off (see the top of this file): a node offset
 * is a multiple of 8 units and a slot is below 8 at both widths, so a leaf's code decodes. */
#define WIDE_CODE(off, k) (count[k] == 0 ? child[k] : -1 - ((off) + (k)))

#ifdef cl_khr_fp64
/* The double-precision fallbacks of the watertight test on four lanes (bvh_wide.tpl.h): an edge
 * function a b - c d, and t of the plane equation with *ok = (den != 0). */
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

/* WN_(name): name4 or name8, the names of the traversal's instance of width WN */
#define WIDE_PASTE_(a, b) a##b
#define WIDE_PASTE(a, b) WIDE_PASTE_(a, b)
#define WN_(name) WIDE_PASTE(name, WN)

#define WN 4
#include "accel/bvh_wide.tpl.h"
#undef WN

#endif
