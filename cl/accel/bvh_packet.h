/* Packet traversal of the 8-wide BVH (bvh_wide8.h's buffer) for CPU devices: PACKET_WIDTH rays
 * (16 on AVX-512, 8 on AVX2) in the lanes of one work-item's vectors, closest hit and any hit.
 *
 * Why: PoCL runs a work-item as scalar code, and the single-ray traversal (bvh_wide8.h) gets its
 * SIMD from eight child boxes or eight triangles per instruction.  Where the rays of a packet
 * visit the same nodes (camera rays; every ray of a small scene such as the Cornell box), testing
 * one box or one triangle against all of them at once does the same work with a fraction of the
 * instructions and without the per-ray stacks and branches (Embree's rtcIntersect16, which
 * Mitsuba's LLVM variants call, works this way).  Where they part ways, a subtree that at most
 * PACKET_HYBRID lanes enter is traversed ray by ray with bvh_wide8.h's functions, so large scenes
 * lose little (docs/BENCHMARKS.md: a 1.3M-triangle scene still renders faster with lanes).  A
 * leaf (one Tri8) whose lanes and triangles fill at most PACKET_PAIR_PASSES vectors as pairs is
 * tested that way instead: each lane a pair of one ray and one triangle (packet_pairs; closest
 * hits only).
 *
 * Results, lane by lane, are those of bvh_wide_closest_hit8 / bvh_wide_any_hit8 bit for bit: the
 * triangle test is intersect_tri8's arithmetic (FP_CONTRACT off), with each lane's own axis
 * permutation and shear applied by selects instead of load offsets, and the same
 * double-precision fallbacks (per lane, in scalar code: they are rare).  Only the order in which
 * a ray meets the leaves differs, so where two triangles give a ray exactly the same t the one
 * reported can differ (as between the binary and wide layouts; tests/accel/test_bvh_packet.py).
 *
 * Traversal: a node's child boxes are tested one after another, each against the lanes that
 * entered the node; the children some lane enters are visited nearest first (by the smallest
 * entry distance over those lanes; any order for any-hit queries) and the others pushed with
 * that distance and their lanes, and a popped entry is skipped when every lane that entered it
 * has a closer hit by now.  A lane whose tmax is below its tmin is inactive (no box test passes
 * for it): an idle path's slot in the packet.
 */
#ifndef PYOPENCL_RT_BVH_PACKET_H
#define PYOPENCL_RT_BVH_PACKET_H

#include "accel/bvh_wide8.h"

#include "render/lanes.h"

#if PACKET_WIDTH > 1 /* packets are lanes: nothing here at one path per work-item */

/* the smallest lane (operands never NaN: entry distances) */
#if PACKET_WIDTH == 16
RT_INLINE float pmin_all(pfloat v) { const float8 a = VMIN(v.lo, v.hi); const float4 b = VMIN(a.lo, a.hi); const float2 c = VMIN(b.lo, b.hi); return FAST_MIN(c.x, c.y); }
#else
RT_INLINE float pmin_all(pfloat v) { const float4 b = VMIN(v.lo, v.hi); const float2 c = VMIN(b.lo, b.hi); return FAST_MIN(c.x, c.y); }
#endif

/* A packet of rays: wide_ray's constants per lane, the permutation as two masks per axis
 * (k == 0, k == 1; else 2) so that a vertex coordinate is picked per lane with two selects. */
typedef struct {
    pfloat ox, oy, oz, dx, dy, dz, ix, iy, iz;
    pint kx0, kx1, ky0, ky1, kz0, kz1;
    pfloat okx, oky, okz, sx, sy;
} PacketRay;

/* Lane k of the packet from one ray, through wide_ray itself: the reference that packet_rays
 * (below, all lanes at once) is checked against (tests/accel/test_bvh_packet.py). */
RT_INLINE void packet_set_ray(PacketRay *p, int k, float3 o, float3 d)
{
    const WideRay r = wide_ray(o, d);
    PLANE(p->ox, k) = o.x; PLANE(p->oy, k) = o.y; PLANE(p->oz, k) = o.z;
    PLANE(p->dx, k) = d.x; PLANE(p->dy, k) = d.y; PLANE(p->dz, k) = d.z;
    PLANE(p->ix, k) = r.inv_d.x; PLANE(p->iy, k) = r.inv_d.y; PLANE(p->iz, k) = r.inv_d.z;
    PLANE_I(p->kx0, k) = -(r.kx == 0); PLANE_I(p->kx1, k) = -(r.kx == 1);
    PLANE_I(p->ky0, k) = -(r.ky == 0); PLANE_I(p->ky1, k) = -(r.ky == 1);
    PLANE_I(p->kz0, k) = -(r.kz == 0); PLANE_I(p->kz1, k) = -(r.kz == 1);
    PLANE(p->okx, k) = r.okx; PLANE(p->oky, k) = r.oky; PLANE(p->okz, k) = r.okz;
    PLANE(p->sx, k) = r.sx; PLANE(p->sy, k) = r.sy;
}

