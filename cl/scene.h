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
#include "spawn.h"
#include "bsdf.h"
#include "rng.h"

#define PRIM_MISS (-1)
#define SPHERE_PRIM(s) (-2 - (s))
#define IS_SPHERE(prim) ((prim) <= -2)
#define SPHERE_INDEX(prim) (-2 - (prim))

/* Every wavefront kernel takes the same parameters, so the host binds buffers once. */
#define WAVE_PARAMS                                                                                 \
    __global const BVHNode *nodes, __global const float4 *tris, __global const int *tri_material,  \
    __global const int *tri_light, __global const Sphere *spheres, __global const int *sphere_material, \
    __global const int *sphere_light, __global const Material *materials, __global const Light *lights, \
    __global const Camera *camera,                                                                  \
    __global float *ray_o, __global float *ray_d, __global float *throughput, __global float *radiance, \
    __global int *path_pixel, __global int *path_pass, __global int *path_depth, __global float *path_pdf, \
    __global float *hit_t, __global int *hit_prim, __global float *hit_u, __global float *hit_v,    \
    __global float *sh_o, __global float *sh_d, __global float *sh_contrib,                         \
    __global int *queue_in, __global int *queue_out, __global int *shadow_q, __global int *term_q,  \
    __global int *free_q, __global int *counters, __global float *pass_ring,                        \
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
