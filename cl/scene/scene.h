/* The scene as the wavefront kernels see it: triangles in a BVH, analytic shapes in a BVH of
 * their own (scene/shapes.h), materials, emitters.  The parameter list every wavefront kernel
 * shares (WAVE_PARAMS), the COUNTER_* slots and the hit encoding (PRIM_MISS, PRIM_SHAPE_FIRST) are
 * generated from pyopencl_rt/device/abi.py.
 *
 * Features are compiled in only when the scene uses them: HAS_TRIANGLES, HAS_SHAPES,
 * HAS_LIGHTS (next-event estimation); the estimator (MIS path, BSDF sampling only, light sampling
 * only) is the kernel argument `integrator`.
 */
#ifndef PYOPENCL_RT_SCENE_H
#define PYOPENCL_RT_SCENE_H

/* bvh_closest_hit / bvh_any_hit of the BVH layout chosen on the host */
#include "accel/traverse.h"
/* the packets of lanes wider than 1 */
#if PACKET_WIDTH > 1 && defined(HAS_TRIANGLES)
#include "accel/bvh_packet.h"
#endif
#ifdef HAS_INSTANCES
#include "accel/instances.h"
#endif
#include "render/spawn.h"
#include "materials/dispatch.h"
#include "render/sampler.h"
/* the alpha cut-outs below look textures up */
#include "scene/textures.h"

/* the hit encoding of shapes (SHAPE_PRIM), and with HAS_SHAPES their BVH and dispatch */
#include "scene/shape_lanes.h"
#ifdef HAS_SHAPES
#include "scene/shapes.h"
#endif

/* Alpha cut-outs in the intersection (MATERIAL_FLAG_CUTOUT: pbrt-v4's shape alpha, glTF's
 * alphaMode; not in scenes with media): a triangle hit whose alpha fails the test is no hit, so
 * the closest-hit and occlusion queries trace on past it (t > the skipped hit's t), up to
 * MAX_CUTOUT_SKIPS times (then the hit stands).  The test, at the hit's uv, lane by lane: alpha =
 * opacity times the R of its TEXP_OPACITY texture; alpha_cutoff > 0: alpha < alpha_cutoff fails
 * (glTF MASK); else alpha <= 0 fails, alpha >= 1 passes, and otherwise a hash of the ray's origin
 * and direction in [0, 1) above alpha fails (pbrt-v4's HashFloat(o, d) > alpha).  Analytic shapes
 * (no uv) are opaque.  CUTOUT_PARAMS / CUTOUT_ARGS add the buffers the test reads to
 * scene_closest_hit and scene_occluded; the kernels' WAVE_PARAMS name them. */
#if defined(HAS_CUTOUTS) && !defined(HAS_MEDIA) && defined(HAS_TRIANGLES)
#define CUTOUTS_ON
#ifndef MAX_CUTOUT_SKIPS
#define MAX_CUTOUT_SKIPS 16
#endif
#define CUTOUT_PARAMS , __global const int *tri_material, __global const Material *materials, \
    __global const float2 *tri_uv, __global const Texture *textures, __global const float4 *tex_data
#define CUTOUT_ARGS , tri_material, materials, tri_uv, textures, tex_data

/* a hash of the ray's bits in [0, 1) (pbrt-v4 hashes them with MurmurHash: any good mix will do) */
RT_INLINE float cutout_hash(float3 o, float3 d)
{
    uint h = 0x9e3779b9u;
    const uint w[6] = {as_uint(o.x), as_uint(o.y), as_uint(o.z), as_uint(d.x), as_uint(d.y), as_uint(d.z)};
    for (int i = 0; i < 6; ++i) {
        h ^= w[i] * 0xcc9e2d51u;
        h = (h << 15) | (h >> 17);
        h *= 0x1b873593u;
        h ^= h >> 16;
        h *= 0x85ebca6bu;
        h ^= h >> 13;
    }
    return (float)(h >> 8) * 0x1p-24f;
}