/* The packet of rays (o, d) per lane: packet_set_ray for every lane at once, with wide_ray's
 * arithmetic (safe reciprocals, the permutation and shear of ray_shear) done on the lanes. */
RT_INLINE PacketRay packet_rays(pvec3 o, pvec3 d)
{
    PacketRay r;
    r.ox = o.x; r.oy = o.y; r.oz = o.z;
    r.dx = d.x; r.dy = d.y; r.dz = d.z;
    r.ix = psafe_rcp(d.x); r.iy = psafe_rcp(d.y); r.iz = psafe_rcp(d.z);
    const pfloat ax = pabs(d.x), ay = pabs(d.y), az = pabs(d.z);
    /* kz: the dominant axis, as ray_shear picks it (ties and NaN to z) */
    const pint kz0 = (ax > ay) & (ax > az), kz1 = ~(ax > ay) & (ay > az), kz2 = ~kz0 & ~kz1;
    const pfloat dz = kz0 ? d.x : (kz1 ? d.y : d.z);
    /* kx = kz + 1, ky = kz + 2 (mod 3), swapped where dz < 0 to keep the winding */
    const pint swap = dz < 0.0f;
    r.kz0 = kz0; r.kz1 = kz1;
    r.kx0 = swap ? kz1 : kz2; r.kx1 = swap ? kz2 : kz0;
    r.ky0 = swap ? kz2 : kz1; r.ky1 = swap ? kz0 : kz2;
    r.okx = r.kx0 ? o.x : (r.kx1 ? o.y : o.z);
    r.oky = r.ky0 ? o.x : (r.ky1 ? o.y : o.z);
    r.okz = kz0 ? o.x : (kz1 ? o.y : o.z);
    r.sx = (r.kx0 ? d.x : (r.kx1 ? d.y : d.z)) / dz;
    r.sy = (r.ky0 ? d.x : (r.ky1 ? d.y : d.z)) / dz;
    return r;
}

/* Coordinate k of (x, y, z) per lane, k given by the masks (k == 0, k == 1). */
#define PICK(x, y, z, k0, k1) SEL(SEL(PFLOAT(z), PFLOAT(y), (k1)), PFLOAT(x), (k0))

/* One child box against every lane: intersect_children8's arithmetic for one slot, with the
 * near/far plane taken by min/max (the same values: inv_d is never 0 or NaN, and the box is
 * present).  Returns the lanes that enter it; *enter their entry distances. */
RT_INLINE pint packet_box(const PacketRay *r, float bx0, float by0, float bz0, float bx1, float by1, float bz1,
                          pfloat tmin, pfloat tmax, pfloat *enter)
{
    const pfloat t0x = (PFLOAT(bx0) - r->ox) * r->ix, t1x = (PFLOAT(bx1) - r->ox) * r->ix;
    const pfloat t0y = (PFLOAT(by0) - r->oy) * r->iy, t1y = (PFLOAT(by1) - r->oy) * r->iy;
    const pfloat t0z = (PFLOAT(bz0) - r->oz) * r->iz, t1z = (PFLOAT(bz1) - r->oz) * r->iz;
    const pfloat e = VMAX(VMAX(VMIN(t0x, t1x), VMIN(t0y, t1y)), VMAX(VMIN(t0z, t1z), tmin));
    const pfloat l = VMIN(VMIN(VMAX(t0x, t1x), VMAX(t0y, t1y)), VMAX(t0z, t1z)) * SLAB_FAR_SCALE;
    *enter = e;
    return (e <= VMIN(l, tmax)) & (e < PFLOAT(INFINITY));
}

#ifdef cl_khr_fp64
/* the lanes as doubles (an fpext of each lane: no call into the built-in library); this file is
 * compiled at 8 and 16 lanes only */
