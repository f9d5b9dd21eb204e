/* The scene as the wavefront kernels see it: triangles in a BVH, spheres in a short list,
 * materials, emitters.  The parameter list every wavefront kernel shares (WAVE_PARAMS), the
 * COUNTER_* slots and the hit encoding (PRIM_MISS, PRIM_SPHERE_FIRST) are generated from
 * pyopencl_rt/device/abi.py.
 *
 * Features are compiled in only when the scene uses them: HAS_TRIANGLES, HAS_SPHERES,
 * HAS_LIGHTS (next-event estimation), and INTEGRATOR (0 = MIS path, 1 = BSDF sampling only,
 * 2 = light sampling only).
 */
#ifndef PYOPENCL_RT_SCENE_H
#define PYOPENCL_RT_SCENE_H

/* bvh_closest_hit / bvh_any_hit of the BVH layout chosen on the host */
#include "accel/traverse.h"
#include "render/spawn.h"
#include "materials/dispatch.h"
#include "render/sampler.h"

#define SPHERE_PRIM(s) (PRIM_SPHERE_FIRST - (s))
#define IS_SPHERE(prim) ((prim) <= PRIM_SPHERE_FIRST)
#define SPHERE_INDEX(prim) (PRIM_SPHERE_FIRST - (prim))

RT_INLINE Hit scene_closest_hit(__global const BVHNode *nodes, __global const float4 *tris,
                             __global const Sphere *spheres, int n_spheres,
                             float3 o, float3 d, float tmin, float tmax)
{
    Hit hit;
#ifdef HAS_TRIANGLES
    hit = bvh_closest_hit(nodes, tris, o, d, tmin, tmax);
#else
    hit.t = tmax; hit.u = 0.0f; hit.v = 0.0f; hit.prim = PRIM_MISS;
#endif
#ifdef HAS_SPHERES
    for (int s = 0; s < n_spheres; ++s) {
        float t;
        if (intersect_sphere(o, d, vload3(0, spheres[s].center), spheres[s].radius, tmin, hit.t, &t)) {
            hit.t = t; hit.prim = SPHERE_PRIM(s); hit.u = 0.0f; hit.v = 0.0f;
        }
    }
#endif
    return hit;
}

RT_INLINE int scene_occluded(__global const BVHNode *nodes, __global const float4 *tris,
                          __global const Sphere *spheres, int n_spheres,
                          float3 o, float3 d, float tmin, float tmax)
{
#ifdef HAS_SPHERES
    for (int s = 0; s < n_spheres; ++s) {
        float t;
        if (intersect_sphere(o, d, vload3(0, spheres[s].center), spheres[s].radius, tmin, tmax, &t))
            return 1;
    }
#endif
#ifdef HAS_TRIANGLES
    return bvh_any_hit(nodes, tris, o, d, tmin, tmax);
#else
    return 0;
#endif
}

/* The hit point and a bound on its rounding error per coordinate.  Triangles interpolate the
 * vertices with the hit's barycentrics (error: a few ulps of the vertices, pbrt's bound), not
 * o + t*d, whose error is a few ulps of |o| + t|d|: that can exceed the spawn offset near a
 * coordinate plane far from the ray's origin, so rays would re-hit their own surface (the bias
 * this caused is described in docs/CONVERGENCE.md).
 * Spheres re-project o + t*d onto the surface (pbrt-v4, 6.8.5). */
#define HIT_GAMMA5 2.98023259e-07f /* 5 * 2^-24 / (1 - 5 * 2^-24), rounded up */
RT_INLINE float3 hit_point(__global const float4 *tris, __global const Sphere *spheres, int prim,
                           float3 o, float3 d, float t, float u, float v, float3 *err)
{
#ifdef HAS_SPHERES
    if (IS_SPHERE(prim)) {
        __global const Sphere *s = spheres + SPHERE_INDEX(prim);
        const float3 c = vload3(0, s->center);
        const float3 p = c + s->radius * normalize(o + t * d - c);
        *err = HIT_GAMMA5 * (fabs(p) + fabs(c));
        return p;
    }
#endif
    return triangle_point(tris[3 * prim].xyz, tris[3 * prim + 1].xyz, tris[3 * prim + 2].xyz, u, v, err);
}

/* Unit geometric normal at a hit (triangles: (v1-v0)x(v2-v0); spheres: outward). */
RT_INLINE float3 hit_normal(__global const float4 *tris, __global const Sphere *spheres, int prim, float3 p)
{
#ifdef HAS_SPHERES
    if (IS_SPHERE(prim)) {
        __global const Sphere *s = spheres + SPHERE_INDEX(prim);
        return (p - vload3(0, s->center)) / s->radius;
    }
#endif
    return triangle_normal(tris, prim);
}

#endif
