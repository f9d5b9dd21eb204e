/* Kernels behind pyopencl_rt.trace() and pyopencl_rt.occluded(): one work-item per ray.
 *
 * Rays are structure-of-arrays: origins and directions are packed float3 (3 floats per ray),
 * tmin/tmax are per ray.
 */
/* bvh_closest_hit / bvh_any_hit of the BVH layout chosen on the host */
#include "accel/traverse.h"

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
    const Hit h = bvh_closest_hit(nodes, tris, o, d, tmin[i], tmax[i]);
    if (h.prim >= 0) {
        out_t[i] = h.t; out_prim[i] = prim_ids[h.prim]; out_u[i] = h.u; out_v[i] = h.v;
        store3(out_ng, i, triangle_normal(tris, h.prim));
    } else {
        out_t[i] = INFINITY; out_prim[i] = -1; out_u[i] = 0.0f; out_v[i] = 0.0f;
        store3(out_ng, i, (float3)(0.0f));
    }
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