/* 1 where the triangle hit (prim, u, v) of ray (o, d) is cut out */
RT_INLINE int cutout_skips(__global const int *tri_material, __global const Material *materials,
                           __global const float2 *tri_uv, __global const Texture *textures,
                           __global const float4 *tex_data, int prim, float u, float v, float3 o, float3 d)
{
    if (prim < 0) return 0; /* a miss or a shape */
    __global const Material *m = materials + tri_material[prim];
    if ((m->flags & MATERIAL_FLAG_CUTOUT) == 0) return 0;
    float a = m->opacity;
#ifdef HAS_TEXTURES
    a = tex_scalar_times(a, (__global const int *)m, TEXP_OPACITY, tri_uv, textures, tex_data, prim, u, v);
#endif
    if (m->alpha_cutoff > 0.0f) return a < m->alpha_cutoff;
    if (a >= 1.0f) return 0;
    if (a <= 0.0f) return 1;
    return cutout_hash(o, d) > a;
}

/* the lanes of `live` whose hits (prim, t, u, v) are cut out */
RT_INLINE pint cutout_lanes(__global const int *tri_material, __global const Material *materials,
                            __global const float2 *tri_uv, __global const Texture *textures,
                            __global const float4 *tex_data, pint live, pint prim, pfloat u, pfloat v, pvec3 o, pvec3 d)
{
#if PACKET_WIDTH == 1
    return live && cutout_skips(tri_material, materials, tri_uv, textures, tex_data, prim, u, v, (float3)(o.x, o.y, o.z),
                                (float3)(d.x, d.y, d.z));
#else
    pint out = PINT(0);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        if (!PLANE_I(live, k)) continue;
        const float3 ok = (float3)(PLANE(o.x, k), PLANE(o.y, k), PLANE(o.z, k));
        const float3 dk = (float3)(PLANE(d.x, k), PLANE(d.y, k), PLANE(d.z, k));
        PLANE_I(out, k) = cutout_skips(tri_material, materials, tri_uv, textures, tex_data, PLANE_I(prim, k),
                                       PLANE(u, k), PLANE(v, k), ok, dk) ? -1 : 0;
    }
    return out;
#endif
}
#else
#define CUTOUT_PARAMS
#define CUTOUT_ARGS
#endif

/* Two-level instances (HAS_INSTANCES, cl/accel/instances.h): scene_closest_hit and scene_occluded
 * also take the TLAS, the instance records and the groups' BVHs (INSTANCE_PARAMS), and the
 * closest hit reports the instance of each lane's hit (*inst, -1: none) after the world's BVH has
 * set the lane's tmax.  One ray at a time at every width: in lanes each lane walks the TLAS and
 * its instances by itself (the wide single-ray traversal inside), after the packet's world pass. */
#ifdef HAS_INSTANCES
#ifdef HAS_MOTION /* and the moving instances' ways (cl/accel/instances.h) */
#define INSTANCE_PARAMS_NOCOMMA __global const BVHNode *tlas, __global const Instance *instances, \
    __global const BVHNode *blas_nodes, __global const Motion *instance_motion
#define INSTANCE_ARGS_NOCOMMA tlas, instances, blas_nodes, instance_motion
#else
#define INSTANCE_PARAMS_NOCOMMA __global const BVHNode *tlas, __global const Instance *instances, \
    __global const BVHNode *blas_nodes
#define INSTANCE_ARGS_NOCOMMA tlas, instances, blas_nodes
#endif
#define INSTANCE_ARGS , INSTANCE_ARGS_NOCOMMA
#define INSTANCE_PARAMS , INSTANCE_PARAMS_NOCOMMA
#ifdef HAS_MOTION /* the lanes' time samples (cl/render/sampler.h time_sample) */
#define SCENE_TIME_PARAM , pfloat time
#define SCENE_TIME_ARG(u) , u
#else
#define SCENE_TIME_PARAM
#define SCENE_TIME_ARG(u)
#endif
#define INSTANCE_HIT_PARAMS INSTANCE_PARAMS, pint *inst SCENE_TIME_PARAM
#define INSTANCE_HIT_ARGS(inst) INSTANCE_ARGS, inst
/* scene_occluded's; with motion blur both also take the lanes' time samples (SCENE_TIME_ARG) */
#define INSTANCE_OCCLUDED_PARAMS INSTANCE_PARAMS SCENE_TIME_PARAM
/* path_shade's: the instance records (through PATH_PARAMS) and the lanes' instances */
#define INSTANCE_SHADE_PARAMS , pint inst
#define INSTANCE_SHADE_ARGS(inst) , inst

