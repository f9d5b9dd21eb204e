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
/* the packets of lanes wider than 1 (it includes nothing traverse.h has not: see lanes.h on
 * conditional includes) */
#if PACKET_WIDTH > 1 && defined(HAS_TRIANGLES)
#include "accel/bvh_packet.h"
#endif
#include "render/spawn.h"
#include "materials/dispatch.h"
#include "render/sampler.h"

#define SPHERE_PRIM(s) (PRIM_SPHERE_FIRST - (s))
#define IS_SPHERE(prim) ((prim) <= PRIM_SPHERE_FIRST)
#define SPHERE_INDEX(prim) (PRIM_SPHERE_FIRST - (prim))

/* The closest hits of the lanes of `live` (t in (0, inf)): *prim (PRIM_MISS for none), *t, and
 * the barycentrics *u, *v of a triangle.  One ray through the BVH layout of traverse.h at width 1,
 * a packet (cl/accel/bvh_packet.h) in lanes; spheres one after the other, over the lanes. */
RT_INLINE void scene_closest_hit(__global const BVHNode *nodes, __global const float4 *tris,
                                 __global const Sphere *spheres, int n_spheres, pvec3 o, pvec3 d, pint live,
                                 pfloat *t, pint *prim, pfloat *u, pfloat *v)
{
    *prim = PINT(PRIM_MISS);
    *u = *v = PFLOAT(0.0f);
#if PACKET_WIDTH == 1
    *t = INFINITY;
#ifdef HAS_TRIANGLES
    if (live) {
        const Hit h = bvh_closest_hit(nodes, tris, (float3)(o.x, o.y, o.z), (float3)(d.x, d.y, d.z), 0.0f, INFINITY);
        *t = h.t; *prim = h.prim; *u = h.u; *v = h.v;
    }
#endif
#else
    *t = live ? PFLOAT(INFINITY) : PFLOAT(-1.0f); /* idle lanes: tmax < tmin */
#ifdef HAS_TRIANGLES
    const PacketRay r = packet_rays(o, d);
    packet_closest_hit(nodes, &r, PFLOAT(0.0f), t, prim, u, v);
#endif
#endif
#ifdef HAS_SPHERES
    for (int s = 0; s < n_spheres; ++s) {
        const pint h = intersect_sphere(o, d, pv3_splat(vload3(0, spheres[s].center)), PFLOAT(spheres[s].radius),
                                        PFLOAT(0.0f), *t, t, live);
        *prim = h ? PINT(SPHERE_PRIM(s)) : *prim;
        *u = h ? PFLOAT(0.0f) : *u;
        *v = h ? PFLOAT(0.0f) : *v;
    }
#endif
}

/* The lanes of `live` whose segment o + t d, t in (0, tmax), is blocked. */
RT_INLINE pint scene_occluded(__global const BVHNode *nodes, __global const float4 *tris,
                              __global const Sphere *spheres, int n_spheres, pvec3 o, pvec3 d, pint live,
                              pfloat tmax)
{
    pint blocked = PINT(0);
#ifdef HAS_SPHERES
    for (int s = 0; s < n_spheres; ++s) {
        pfloat t;
        blocked |= intersect_sphere(o, d, pv3_splat(vload3(0, spheres[s].center)), PFLOAT(spheres[s].radius),
                                    PFLOAT(0.0f), tmax, &t, live & pnot(blocked));
    }
#endif
#ifdef HAS_TRIANGLES
    const pint rest = live & pnot(blocked);
#if PACKET_WIDTH == 1
    if (rest) blocked = bvh_any_hit(nodes, tris, (float3)(o.x, o.y, o.z), (float3)(d.x, d.y, d.z), 0.0f, tmax);
#else
    if (pany(rest)) {
        const PacketRay r = packet_rays(o, d);
        blocked |= packet_any_hit(nodes, &r, PFLOAT(0.0f), rest ? tmax : PFLOAT(-1.0f));
    }
#endif
#endif
    return blocked & live;
}

