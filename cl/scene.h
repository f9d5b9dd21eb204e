/* The scene as the wavefront kernels see it: triangles in a BVH, spheres in a short list,
 * materials, emitters; and the parameter list every wavefront kernel shares.
 *
 * Hit encoding: prim >= 0 is a triangle (index into the BVH-reordered triangle array),
 * prim <= -2 is sphere (-2 - prim), prim == -1 is a miss.
 *
 * Features are compiled in only when the scene uses them: HAS_TRIANGLES, HAS_SPHERES,
 * HAS_LIGHTS (next-event estimation), and INTEGRATOR (0 = MIS path, 1 = BSDF sampling only,
 * 2 = light sampling only).
 */
#ifndef PYOPENCL_RT_SCENE_H
#define PYOPENCL_RT_SCENE_H

#include "bvh.h"
#ifdef BVH_WIDE /* the 4-wide layout (CPU devices): replaces bvh_closest_hit / bvh_any_hit */
#include "bvh_wide.h"
#endif
#include "spawn.h"
#include "bsdf.h"
#include "rng.h"

#define PRIM_MISS (-1)
#define SPHERE_PRIM(s) (-2 - (s))
#define IS_SPHERE(prim) ((prim) <= -2)
#define SPHERE_INDEX(prim) (-2 - (prim))

/* Every wavefront kernel takes the same parameters, so the host binds buffers once.
 * Textures (cl/textures.h): tri_uv (3 UVs per reordered triangle), the Texture table, the float4
 * texels and mat_scratch (one effective Material per path slot); dummies without HAS_TEXTURES.
 * env_map, env_cdf: the environment map and its sampling CDFs (cl/lights.h); dummies without
 * HAS_ENVIRONMENT. */
#define WAVE_PARAMS                                                                                 \
    __global const BVHNode *nodes, __global const float4 *tris, __global const int *tri_material,  \
    __global const int *tri_light, __global const Sphere *spheres, __global const int *sphere_material, \
    __global const int *sphere_light, __global const Material *materials, __global const Light *lights, \
    __global const Camera *camera,                                                                  \
    __global float *ray_o, __global float *ray_d, __global float *throughput, __global float *radiance, \
    __global int *path_pixel, __global int *path_pass, __global int *path_depth, __global float *path_pdf, \
    __global float *hit_t, __global int *hit_prim, __global float *hit_u, __global float *hit_v,    \
    __global float *sh_o, __global float *sh_d, __global float *sh_contrib,                         \
    __global const float2 *tri_uv, __global const Texture *textures, __global const float4 *tex_data, \
    __global Material *mat_scratch,                                                                 \
    __global int *queue_in, __global int *queue_out, __global int *shadow_q, __global int *term_q,  \
    __global int *free_q, __global int *counters, __global float *pass_ring,                        \
    __global const float *env_map, __global const float *env_cdf,                                   \
    const int n_spheres, const int n_lights, const int n_pixels, const int ring_size,               \
    const int max_depth, const int rr_depth, const uint seed,                                      \
    const int a0, const int a1, const int a2, const int a3, const int a4

/* Work-group size of every wavefront launch (the host's LOCAL_SIZE, pyopencl_rt/wavefront.py). */
#ifndef WAVE_LOCAL_SIZE
#define WAVE_LOCAL_SIZE 64
#endif

/* counters[] slots (the pass completion counts of the ring follow at COUNTER_PASS_DONE) */
#define COUNTER_QUEUE_OUT 0
#define COUNTER_SHADOW 1
#define COUNTER_TERM 2
#define COUNTER_NONFINITE 3
#define COUNTER_PASS_DONE 8

/* random-number dimensions: 2 for the pixel jitter, then DIMS_PER_BOUNCE per bounce */
#define DIM_PIXEL 0
#define DIM_LENS 0xFFFFFFF0u /* and + 1: the thin lens, far from every bounce's dimensions */
#define DIMS_PER_BOUNCE 8
#define DIM_LIGHT_PICK 0
#define DIM_LIGHT_POINT 1 /* and 2 */
#define DIM_BSDF 3        /* and 4 */
#define DIM_RR 5

RT_INLINE Hit scene_closest_hit(__global const BVHNode *nodes, __global const float4 *tris,
                             __global const Sphere *spheres, int n_spheres,
                             float3 o, float3 d, float tmin, float tmax)
{
    Hit hit;
#ifdef HAS_TRIANGLES
    hit = bvh_closest_hit(nodes, tris, o, d, tmin, tmax);
#else
    hit.t = tmax; hit.u = 0.0f; hit.v = 0.0f; hit.tri = PRIM_MISS;
#endif
#ifdef HAS_SPHERES
    for (int s = 0; s < n_spheres; ++s) {
        float t;
        if (intersect_sphere(o, d, vload3(0, spheres[s].center), spheres[s].radius, tmin, hit.t, &t)) {
            hit.t = t; hit.tri = SPHERE_PRIM(s); hit.u = 0.0f; hit.v = 0.0f;
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
 * o + t*d, whose error is a few ulps of |o| + t|d|: in the millimetre Cornell box that was
 * larger than the spawn offset near x = 0 and y = 0, rays re-hit their own wall and the direct
 * light there was 27% too dark (found by the Mitsuba comparison, docs/CONVERGENCE.md).
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