/* the lanes of `live`: a closer hit among the instances than *t (updated with the rest) */
RT_INLINE void instance_lanes_hit(INSTANCE_PARAMS_NOCOMMA, __global const float4 *tris, pvec3 o, pvec3 d,
                                  pint live, pfloat *t, pint *prim, pfloat *u, pfloat *v, pint *inst SCENE_TIME_PARAM)
{
    *inst = PINT(-1);
#if PACKET_WIDTH == 1
    if (live) {
        Hit h; h.t = *t; h.u = *u; h.v = *v; h.prim = *prim;
        instances_closest_hit(tlas, instances, blas_nodes, tris, (float3)(o.x, o.y, o.z), (float3)(d.x, d.y, d.z),
                              0.0f, &h, inst MOTION_TIME_ARG(time));
        *t = h.t; *prim = h.prim; *u = h.u; *v = h.v;
    }
#else
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        if (!PLANE_I(live, k)) continue;
        Hit h; h.t = PLANE(*t, k); h.u = PLANE(*u, k); h.v = PLANE(*v, k); h.prim = PLANE_I(*prim, k);
        int in = -1;
        instances_closest_hit(tlas, instances, blas_nodes, tris, pv3_lane(o, k), pv3_lane(d, k), 0.0f, &h, &in
                              MOTION_TIME_ARG(PLANE(time, k)));
        PLANE(*t, k) = h.t; PLANE_I(*prim, k) = h.prim; PLANE(*u, k) = h.u; PLANE(*v, k) = h.v;
        PLANE_I(*inst, k) = in;
    }
#endif
}

/* the lanes of `live` that an instance blocks in (0, tmax) */
RT_INLINE pint instance_lanes_occluded(INSTANCE_PARAMS_NOCOMMA, __global const float4 *tris, pvec3 o, pvec3 d,
                                       pint live, pfloat tmax SCENE_TIME_PARAM)
{
#if PACKET_WIDTH == 1
    return live && instances_any_hit(tlas, instances, blas_nodes, tris, (float3)(o.x, o.y, o.z),
                                     (float3)(d.x, d.y, d.z), 0.0f, tmax MOTION_TIME_ARG(time));
#else
    int bits = 0;
    for (int k = 0; k < PACKET_WIDTH; ++k)
        if (PLANE_I(live, k) && instances_any_hit(tlas, instances, blas_nodes, tris, pv3_lane(o, k), pv3_lane(d, k),
                                                  0.0f, PLANE(tmax, k) MOTION_TIME_ARG(PLANE(time, k))))
            bits |= 1 << k;
    return pmask(bits);
#endif
}
#else
#define INSTANCE_PARAMS
#define INSTANCE_ARGS
#define INSTANCE_HIT_PARAMS
#define INSTANCE_HIT_ARGS(inst)
#define INSTANCE_OCCLUDED_PARAMS
#define SCENE_TIME_ARG(u)
#define INSTANCE_SHADE_PARAMS
#define INSTANCE_SHADE_ARGS(inst)
#endif

/* The closest hits of the lanes of `live` (t in (0, inf)): *prim (PRIM_MISS for none), *t, and
 * the barycentrics *u, *v of a triangle.  One ray through the BVH layout of traverse.h at width 1,
 * a packet (cl/accel/bvh_packet.h) in lanes; then the shapes' BVH, over the lanes (scene/shapes.h). */