#if PACKET_WIDTH == 16
typedef double16 pdouble;
#else
typedef double8 pdouble;
#endif
#ifdef RT_CONVERTVECTOR
#define PDOUBLE(x) __builtin_convertvector((x), pdouble)
#define PINT_OF_PDOUBLE_MASK(m) __builtin_convertvector((m), pint)
#define PFLOAT_OF_PDOUBLE(x) __builtin_convertvector((x), pfloat)
#elif PACKET_WIDTH == 16
#define PDOUBLE(x) convert_double16(x)
#define PINT_OF_PDOUBLE_MASK(m) convert_int16(m)
#define PFLOAT_OF_PDOUBLE(x) convert_float16(x)
#else
#define PDOUBLE(x) convert_double8(x)
#define PINT_OF_PDOUBLE_MASK(m) convert_int8(m)
#define PFLOAT_OF_PDOUBLE(x) convert_float8(x)
#endif

RT_INLINE float edge_double(float a, float b, float c, float d)
{
    return (float)((double)a * (double)b - (double)c * (double)d);
}
#endif

/* Each lane's ray against its own triangle (p0, p1, p2 per lane) whose plane (triangle_plane:
 * n, its magnitudes nabs, the sliver flag) is given: intersect_tri8's arithmetic per lane.
 * Returns the lanes hit in (tmin, tmax); *t_out, *U_out, *V_out, *W_out hold their values.
 * packet_triangle (one triangle against every lane) and packet_pairs (pairs of rays and
 * triangles) both test through here. */
RT_INLINE pint packet_triangle_lanes(const PacketRay *r, pvec3 p0, pvec3 p1, pvec3 p2, pvec3 n, pvec3 nabs,
                                     pint sliver, pfloat tmin, pfloat tmax,
                                     pfloat *t_out, pfloat *U_out, pfloat *V_out, pfloat *W_out)
{
    /* The plane equation first (intersect_tri8's t, the same arithmetic): a lane can only hit
     * where its plane crossing lies in (tmin, tmax), or where the double-precision refinement may
     * move it (a sliver, a numerator in doubt).  When no lane can, the edge test is skipped:
     * walls behind the rays or beyond the hits found so far, and for shadow rays almost every
     * triangle. */
    const pfloat den = n.x * r->dx + n.y * r->dy + n.z * r->dz;
    const pfloat ax0 = p0.x - r->ox, ay0 = p0.y - r->oy, az0 = p0.z - r->oz;
    const pfloat num = n.x * ax0 + n.y * ay0 + n.z * az0;
    const pint doubt = pabs(num) <= NUM_DOUBT * (nabs.x * pabs(ax0) + nabs.y * pabs(ay0) + nabs.z * pabs(az0));
    pfloat tt = num / den;
    pint ok = den != 0.0f;
#ifdef cl_khr_fp64
    const pint may_move = sliver | doubt;
    const pint maybe = (tmin <= tmax) & ((ok & (tt > tmin) & (tt < tmax)) | may_move);
#else
    ok &= ~doubt;
    const pint maybe = (tmin <= tmax) & ok & (tt > tmin) & (tt < tmax);
#endif
    if (!pany(maybe))
        return maybe;
    /* the edge functions in the ray's sheared space (Woop et al.), each lane's own permutation */
    const pfloat Ax = PICK(p0.x, p0.y, p0.z, r->kx0, r->kx1) - r->okx;
    const pfloat Ay = PICK(p0.x, p0.y, p0.z, r->ky0, r->ky1) - r->oky;
    const pfloat Az = PICK(p0.x, p0.y, p0.z, r->kz0, r->kz1) - r->okz;
    const pfloat Bx = PICK(p1.x, p1.y, p1.z, r->kx0, r->kx1) - r->okx;
    const pfloat By = PICK(p1.x, p1.y, p1.z, r->ky0, r->ky1) - r->oky;
    const pfloat Bz = PICK(p1.x, p1.y, p1.z, r->kz0, r->kz1) - r->okz;
    const pfloat Cx = PICK(p2.x, p2.y, p2.z, r->kx0, r->kx1) - r->okx;
    const pfloat Cy = PICK(p2.x, p2.y, p2.z, r->ky0, r->ky1) - r->oky;
    const pfloat Cz = PICK(p2.x, p2.y, p2.z, r->kz0, r->kz1) - r->okz;
    SHEARED_EDGES(pfloat, Ax, Ay, Az, Bx, By, Bz, Cx, Cy, Cz, r->sx, r->sy);
#ifdef cl_khr_fp64
    const pint zero = maybe & ((U == 0.0f) | (V == 0.0f) | (W == 0.0f));
    if (pany(zero)) {
        for (int bits = pbits(zero); bits; bits &= bits - 1) {
            const int k = lowest_bit(bits);
            const float lax = PLANE(ax, k), lay = PLANE(ay, k), lbx = PLANE(bx, k);
            const float lby = PLANE(by, k), lcx = PLANE(cx, k), lcy = PLANE(cy, k);
            PLANE(U, k) = edge_double(lcx, lby, lcy, lbx);
            PLANE(V, k) = edge_double(lax, lcy, lay, lcx);
            PLANE(W, k) = edge_double(lbx, lay, lby, lax);
        }
    }
#endif
    const pint mixed = ((U < 0.0f) | (V < 0.0f) | (W < 0.0f)) & ((U > 0.0f) | (V > 0.0f) | (W > 0.0f));
    const pfloat det = U + V + W;
    const pint inside = maybe & ~mixed & ((det < 0.0f) | (det > 0.0f));
#ifdef cl_khr_fp64
    const pint refine = inside & may_move;
    if (pany(refine)) {
        /* over the lanes in double vectors: every lane's origin next to the plane (a ray spawned
         * from a triangle, against that triangle and its coplanar neighbours) is in doubt, so
         * most packets refine several lanes; intersect_triangle's operations in its order */
        const pdouble q0x = PDOUBLE(p0.x), q0y = PDOUBLE(p0.y), q0z = PDOUBLE(p0.z);
        const pdouble f1x = PDOUBLE(p1.x) - q0x, f1y = PDOUBLE(p1.y) - q0y, f1z = PDOUBLE(p1.z) - q0z;
        const pdouble f2x = PDOUBLE(p2.x) - q0x, f2y = PDOUBLE(p2.y) - q0y, f2z = PDOUBLE(p2.z) - q0z;
        const pdouble mx = f1y * f2z - f1z * f2y, my = f1z * f2x - f1x * f2z, mz = f1x * f2y - f1y * f2x;
        const pdouble dden = mx * PDOUBLE(r->dx) + my * PDOUBLE(r->dy) + mz * PDOUBLE(r->dz);
        const pdouble dnum = mx * (q0x - PDOUBLE(r->ox)) + my * (q0y - PDOUBLE(r->oy)) + mz * (q0z - PDOUBLE(r->oz));
        ok = refine ? PINT_OF_PDOUBLE_MASK(dden != 0.0) : ok;
        tt = refine ? PFLOAT_OF_PDOUBLE(dnum / dden) : tt;
    }
#endif
    *t_out = tt; *U_out = U; *V_out = V; *W_out = W;
    return inside & ok & (tt > tmin) & (tt < tmax);
}

