/* Kernels behind pyopencl_rt.trace() and pyopencl_rt.occluded(): one work-item per ray, or, on
 * CPUs with the 8-wide layout (PACKET_WIDTH defined by the host), one work-item per PACKET_WIDTH
 * consecutive rays of the batch.
 *
 * Rays are structure-of-arrays: origins and directions are packed float3 (3 floats per ray),
 * tmin/tmax are per ray.
 */
/* bvh_closest_hit / bvh_any_hit of the BVH layout chosen on the host */
#include "accel/traverse.h"

/* A ray's result: the caller's triangle index and its geometric normal, or a miss. */
RT_INLINE void write_hit(Hit h, int i, __global const float4 *tris, __global const int *prim_ids,
                         __global float *out_t, __global int *out_prim, __global float *out_u, __global float *out_v,
                         __global float *out_ng)
{
    if (h.prim >= 0) {
        out_t[i] = h.t; out_prim[i] = prim_ids[h.prim]; out_u[i] = h.u; out_v[i] = h.v;
        store3(out_ng, i, triangle_normal(tris, h.prim));
    } else {
        out_t[i] = INFINITY; out_prim[i] = -1; out_u[i] = 0.0f; out_v[i] = 0.0f;
        store3(out_ng, i, (float3)(0.0f));
    }
}

__kernel void trace_closest(__global const BVHNode *nodes, __global const float4 *tris,
                            __global const int *prim_ids,
                            __global const float *origins, __global const float *directions,
                            __global const float *tmin, __global const float *tmax,
                            const int n_rays,
                            __global float *out_t, __global int *out_prim,
                            __global float *out_u, __global float *out_v, __global float *out_ng)
{
    const int i = get_global_id(0);
    if (i >= n_rays) return;
    const float3 o = load3(origins, i), d = load3(directions, i);
    write_hit(bvh_closest_hit(nodes, tris, o, d, tmin[i], tmax[i]), i, tris, prim_ids, out_t, out_prim, out_u, out_v,
              out_ng);
}

__kernel void trace_any(__global const BVHNode *nodes, __global const float4 *tris,
                        __global const float *origins, __global const float *directions,
                        __global const float *tmin, __global const float *tmax,
                        const int n_rays, __global uchar *out_hit)
{
    const int i = get_global_id(0);
    if (i >= n_rays) return;
    out_hit[i] = (uchar)bvh_any_hit(nodes, tris, load3(origins, i), load3(directions, i), tmin[i], tmax[i]);
}

#if PACKET_WIDTH > 1
/* ---------------------------------------------------------------------------------------------
 * Packets: rays PACKET_WIDTH * i .. PACKET_WIDTH * i + PACKET_WIDTH - 1 in the lanes of work-item
 * i, traced with bvh_packet.h (16 rays per node or triangle test where they go the same way, ray
 * by ray below where they part), as Embree's rtcIntersect16 traces a packet.  Consecutive rays of
 * a batch are often neighbours (a camera's pixels, the bounces of neighbouring pixels), and then
 * the top of the tree is tested once for all of them.  When their origins lie far apart (more
 * than origin_spread apart along an axis: a batch in random order), the packet would share
 * little and costs its bookkeeping, so its rays go one by one through bvh_closest_hit.  Either
 * way each ray's hit is the single-ray traversal's, bit for bit, but for which of two triangles
 * at exactly the same t is reported (bvh_packet.h).  Lanes past the batch's end are idle
 * (tmax < tmin). */
#include "accel/bvh_packet.h"

/* The packet's rays one by one, out of line: inlined beside the packet traversal, the single-ray
 * loop ran 9% slower (its registers spilled). */
__attribute__((noinline)) Hit trace_one(__global const float8 *nodes, __global const float4 *tris, float3 o, float3 d,
                                        float tmin, float tmax)
{
    return bvh_closest_hit(nodes, tris, o, d, tmin, tmax);
}

typedef struct {
    pvec3 o, d;
    pfloat tmin, tmax;
    int n;          /* rays of the batch in this packet */
    int coherent;   /* origins within origin_spread of each other on every axis */
} TracePacket;