RT_INLINE void scene_closest_hit(__global const BVHNode *nodes, __global const float4 *tris,
                                 __global const BVHNode *shape_nodes, __global const Shape *shapes, pvec3 o, pvec3 d, pint live,
                                 pfloat *t, pint *prim, pfloat *u, pfloat *v CUTOUT_PARAMS INSTANCE_HIT_PARAMS)
{
    *prim = PINT(PRIM_MISS);
    *u = *v = PFLOAT(0.0f);
#if PACKET_WIDTH == 1
    *t = INFINITY;
#ifdef HAS_TRIANGLES
    if (live) {
        const float3 o1 = (float3)(o.x, o.y, o.z), d1 = (float3)(d.x, d.y, d.z);
        Hit h = bvh_closest_hit(nodes, tris, o1, d1, 0.0f, INFINITY);
#ifdef CUTOUTS_ON
        for (int k = 0; k < MAX_CUTOUT_SKIPS && cutout_skips(tri_material, materials, tri_uv, textures, tex_data, h.prim,
                                                            h.u, h.v, o1, d1); ++k)
            h = bvh_closest_hit(nodes, tris, o1, d1, h.t, INFINITY);
#endif
        *t = h.t; *prim = h.prim; *u = h.u; *v = h.v;
    }
#endif
#else
    *t = live ? PFLOAT(INFINITY) : PFLOAT(-1.0f); /* idle lanes: tmax < tmin */
#ifdef HAS_TRIANGLES
    const PacketRay r = packet_rays(o, d);
    packet_closest_hit(nodes, &r, PFLOAT(0.0f), t, prim, u, v);
#ifdef CUTOUTS_ON
    pint again = cutout_lanes(tri_material, materials, tri_uv, textures, tex_data, live, *prim, *u, *v, o, d);
    for (int k = 0; k < MAX_CUTOUT_SKIPS && pany(again); ++k) {
        /* the cut-out lanes trace on past their hits; the others sit idle (tmax < tmin) */
        const pfloat tmin = again ? *t : PFLOAT(0.0f);
        pfloat t2 = again ? PFLOAT(INFINITY) : PFLOAT(-1.0f), u2 = PFLOAT(0.0f), v2 = PFLOAT(0.0f);
        pint p2 = PINT(PRIM_MISS);
        packet_closest_hit(nodes, &r, tmin, &t2, &p2, &u2, &v2);
        *t = again ? t2 : *t;
        *prim = again ? p2 : *prim;
        *u = again ? u2 : *u;
        *v = again ? v2 : *v;
        again = cutout_lanes(tri_material, materials, tri_uv, textures, tex_data, again, *prim, *u, *v, o, d);
    }
    *t = (live & (*prim == PRIM_MISS)) ? PFLOAT(INFINITY) : *t;
#endif
#endif
#endif
#ifdef HAS_INSTANCES
    instance_lanes_hit(INSTANCE_ARGS_NOCOMMA, tris, o, d, live, t, prim, u, v, inst SCENE_TIME_ARG(time));
#endif
#ifdef HAS_SHAPES
    const pint h = shapes_walk(shape_nodes, shapes, o, d, live, t, prim, 0);
#ifdef HAS_INSTANCES
    *inst = h ? PINT(-1) : *inst;
#endif
    *u = h ? PFLOAT(0.0f) : *u;
    *v = h ? PFLOAT(0.0f) : *v;
#endif
}

/* The lanes of `live` whose segment o + t d, t in (0, tmax), is blocked. */
RT_INLINE pint scene_occluded(__global const BVHNode *nodes, __global const float4 *tris,
                              __global const BVHNode *shape_nodes, __global const Shape *shapes, pvec3 o, pvec3 d, pint live,
                              pfloat tmax CUTOUT_PARAMS INSTANCE_OCCLUDED_PARAMS)
{
    pint blocked = PINT(0);
#ifdef HAS_SHAPES
    pfloat t_shapes = tmax;
    pint prim_unused = PINT(PRIM_MISS);
    blocked = shapes_walk(shape_nodes, shapes, o, d, live, &t_shapes, &prim_unused, 1);
#endif
#ifdef HAS_TRIANGLES
    const pint rest = live & pnot(blocked);
#ifdef CUTOUTS_ON
    /* the closest hits in turn, past the cut-out ones: blocked by the first that stands */
#if PACKET_WIDTH == 1
    if (rest) {
        const float3 o1 = (float3)(o.x, o.y, o.z), d1 = (float3)(d.x, d.y, d.z);
        Hit h = bvh_closest_hit(nodes, tris, o1, d1, 0.0f, tmax);
        for (int k = 0; k < MAX_CUTOUT_SKIPS && cutout_skips(tri_material, materials, tri_uv, textures, tex_data, h.prim,
                                                            h.u, h.v, o1, d1); ++k)
            h = bvh_closest_hit(nodes, tris, o1, d1, h.t, tmax);
        blocked = h.prim != PRIM_MISS;
    }
#else
    if (pany(rest)) {
        const PacketRay r = packet_rays(o, d);
        pint again = rest;
        pfloat tmin = PFLOAT(0.0f);
        for (int k = 0; k <= MAX_CUTOUT_SKIPS && pany(again); ++k) {
            pfloat th = again ? tmax : PFLOAT(-1.0f), uh = PFLOAT(0.0f), vh = PFLOAT(0.0f);
            pint ph = PINT(PRIM_MISS);
            packet_closest_hit(nodes, &r, again ? tmin : PFLOAT(0.0f), &th, &ph, &uh, &vh);
            const pint found = again & (ph != PRIM_MISS);
            const pint cut = k < MAX_CUTOUT_SKIPS ? cutout_lanes(tri_material, materials, tri_uv, textures, tex_data,
                                                                 found, ph, uh, vh, o, d) : PINT(0);
            blocked |= found & pnot(cut);
            tmin = cut ? th : tmin;
            again = cut;
        }
    }
#endif
#else
#if PACKET_WIDTH == 1
    if (rest) blocked = bvh_any_hit(nodes, tris, (float3)(o.x, o.y, o.z), (float3)(d.x, d.y, d.z), 0.0f, tmax);
#else
    if (pany(rest)) {
        const PacketRay r = packet_rays(o, d);
        blocked |= packet_any_hit(nodes, &r, PFLOAT(0.0f), rest ? tmax : PFLOAT(-1.0f));
    }
#endif
#endif
#endif
#ifdef HAS_INSTANCES
    blocked |= instance_lanes_occluded(INSTANCE_ARGS_NOCOMMA, tris, o, d, live & pnot(blocked), tmax
                                       SCENE_TIME_ARG(time));
#endif
    return blocked & live;
}