/* The hit point and a bound on its rounding error per coordinate.  Triangles interpolate the
 * vertices with the hit's barycentrics (error: a few ulps of the vertices, pbrt's bound), not
 * o + t*d, whose error is a few ulps of |o| + t|d|: that can exceed the spawn offset near a
 * coordinate plane far from the ray's origin, so rays would re-hit their own surface (the bias
 * this caused is described in docs/CONVERGENCE.md).
 * Spheres re-project o + t*d onto the surface (pbrt-v4, 6.8.5). */
#define HIT_GAMMA5 2.98023259e-07f /* 5 * 2^-24 / (1 - 5 * 2^-24), rounded up */

/* Gathers of the lanes' primitives (every index valid): vertex k of triangle prim (tris: three
 * float4 a triangle), and a sphere's centre and radius. */
RT_INLINE pvec3 tri_vertex(__global const float4 *tris, pint prim, int k)
{
    __global const float *f = (__global const float *)tris;
    const pint i = prim * 12 + 4 * k;
    return pv3_gather(f, i);
}

RT_INLINE pvec3 sphere_center(__global const Sphere *spheres, pint s)
{
    __global const float *f = (__global const float *)spheres;
    const pint i = s * STRIDE_INDEX(Sphere) + FIELD_INDEX(Sphere, center);
    return pv3_gather(f, i);
}

RT_INLINE pfloat sphere_radius(__global const Sphere *spheres, pint s)
{
    return pgather((__global const float *)spheres, s * STRIDE_INDEX(Sphere) + FIELD_INDEX(Sphere, radius));
}

/* Per lane: triangles (prim >= 0) and (HAS_SPHERES) spheres; lanes of neither (PRIM_MISS) get 0. */
RT_INLINE pvec3 hit_point(__global const float4 *tris, __global const Sphere *spheres, pint prim,
                          pvec3 o, pvec3 d, pfloat t, pfloat u, pfloat v, pvec3 *err)
{
    pvec3 p = pv3_zero();
    *err = pv3_zero();
    const pint tri = prim >= 0;
    if (pany(tri)) {
        const pint i = tri ? prim : PINT(0);
        p = triangle_point(tri_vertex(tris, i, 0), tri_vertex(tris, i, 1), tri_vertex(tris, i, 2), u, v, err);
    }
#ifdef HAS_SPHERES
    const pint sphere = IS_SPHERE(prim);
    if (pany(sphere)) {
        const pint s = sphere ? SPHERE_INDEX(prim) : PINT(0);
        const pvec3 c = sphere_center(spheres, s);
        const pvec3 ps = pv3_add(c, pv3_scale(pv3_normalize(pv3_sub(pv3_add(o, pv3_scale(d, t)), c), sphere),
                                              sphere_radius(spheres, s)));
        *err = pv3_sel(*err, pv3_scale(pv3_add(pv3_abs(ps), pv3_abs(c)), PFLOAT(HIT_GAMMA5)), sphere);
        p = pv3_sel(p, ps, sphere);
    }
#endif
    return p;
}

/* Unit geometric normal at a hit (triangles: (v1-v0)x(v2-v0); spheres: outward), per lane (`live`:
 * the lanes whose normal counts, for pv3_normalize's fallback; lanes of neither kind get 0). */
RT_INLINE pvec3 hit_normal(__global const float4 *tris, __global const Sphere *spheres, pint prim, pvec3 p, pint live)
{
    pvec3 n = pv3_zero();
    const pint tri = prim >= 0;
    if (pany(tri)) {
        const pint i = tri ? prim : PINT(0);
        const pvec3 p0 = tri_vertex(tris, i, 0);
        n = pv3_normalize(pv3_cross(pv3_sub(tri_vertex(tris, i, 1), p0), pv3_sub(tri_vertex(tris, i, 2), p0)), live & tri);
    }
#ifdef HAS_SPHERES
    const pint sphere = IS_SPHERE(prim);
    if (pany(sphere)) {
        const pint s = sphere ? SPHERE_INDEX(prim) : PINT(0);
        n = pv3_sel(n, pv3_div(pv3_sub(p, sphere_center(spheres, s)), sphere_radius(spheres, s)), sphere);
    }
#endif
    return n;
}

#endif