/* Triangle j of a Tri8 (pk) against every lane: its plane from `plane` (tri_plane8's results for
 * the Tri8, once for its triangles), the rest per lane (packet_triangle_lanes). */
typedef struct { float8 nx, ny, nz, nabs_x, nabs_y, nabs_z; int8 sliver; } Tri8Plane;

RT_INLINE Tri8Plane tri8_planes(__global const float8 *pk)
{
    Tri8Plane p;
    p.sliver = tri_plane8(pk, &p.nx, &p.ny, &p.nz, &p.nabs_x, &p.nabs_y, &p.nabs_z);
    return p;
}

RT_INLINE pint packet_triangle(const PacketRay *r, __global const float8 *pk, const Tri8Plane *plane, int j,
                               pfloat tmin, pfloat tmax, pfloat *t_out, pfloat *U_out, pfloat *V_out, pfloat *W_out)
{
    __global const float *vf = (__global const float *)pk;
    const pvec3 p0 = pv3(PFLOAT(vf[j]), PFLOAT(vf[8 + j]), PFLOAT(vf[16 + j]));
    const pvec3 p1 = pv3(PFLOAT(vf[24 + j]), PFLOAT(vf[32 + j]), PFLOAT(vf[40 + j]));
    const pvec3 p2 = pv3(PFLOAT(vf[48 + j]), PFLOAT(vf[56 + j]), PFLOAT(vf[64 + j]));
    const pvec3 n = pv3(PFLOAT(lane8(plane->nx, j)), PFLOAT(lane8(plane->ny, j)), PFLOAT(lane8(plane->nz, j)));
    const pvec3 nabs = pv3(PFLOAT(lane8(plane->nabs_x, j)), PFLOAT(lane8(plane->nabs_y, j)),
                           PFLOAT(lane8(plane->nabs_z, j)));
    return packet_triangle_lanes(r, p0, p1, p2, n, nabs, PINT(((const int *)&plane->sliver)[j]), tmin, tmax,
                                 t_out, U_out, V_out, W_out);
}