/* The hit point and a bound on its rounding error per coordinate.  Triangles interpolate the
 * vertices with the hit's barycentrics (error: a few ulps of the vertices, pbrt's bound), not
 * o + t*d, whose error is a few ulps of |o| + t|d|: that can exceed the spawn offset near a
 * coordinate plane far from the ray's origin, so rays would re-hit their own surface (the bias
 * this caused is described in docs/CONVERGENCE.md).
 * Analytic shapes bound their own (cl/shapes/<name>.h). */

/* The mesh that shading reads (the BVH keeps its own copies of the triangles for traversal: tris
 * in the binary layout, the packets of the wide ones): the scene's vertices (3 floats each) and
 * faces (3 vertex indices each), and the face of each reordered triangle. */
#define MESH_PARAMS __global const float *vertices, __global const int *faces, __global const int *prim_ids
#define MESH_ARGS vertices, faces, prim_ids

/* Gathers of the lanes' primitives (every index valid): vertex k of triangle prim. */
RT_INLINE pvec3 tri_vertex(MESH_PARAMS, pint prim, int k)
{
    return pv3_gather(vertices, pgather_int(faces, pgather_int(prim_ids, prim) * 3 + k) * 3);
}

/* Per lane: triangles (prim >= 0) and (HAS_SHAPES) analytic shapes; lanes of neither (PRIM_MISS) get 0. */
RT_INLINE pvec3 hit_point(MESH_PARAMS, __global const Shape *shapes, pint prim,
                          pvec3 o, pvec3 d, pfloat t, pfloat u, pfloat v, pvec3 *err)
{
    pvec3 p = pv3_zero();
    *err = pv3_zero();
    const pint tri = prim >= 0;
    if (pany(tri)) {
        const pint i = tri ? prim : PINT(0);
        p = triangle_point(tri_vertex(MESH_ARGS, i, 0), tri_vertex(MESH_ARGS, i, 1), tri_vertex(MESH_ARGS, i, 2), u, v, err);
    }
#ifdef HAS_SHAPES
    shape_hit_point(shapes, prim, o, d, t, &p, err);
#endif
    return p;
}

/* Unit geometric normal at a hit (triangles: (v1-v0)x(v2-v0); shapes: their front side's), per lane
 * (`live`: the lanes whose normal counts, for pv3_normalize's fallback; lanes of neither kind get 0). */
RT_INLINE pvec3 hit_normal(MESH_PARAMS, __global const Shape *shapes, pint prim, pvec3 p, pint live)
{
    pvec3 n = pv3_zero();
    const pint tri = prim >= 0;
    if (pany(tri)) {
        const pint i = tri ? prim : PINT(0);
        const pvec3 p0 = tri_vertex(MESH_ARGS, i, 0);
        n = pv3_normalize(pv3_cross(pv3_sub(tri_vertex(MESH_ARGS, i, 1), p0), pv3_sub(tri_vertex(MESH_ARGS, i, 2), p0)), live & tri);
    }
#ifdef HAS_SHAPES
    shape_hit_normal(shapes, prim, p, &n);
#endif
    return n;
}

#endif