/* The packet of rays base .. base + PACKET_WIDTH - 1 (base < n_rays). */
RT_INLINE TracePacket load_trace_packet(__global const float *origins, __global const float *directions,
                                        __global const float *tmin, __global const float *tmax, int base,
                                        int n_rays, float origin_spread)
{
    TracePacket p;
    p.n = min(PACKET_WIDTH, n_rays - base);
    float3 lo = (float3)(INFINITY), hi = (float3)(-INFINITY);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        const int i = base + min(k, p.n - 1);   /* idle lanes repeat the last ray, with tmax < tmin */
        const float3 o = load3(origins, i);
        pv3_set_lane(&p.o, k, o);
        pv3_set_lane(&p.d, k, load3(directions, i));
        PLANE(p.tmin, k) = k < p.n ? tmin[i] : 1.0f;
        PLANE(p.tmax, k) = k < p.n ? tmax[i] : 0.0f;
        lo = fmin(lo, o);
        hi = fmax(hi, o);
    }
    const float3 spread = hi - lo;
    p.coherent = fmax(fmax(spread.x, spread.y), spread.z) <= origin_spread;
    return p;
}

__kernel LANE_KERNEL void trace_closest_packets(__global const float8 *nodes, __global const float4 *tris,
                                    __global const int *prim_ids,
                                    __global const float *origins, __global const float *directions,
                                    __global const float *tmin, __global const float *tmax,
                                    const int n_rays, const float origin_spread,
                                    __global float *out_t, __global int *out_prim,
                                    __global float *out_u, __global float *out_v, __global float *out_ng)
{
    if (get_global_id(0) * PACKET_WIDTH >= n_rays) return;
    const int base = get_global_id(0) * PACKET_WIDTH;
    const TracePacket p = load_trace_packet(origins, directions, tmin, tmax, base, n_rays, origin_spread);
    pfloat t = p.tmax, u = PFLOAT(0.0f), v = PFLOAT(0.0f);
    pint prim = PINT(PRIM_MISS);
    if (p.coherent) {
        const PacketRay r = packet_rays(p.o, p.d);
        packet_closest_hit(nodes, &r, p.tmin, &t, &prim, &u, &v);
    } else {
        for (int k = 0; k < p.n; ++k) {
            const Hit h = trace_one(nodes, tris, pv3_lane(p.o, k), pv3_lane(p.d, k), PLANE(p.tmin, k), PLANE(p.tmax, k));
            PLANE(t, k) = h.t; PLANE_I(prim, k) = h.prim; PLANE(u, k) = h.u; PLANE(v, k) = h.v;
        }
    }
    for (int k = 0; k < p.n; ++k) {
        Hit h;
        h.t = PLANE(t, k); h.prim = PLANE_I(prim, k); h.u = PLANE(u, k); h.v = PLANE(v, k);
        write_hit(h, base + k, tris, prim_ids, out_t, out_prim, out_u, out_v, out_ng);
    }
}

__kernel LANE_KERNEL void trace_any_packets(__global const float8 *nodes, __global const float4 *tris,
                                __global const float *origins, __global const float *directions,
                                __global const float *tmin, __global const float *tmax,
                                const int n_rays, const float origin_spread, __global uchar *out_hit)
{
    if (get_global_id(0) * PACKET_WIDTH >= n_rays) return;
    const int base = get_global_id(0) * PACKET_WIDTH;
    const TracePacket p = load_trace_packet(origins, directions, tmin, tmax, base, n_rays, origin_spread);
    if (p.coherent) {
        const PacketRay r = packet_rays(p.o, p.d);
        const pint hit = packet_any_hit(nodes, &r, p.tmin, p.tmax);
        for (int k = 0; k < p.n; ++k) out_hit[base + k] = (uchar)(PLANE_I(hit, k) != 0);
    } else {
        for (int k = 0; k < p.n; ++k)
            out_hit[base + k] = (uchar)bvh_any_hit(nodes, tris, pv3_lane(p.o, k), pv3_lane(p.d, k), PLANE(p.tmin, k),
                                                   PLANE(p.tmax, k));
    }
}
#endif