/* Lane tri[k] of v in lane k (tri < 8): a Tri8's value for each lane's triangle. */
#if PACKET_WIDTH == 16
#define TRI8_WIDE(v) ((v), (v)) /* the eight lanes twice: a 16-lane index picks lane tri & 7 */
#else
#define TRI8_WIDE(v) (v)
#endif
RT_INLINE pfloat spread8(float8 v, pint tri) { return ppermute((pfloat)TRI8_WIDE(v), tri); }
RT_INLINE pint spread8_int(int8 v, pint tri) { return ppermute_int((pint)TRI8_WIDE(v), tri); }

/* Pairs of rays and triangles, one pair per lane: lane k tests the packet's ray ray[k] against
 * the Tri8's triangle tri[k].  For a leaf that few lanes enter, this fills the vector where the
 * packet test (one triangle against every lane) would run mostly empty and the ray-by-ray test
 * (one ray against the Tri8's eight slots) half empty and once per lane: three rays and five
 * triangles are 15 lanes of one test. */
RT_INLINE pint packet_pairs(const PacketRay *r, __global const float8 *pk, const Tri8Plane *plane, pint ray,
                            pint tri, pfloat tmin, pfloat tmax, pfloat *t_out, pfloat *U_out, pfloat *V_out,
                            pfloat *W_out)
{
    PacketRay q; /* the fields the triangle test reads, of each lane's ray */
    q.ox = ppermute(r->ox, ray); q.oy = ppermute(r->oy, ray); q.oz = ppermute(r->oz, ray);
    q.dx = ppermute(r->dx, ray); q.dy = ppermute(r->dy, ray); q.dz = ppermute(r->dz, ray);
    q.kx0 = ppermute_int(r->kx0, ray); q.kx1 = ppermute_int(r->kx1, ray);
    q.ky0 = ppermute_int(r->ky0, ray); q.ky1 = ppermute_int(r->ky1, ray);
    q.kz0 = ppermute_int(r->kz0, ray); q.kz1 = ppermute_int(r->kz1, ray);
    q.okx = ppermute(r->okx, ray); q.oky = ppermute(r->oky, ray); q.okz = ppermute(r->okz, ray);
    q.sx = ppermute(r->sx, ray); q.sy = ppermute(r->sy, ray);
    const pvec3 p0 = pv3(spread8(pk[0], tri), spread8(pk[1], tri), spread8(pk[2], tri));
    const pvec3 p1 = pv3(spread8(pk[3], tri), spread8(pk[4], tri), spread8(pk[5], tri));
    const pvec3 p2 = pv3(spread8(pk[6], tri), spread8(pk[7], tri), spread8(pk[8], tri));
    /* the planes of tri_plane8 (once for the leaf), each lane its triangle's */
    const pvec3 n = pv3(spread8(plane->nx, tri), spread8(plane->ny, tri), spread8(plane->nz, tri));
    const pvec3 nabs = pv3(spread8(plane->nabs_x, tri), spread8(plane->nabs_y, tri), spread8(plane->nabs_z, tri));
    const pint sliver = spread8_int(plane->sliver, tri);
    return packet_triangle_lanes(&q, p0, p1, p2, n, nabs, sliver, tmin, tmax, t_out, U_out, V_out, W_out);
}

/* A one-Tri8 leaf is tested as pairs when they fill at most PACKET_PAIR_PASSES tests; not where a
 * permutation of the lanes is not one instruction (16 lanes on AVX2): then the lanes' loops cost
 * more than the pairs save.  A subtree that at most PACKET_HYBRID lanes enter is traversed ray by
 * ray (fewer with pairs, which serve the leaves of few lanes better). */
#ifndef PACKET_PAIR_PASSES
#define PACKET_PAIR_PASSES (PERMUTE_IN_REGISTER ? 3 : 0)
#endif
#ifndef PACKET_HYBRID
#define PACKET_HYBRID (PACKET_PAIR_PASSES ? 2 : 4)
#endif

/* The pairs of a leaf (one Tri8): every lane of `lanes` with every triangle of the packet.
 * Returns their number where pairs are the test to use (they fit PACKET_PAIR_PASSES tests, fewer
 * than the packet test's one per triangle, or the lanes are few enough for ray by ray), else 0. */
RT_INLINE int leaf_pairs(__global const float8 *pk, int cnt, int lanes, int *tri_bits)
{
    if (cnt != 1) return 0;
    *tri_bits = ~mask_bits8(as_int8(pk[9])) & 0xff; /* the slots holding a triangle */
    const int k = bit_count(lanes), n = bit_count(*tri_bits), pairs = k * n;
    const int passes = (pairs + PACKET_WIDTH - 1) / PACKET_WIDTH;
    return passes <= PACKET_PAIR_PASSES && (passes < n || k <= PACKET_HYBRID) ? pairs : 0;
}

/* Chunk c of the pairs (ray-major: pair p is ray p / n with triangle p % n, of ray_ids and
 * tri_ids): each lane's ray and triangle, and the lanes holding a pair. */
RT_INLINE pint pair_chunk(int c, int n, int n_pairs, pint ray_ids, pint tri_ids, pint *ray, pint *tri)
{
    const pint p = LANE_IDS + c * PACKET_WIDTH;
    const pint i = (p * (65536 / n + 1)) >> 16; /* p / n, exact for p < 256 and n <= 8 */
    *ray = ppermute_int(ray_ids, i);
    *tri = ppermute_int(tri_ids, p - i * n);
    return p < n_pairs;
}

/* Lane k's ray as bvh_wide8.h's WideRay (wide_ray's constants, the same bits). */
RT_INLINE WideRay packet_lane_ray(const PacketRay *r, int k)
{
    WideRay w;
    w.o = (float3)(PLANE(r->ox, k), PLANE(r->oy, k), PLANE(r->oz, k));
    w.d = (float3)(PLANE(r->dx, k), PLANE(r->dy, k), PLANE(r->dz, k));
    w.inv_d = (float3)(PLANE(r->ix, k), PLANE(r->iy, k), PLANE(r->iz, k));
    w.inv_far = w.inv_d * SLAB_FAR_SCALE;
    w.nx = w.inv_d.x >= 0.0f ? 0 : 3;
    w.ny = w.inv_d.y >= 0.0f ? 1 : 4;
    w.nz = w.inv_d.z >= 0.0f ? 2 : 5;
    w.kx = PLANE_I(r->kx0, k) ? 0 : (PLANE_I(r->kx1, k) ? 1 : 2);
    w.ky = PLANE_I(r->ky0, k) ? 0 : (PLANE_I(r->ky1, k) ? 1 : 2);
    w.kz = PLANE_I(r->kz0, k) ? 0 : (PLANE_I(r->kz1, k) ? 1 : 2);
    w.okx = PLANE(r->okx, k); w.oky = PLANE(r->oky, k); w.okz = PLANE(r->okz, k);
    w.sx = PLANE(r->sx, k); w.sy = PLANE(r->sy, k);
    return w;
}

/* The children of node `off` that some lane of `lanes` enters: their slots (`sorted`: nearest
 * first, by the smallest entry over the lanes, in near[]; else in slot order), their lanes, and
 * how many there are. */
RT_INLINE int packet_node(__global const float8 *base, int off, const PacketRay *r, pfloat tmin, pfloat tmax,
                          int lanes, int *slots, float *near, int *masks, const int sorted)
{
    __global const float *box = (__global const float *)(base + off);
    __global const int *count = (__global const int *)(base + off + 7);
    int n = 0;
    for (int c = 0; c < 8; ++c) {
        if (count[c] < 0) continue;
        pfloat enter;
        const pint m = packet_box(r, box[c], box[8 + c], box[16 + c], box[24 + c], box[32 + c], box[40 + c],
                                  tmin, tmax, &enter) & pmask(lanes);
        if (!pany(m)) continue;
        if (!sorted) { slots[n] = c; masks[n] = pbits(m); ++n; continue; }
        const float e = pmin_all(SEL(PFLOAT(INFINITY), enter, m));
        int j = n++;
        for (; j > 0 && near[j - 1] > e; --j) { near[j] = near[j - 1]; slots[j] = slots[j - 1]; masks[j] = masks[j - 1]; }
        near[j] = e; slots[j] = c; masks[j] = pbits(m);
    }
    return n;
}

/* The closest hits of the packet in (tmin, tmax) (per lane; tmax < tmin: inactive lane).  *t
 * holds tmax on entry and the hit distance on return; prim (PRIM_MISS on entry), u, v as Hit.
 * Each stack entry keeps the lanes that entered its box; a subtree that at most PACKET_HYBRID of
 * them enter is traversed ray by ray (bvh_wide8.h; a leaf with intersect_leaf8), as Embree's
 * hybrid traversal switches to single rays; a leaf entered by more is tested triangle by triangle
 * against all its lanes. */
RT_INLINE void packet_closest_hit(__global const void *bvh, const PacketRay *r, pfloat tmin, pfloat *t,
                                  pint *prim, pfloat *u, pfloat *v)
{
    __global const float8 *base = (__global const float8 *)bvh;
    int stack_code[WIDE8_STACK_SIZE], stack_lanes[WIDE8_STACK_SIZE];
    float stack_t[WIDE8_STACK_SIZE];
    int sp = 0;
    int off = 0, cnt = 0, lanes = pbits(tmin <= *t);
    for (;;) {
        int tri_bits, n_pairs;
        if ((n_pairs = leaf_pairs(base + off, cnt, lanes, &tri_bits))) { /* a leaf: its pairs */
            __global const float8 *pk = base + off;
            __global const int *tri_id = (__global const int *)(pk + 9);
            const pint ray_ids = pcompress_ids(lanes), tri_ids = pcompress_ids(tri_bits);
            const Tri8Plane plane = tri8_planes(pk);
            const int n_tris = bit_count(tri_bits);
            for (int c = 0; c * PACKET_WIDTH < n_pairs; ++c) {
                pint ray, tri;
                const pint on = pair_chunk(c, n_tris, n_pairs, ray_ids, tri_ids, &ray, &tri);
                pfloat tt, U, V, W;
                const pint m = packet_pairs(r, pk, &plane, ray, tri, on ? ppermute(tmin, ray) : PFLOAT(INFINITY),
                                            ppermute(*t, ray), &tt, &U, &V, &W);
                /* in pair order (a ray's triangles in slot order): a strictly nearer hit replaces,
                 * so among equal t the lower slot stays, as in intersect_leaf8 */
                for (int bits = pbits(m); bits; bits &= bits - 1) {
                    const int q = lowest_bit(bits), k = PLANE_I(ray, q);
                    if (PLANE(tt, q) < PLANE(*t, k)) {
                        const float rcp = 1.0f / (PLANE(U, q) + PLANE(V, q) + PLANE(W, q));
                        PLANE(*t, k) = PLANE(tt, q);
                        PLANE(*u, k) = PLANE(V, q) * rcp;
                        PLANE(*v, k) = PLANE(W, q) * rcp;
                        PLANE_I(*prim, k) = tri_id[PLANE_I(tri, q)];
                    }
                }
            }
        } else if (bit_count(lanes) <= PACKET_HYBRID) { /* few rays in this subtree: one at a time */
            for (int bits = lanes; bits; bits &= bits - 1) {
                const int k = lowest_bit(bits);
                const WideRay w = packet_lane_ray(r, k);
                Hit h;
                h.t = PLANE(*t, k); h.prim = PLANE_I(*prim, k); h.u = PLANE(*u, k); h.v = PLANE(*v, k);
                if (cnt > 0) intersect_leaf8(base + off, cnt, &w, PLANE(tmin, k), &h); /* a leaf: no traversal */
                else wide_closest_from8(base, &w, PLANE(tmin, k), &h, off, cnt);
                PLANE(*t, k) = h.t; PLANE_I(*prim, k) = h.prim; PLANE(*u, k) = h.u; PLANE(*v, k) = h.v;
            }
        } else if (cnt == 0) {
            int slots[8], masks[8];
            float near[8];
            const int n = packet_node(base, off, r, tmin, *t, lanes, slots, near, masks, 1);
            if (n > 0) {
                __global const int *child = (__global const int *)(base + off + 6);
                __global const int *count = (__global const int *)(base + off + 7);
                for (int j = n - 1; j >= 1; --j) {
                    stack_code[sp] = WIDE_CODE(off, slots[j]); stack_t[sp] = near[j]; stack_lanes[sp] = masks[j]; ++sp;
                }
                lanes = masks[0];
                off = child[slots[0]]; cnt = count[slots[0]];
                continue;
            }
        } else {
            __global const float8 *pk = base + off;
            const pfloat lane_tmin = pmask(lanes) ? tmin : PFLOAT(INFINITY); /* the lanes that entered */
            for (int q = 0; q < cnt; ++q, pk += TRI8_UNITS) {
                __global const int *tri = (__global const int *)(pk + 9);
                const Tri8Plane plane = tri8_planes(pk);
                for (int j = 0; j < 8; ++j) {
                    const int id = tri[j];
                    if (id < 0) continue;
                    pfloat tt, U, V, W;
                    const pint m = packet_triangle(r, pk, &plane, j, lane_tmin, *t, &tt, &U, &V, &W);
                    if (!pany(m)) continue;
                    const pfloat rcp = 1.0f / (U + V + W);
                    *t = SEL(*t, tt, m);
                    *u = SEL(*u, V * rcp, m);
                    *v = SEL(*v, W * rcp, m);
                    *prim = SEL(*prim, PINT(id), m);
                }
            }
        }
        for (;;) {
            if (sp == 0) return;
            --sp;
            /* skipped when every lane that entered it has a closer hit by now (one comparison
             * of the lanes against its smallest entry distance, not a reduction of them) */
            if (pbits(PFLOAT(stack_t[sp]) <= *t) & stack_lanes[sp]) {
                wide_decode8(base, stack_code[sp], &off, &cnt);
                lanes = stack_lanes[sp];
                break;
            }
        }
    }
}

/* Any hit per lane in (tmin, tmax): returns the lanes occluded (-1).  Lanes stop testing once
 * they are (their tmax drops below tmin), and the traversal ends when every lane has.  Subtrees
 * entered by at most PACKET_HYBRID lanes are traversed ray by ray, as in packet_closest_hit; leaves
 * are not tested as pairs here (no faster for shadow rays, docs/BENCHMARKS.md). */
RT_INLINE pint packet_any_hit(__global const void *bvh, const PacketRay *r, pfloat tmin, pfloat tmax)
{
    __global const float8 *base = (__global const float8 *)bvh;
    pint hit = PINT(0);
    int stack_code[WIDE8_STACK_SIZE], stack_lanes[WIDE8_STACK_SIZE];
    int sp = 0;
    int off = 0, cnt = 0, lanes = (1 << PACKET_WIDTH) - 1;
    for (;;) {
        lanes &= pbits(tmin <= tmax); /* active and not yet occluded */
        if (bit_count(lanes) <= PACKET_HYBRID) { /* few rays in this subtree: one at a time */
            for (int bits = lanes; bits; bits &= bits - 1) {
                const int k = lowest_bit(bits);
                const WideRay w = packet_lane_ray(r, k);
                if (cnt > 0 ? occluded_leaf8(base + off, cnt, &w, PLANE(tmin, k), PLANE(tmax, k))
                            : wide_any_from8(base, &w, PLANE(tmin, k), PLANE(tmax, k), off, cnt)) {
                    PLANE_I(hit, k) = -1;
                    PLANE(tmax, k) = -INFINITY;
                }
            }
            if (!pany(tmin <= tmax)) return hit;
        } else if (cnt == 0) {
            int slots[8], masks[8];
            float near[8];
            const int n = packet_node(base, off, r, tmin, tmax, lanes, slots, near, masks, 0); /* any order */
            if (n > 0) {
                __global const int *child = (__global const int *)(base + off + 6);
                __global const int *count = (__global const int *)(base + off + 7);
                for (int j = n - 1; j >= 1; --j) {
                    stack_code[sp] = WIDE_CODE(off, slots[j]); stack_lanes[sp] = masks[j]; ++sp;
                }
                lanes = masks[0];
                off = child[slots[0]]; cnt = count[slots[0]];
                continue;
            }
        } else {
            __global const float8 *pk = base + off;
            const pfloat lane_tmin = pmask(lanes) ? tmin : PFLOAT(INFINITY);
            for (int q = 0; q < cnt; ++q, pk += TRI8_UNITS) {
                __global const int *tri = (__global const int *)(pk + 9);
                const Tri8Plane plane = tri8_planes(pk);
                for (int j = 0; j < 8; ++j) {
                    if (tri[j] < 0) continue;
                    pfloat tt, U, V, W;
                    const pint m = packet_triangle(r, pk, &plane, j, lane_tmin, tmax, &tt, &U, &V, &W);
                    if (!pany(m)) continue;
                    hit |= m;
                    tmax = SEL(tmax, PFLOAT(-INFINITY), m);
                    if (!pany(tmin <= tmax)) return hit;
                }
            }
        }
        if (sp == 0) return hit;
        --sp;
        wide_decode8(base, stack_code[sp], &off, &cnt);
        lanes = stack_lanes[sp];
    }
}

#endif /* PACKET_WIDTH > 1 */
#endif
