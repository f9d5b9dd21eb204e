/* The path integrator, written once over the lanes of cl/render/lanes.h: PACKET_WIDTH paths at a
 * time, each lane computing exactly what the others compute for their own paths.  Every schedule
 * compiles it: the wavefront's generate and shade stages (cl/wavefront/, width 1, on every
 * device), the one-path megakernel (width 1) and the lane megakernel (width 8 or 16 on x86 CPUs,
 * cl/megakernel/path.cl).  The same samples, the same random numbers and the same arithmetic in
 * every lane, so every width and schedule renders the same image, bit for bit (but where the
 * packet traversal reports the other of two triangles at exactly the same distance:
 * tests/render/test_path_lanes.py).  Divergence is handled with masks: a material is evaluated
 * over the lanes that hit it (cl/materials/dispatch.h), a light over the lanes that picked it
 * (cl/render/lights.h); what has no lane form (texture fetches, the double-precision plane test
 * near a light) runs lane by lane; sin, cos, atan2 and acos are inline (render/lanes_math.h).
 *
 *   camera_ray      the camera rays of (pixel, pass): the pixel filter's offset (filter.h) and
 *                   the sample's weight, perspective or orthographic, thin lens
 *   path_escape     (HAS_ENVIRONMENT) the environment seen by the lanes whose rays left the
 *                   scene, weighted as the emission of a hit
 *   path_shade      at the lanes' hits: their emission, weighted by MIS against light sampling
 *                   (power heuristic; weight 1 for camera rays), or by 1 (integrator 1, BSDF
 *                   sampling only) or 0 after the first segment (integrator 2, light sampling
 *                   only); one light sample each (picked by power with the alias table, or by
 *                   importance with the light BVH: LIGHT_TREE, render/light_tree.h) whose
 *                   contribution, weighted by MIS (weight 1 for delta lights), comes back with
 *                   its shadow ray (not with integrator 1; infinitely distant lights get a shadow
 *                   ray of length ls.far along their exact direction); one BSDF sample that
 *                   continues the path, with Russian roulette after rr_depth bounces keeping it
 *                   with probability min(max(throughput) * eta_scale, 0.95) (eta_scale: the
 *                   product of eta^2 over the refractions so far, so that radiance compressed by
 *                   refraction is not rouletted away; RR_NO_ETA drops it).  A delta (perfectly
 *                   specular) sample stores pdf = 0, which marks the next segment like a camera
 *                   ray: the emitter it hits gets MIS weight 1 (light sampling cannot find it).
 *                   Materials with delta lobes only skip light sampling.
 *
 * max_depth counts path segments, as in Mitsuba: 1 shows emitters only, 2 adds direct lighting;
 * a negative value means no limit (Russian roulette ends paths).
 *
 * PATH_ARGS passes the scene buffers of WAVE_PARAMS by their names: every schedule's kernels take
 * WAVE_PARAMS, so the names are in scope in each. */
#ifndef PYOPENCL_RT_PATH_H
#define PYOPENCL_RT_PATH_H

#include "render/lights.h"
#include "render/filter.h"
#include "accel/motion.h"
#ifdef LIGHT_TREE
#include "render/light_tree.h"
/* whether this scene's lights have a tree: the kernels' light_tree where LIGHT_TREE_RUNTIME compiles
 * the tree in for every scene (PYOPENCL_RT_KERNEL_FEATURES=all), else always (LIGHT_TREE is the scene's) */
#ifdef LIGHT_TREE_RUNTIME
#define LIGHT_TREE_ON (light_tree != 0)
#else
#define LIGHT_TREE_ON 1
#endif
#endif
#ifdef HAS_TEXTURES
#include "scene/textures.h"
#include "scene/texture_lights.h"
#endif
#include "scene/shading.h"
#include "materials/mix.h"
#ifdef HAS_AOVS
#include "render/aov.h"
#endif

/* The estimator is a kernel argument (`integrator`, as max_depth: one build serves the three):
 * INTEGRATOR_MIS, INTEGRATOR_BSDF (BSDF sampling only) or INTEGRATOR_NEE (light sampling only). */

/* What a path carries from one vertex to the next, per lane. */
typedef struct {
    pvec3 o, d;      /* the ray that reaches the next vertex */
    pvec3 beta;      /* throughput */
    pvec3 L;         /* radiance gathered so far (unoccluded light samples are added by the caller) */
    pfloat pdf;      /* solid-angle pdf of the BSDF sample that made d; 0 = camera or delta */
    pfloat eta_scale; /* product of eta^2 over the refractions so far */
    pint depth;      /* segments traced before this ray */
#ifdef LIGHT_TREE
    pvec3 nref;      /* the normal at the vertex that sampled d (0 in a medium): the light BVH's pmf at its hit */
#endif
#ifdef HAS_MEDIA
    pvec3 ref;       /* the last scattering vertex (light_pdf's reference point; o after a null crossing is not) */
    pvec3 r;         /* spectral-MIS ratios p_k / p_hero, mean 1 (cl/render/volpath.h) */
    pint medium;     /* the medium the ray is in, MEDIUM_VACUUM if none */
    pint channel;    /* the hero channel its distances are sampled with */
    puint rng;       /* its tracking stream (cl/render/media.h, medium_uniform) */
#endif
} PathState;

/* A light sample's shadow ray, from o to o + d (t in (0, 1)), and what it adds if unoccluded. */
typedef struct {
    pvec3 o, d, contribution;
} ShadowRay;

#define PATH_PARAMS                                                                                   \
    MESH_PARAMS, __global const Shape *shapes, __global const int *tri_material,                    \
    __global const int *tri_light, __global const int *shape_material,                              \
    __global const int *shape_light, __global const Material *materials,                            \
    __global const Light *lights, __global const LightNode *light_nodes, const int n_lights,         \
    const int light_tree,                                                                            \
    __global const float *env_map,                                                                   \
    __global const float *env_cdf, __global const float2 *tri_uv, __global const Texture *textures,  \
    __global const float4 *tex_data, __global const float *face_normal, __global const float *tri_color, \
    __global float *aov_path, const int max_depth, const int rr_depth, const int integrator PATH_INSTANCES
#define PATH_ARGS                                                                                     \
    MESH_ARGS, shapes, tri_material, tri_light, shape_material, shape_light, materials, lights,     \
    light_nodes, n_lights, light_tree, env_map, env_cdf, tri_uv, textures, tex_data, face_normal, tri_color, aov_path, max_depth, \
    rr_depth, integrator PATH_INSTANCES_ARGS
#if defined(HAS_INSTANCES) && defined(HAS_MOTION)
#define PATH_INSTANCES , __global const Instance *instances, __global const Motion *instance_motion
#define PATH_INSTANCES_ARGS , instances, instance_motion
#elif defined(HAS_INSTANCES)
#define PATH_INSTANCES , __global const Instance *instances
#define PATH_INSTANCES_ARGS , instances
#else
#define PATH_INSTANCES
#define PATH_INSTANCES_ARGS
#endif

/* A moving camera (HAS_CAMERA_MOTION; pbrt-v4's ActiveTransform before Camera): its way from its
 * frame at the start to the end (camera_motion, abi.MOTION), along which each camera ray moves by
 * M(s) M(0)^-1 at its path's time sample (the camera record is the frame at the start). */
#ifdef HAS_CAMERA_MOTION
#define CAMERA_MOTION_PARAM , __global const Motion *camera_motion
#define CAMERA_MOTION_ARG , camera_motion

RT_INLINE void camera_moved(__global const Motion *way, SampleKey k, pint live, pvec3 *o, pvec3 *d)
{
    if (way->time[1] == 0.0f) return; /* a camera that stays (every-feature programs compile this in) */
    const pfloat u = time_sample(k);
    float m0[12], w0[12];
    motion_matrices_at(way, 0.0f, m0, w0);
    for (int l = 0; l < PACKET_WIDTH; ++l) {
        if (!PLANE_I(live, l)) continue;
        float m[12], w[12];
        motion_matrices(way, PLANE(u, l), m, w);
        const float3 p = xf_point_private(m, xf_point_private(w0, pv3_lane(*o, l)));
        float3 v = xf_vector_private(m, xf_vector_private(w0, pv3_lane(*d, l)));
        v *= 1.0f / sqrt(v.x * v.x + v.y * v.y + v.z * v.z);
        PLANE(o->x, l) = p.x; PLANE(o->y, l) = p.y; PLANE(o->z, l) = p.z;
        PLANE(d->x, l) = v.x; PLANE(d->y, l) = v.y; PLANE(d->z, l) = v.z;
    }
}
#else
#define CAMERA_MOTION_PARAM
#define CAMERA_MOTION_ARG
#endif

/* The camera rays through pixels (x, y) of the lanes, and the weight each sample carries (the
 * pixel filter's sign and normalisation, cl/render/filter.h; 1 for filters without negative
 * lobes). */
RT_INLINE void camera_ray(__global const Camera *camera, __global const float *filter_cdf, SampleKey k, pint x,
                          pint y, pint live, pvec3 *origin, pvec3 *direction, pfloat *weight CAMERA_MOTION_PARAM)
{
    const Camera cam = *camera;
    pfloat ux, uy;
    pint negative_x, negative_y;
    sample_2d(k, PUINT(DIM_PIXEL), &ux, &uy);
#ifdef AUDIT_INDEPENDENT_PIXEL /* variance audits only (tools/glass_env_samplers.py): the pixel jitter unstratified */
    ux = rng_uniform(k.a, k.b, k.c, PUINT(DIM_PIXEL));
    uy = rng_uniform(k.a, k.b, k.c, PUINT(DIM_PIXEL + 1));
#endif
    const pfloat jx = filter_jitter(&cam, filter_cdf, 0, ux, &negative_x);
    const pfloat jy = filter_jitter(&cam, filter_cdf, 1, uy, &negative_y);
    *weight = filter_weight(&cam, negative_x, negative_y);
    const pfloat sx = (convert_pfloat(x) + jx) / (float)cam.width * 2.0f - 1.0f;
    const pfloat sy = 1.0f - (convert_pfloat(y) + jy) / (float)cam.height * 2.0f;
    const float3 forward = vload3(0, cam.forward), right = vload3(0, cam.right), up = vload3(0, cam.up);
    pvec3 dir, d, o = pv3_splat(vload3(0, cam.origin));
    if (cam.projection == PROJECTION_ORTHOGRAPHIC) {
        /* parallel rays from the film's points */
        dir = pv3_splat(forward);
        d = pv3_normalize(dir, live);
        o = pv3_add(pv3_add(o, pv3_scale(pv3_splat(right), sx)), pv3_scale(pv3_splat(up), sy));
    } else {
        dir = pv3_add(pv3_add(pv3_splat(forward), pv3_scale(pv3_splat(right), sx)), pv3_scale(pv3_splat(up), sy));
        d = pv3_normalize(dir, live);
    }
    if (cam.lens_radius > 0.0f) {
        /* thin lens: from a point of the lens disk (concentric map, dims DIM_LENS and + 1)
         * through the point of the pinhole ray at distance focus_distance along forward (dir:
         * forward at unit distance); lens_radius 0 is the pinhole, bit for bit */
        pfloat lx, ly, dx, dy;
        sample_2d(k, PUINT(DIM_LENS), &lx, &ly);
        sample_concentric_disk(lx, ly, &dx, &dy);
        const pvec3 lens = pv3_add(pv3_scale(pv3_splat(normalize(right)), cam.lens_radius * dx),
                                   pv3_scale(pv3_splat(normalize(up)), cam.lens_radius * dy));
        d = pv3_normalize(pv3_sub(pv3_scale(dir, PFLOAT(cam.focus_distance)), lens), live);
        o = pv3_add(o, lens);
    }
#ifdef HAS_CAMERA_MOTION
    camera_moved(camera_motion, k, live, &o, &d);
#endif
    *origin = o;
    *direction = d;
}

/* The lanes of `m` start new paths along (o, d). */
RT_INLINE void path_start(PathState *s, pint m, pvec3 o, pvec3 d)
{
    s->o = pv3_sel(s->o, o, m);
    s->d = pv3_sel(s->d, d, m);
    s->beta = pv3_sel(s->beta, pv3_splat((float3)(1.0f)), m);
    s->L = pv3_sel(s->L, pv3_zero(), m);
    s->pdf = m ? PFLOAT(0.0f) : s->pdf;
    s->eta_scale = m ? PFLOAT(1.0f) : s->eta_scale;
    s->depth = m ? PINT(0) : s->depth;
#ifdef LIGHT_TREE
    s->nref = pv3_sel(s->nref, pv3_zero(), m);
#endif
}

#ifdef HAS_ENVIRONMENT
/* The environment seen by the lanes of `missed`, whose rays left the scene. */
RT_INLINE void path_escape(__global const Light *lights, int env_light, __global const float *env_map,
                           __global const float *env_cdf, int integrator, pint missed, PathState *s)
{
    if (env_light < 0) return; /* compiled in, but this scene has no environment */
    __global const Light *lt = lights + env_light;
    const pvec3 Le = env_radiance(lt, env_map, s->d);
    const pint seen = missed & (pv3_max3(Le) > 0.0f);
    if (!pany(seen)) return;
    pfloat w = PFLOAT(1.0f);
    if (integrator == INTEGRATOR_NEE) {
        w = s->pdf > 0.0f ? PFLOAT(0.0f) : w;
    } else if (integrator == INTEGRATOR_MIS) {
        const pint mis = seen & (s->pdf > 0.0f);
        if (pany(mis)) w = mis ? power_heuristic(s->pdf, lt->pmf * env_pdf(lt, env_map, env_cdf, s->d)) : w;
    }
    s->L = pv3_sel(s->L, pv3_add(s->L, pv3_scale(pv3_mul(s->beta, Le), w)), seen);
}
#endif

/* The material and emitter of the lanes' primitives (index valid in every lane). */
RT_INLINE void hit_records(__global const int *tri_material, __global const int *tri_light,
                           __global const int *shape_material, __global const int *shape_light, pint prim,
                           pint *mat_index, pint *light_index)
{
#if defined(HAS_SHAPES) && defined(HAS_TRIANGLES)
    const pint shape = IS_SHAPE(prim);
    const pint si = shape ? SHAPE_INDEX(prim) : PINT(0), ti = shape ? PINT(0) : prim;
    *mat_index = shape ? pgather_int(shape_material, si) : pgather_int(tri_material, ti);
    *light_index = shape ? pgather_int(shape_light, si) : pgather_int(tri_light, ti);
#elif defined(HAS_SHAPES)
    *mat_index = pgather_int(shape_material, SHAPE_INDEX(prim));
    *light_index = pgather_int(shape_light, SHAPE_INDEX(prim));
#else
    *mat_index = pgather_int(tri_material, prim);
    *light_index = pgather_int(tri_light, prim);
#endif
}

/* A primitive every lane may gather from (the lanes that hit nothing shade it and discard it). */
#ifdef HAS_TRIANGLES
#define ANY_PRIM 0
#else
#define ANY_PRIM SHAPE_PRIM(0)
#endif

#ifdef HAS_LIGHTS
/* the most lights whose pick reuses the light point's sample (below): 16 bits are left for it */
#define ALIAS_REUSE_MAX_LIGHTS 256

/* The MIS weight of a light sample of density lpdf against the BSDF's or phase function's density
 * `other` for the same direction: the power heuristic, 1 for delta lights and without MIS. */
RT_INLINE pfloat nee_mis_weight(int integrator, pint delta, pfloat lpdf, pfloat other)
{
    if (integrator != INTEGRATOR_MIS) return PFLOAT(1.0f);
    return delta ? PFLOAT(1.0f) : power_heuristic(lpdf, other);
}

/* The probability that next-event estimation from `from` (normal nref) picks light li, the one a
 * BSDF sample hit (the lanes of `mis`; li valid in every lane): its alias table's pmf, times with
 * the light BVH the descent's probability. */
RT_INLINE pfloat light_pick_pmf(__global const Light *lights, __global const LightNode *light_nodes, pint mis,
                                pint li, pvec3 from, pvec3 nref)
{
    pfloat pmf = pgather((__global const float *)lights, li * STRIDE_INDEX(Light) + FIELD_INDEX(Light, pmf));
#ifdef LIGHT_TREE
    const pint trail = pgather_int((__global const int *)lights, li * STRIDE_INDEX(Light) + FIELD_INDEX(Light, trail));
    const pint in_tree = mis & (trail >= 0);
    if (pany(in_tree)) pmf = in_tree ? pmf * light_tree_pmf(light_nodes, in_tree ? trail : PINT(-1), from, nref) : pmf;
#endif
    return pmf;
}

/* Next-event estimation's light sample from ref (a surface's spawn point or a medium's scattering
 * point; nref its normal, 0 in a medium) in the lanes of `active`: a light picked by power, or with
 * the light BVH by importance to (ref, nref) (*pick_pmf) and a point on it (*ls, its texture's
 * emission included).  Returns the lanes with a sample of positive density and radiance; there
 * *wi is the unit direction toward it and *dist its distance (for an infinitely far light the
 * exact direction and the far end). */
/* RT_NEE_NOINLINE (every-feature programs, render/settings.py): out of line, one copy for the surface
 * and the medium vertex: their cold build 35 -> 31 CPU s, with media 62 -> 39 s, the same bits; 5% fewer
 * samples/s on the Cornell box, so scene kernels keep it inline. */
#ifdef RT_NEE_NOINLINE
__attribute__((noinline))
#else
RT_INLINE
#endif
pint nee_light_sample(PATH_PARAMS, SampleKey key, puint dim, pint active, pvec3 ref, pvec3 nref,
                                LightSample *ls, pfloat *pick_pmf, pvec3 *wi, pfloat *dist)
{
    pfloat ulx, uly;
    sample_2d(key, dim + DIM_LIGHT_POINT, &ulx, &uly);
    pint li;
#ifdef LIGHT_TREE
    if (LIGHT_TREE_ON) {
        /* the alias table picks an infinitely far light or the tree (any row of it: the tree's
         * share, in each one's pmf), its remainder of u descends the tree; the point's sample is
         * its own */
        pfloat u_tree;
        li = sample_alias(lights, n_lights, sample_1d(key, dim + DIM_LIGHT_PICK), pick_pmf, &u_tree);
        const pint trail = pgather_int((__global const int *)lights, li * STRIDE_INDEX(Light) + FIELD_INDEX(Light, trail));
        const pint tree = active & (trail >= 0);
        if (pany(tree)) {
            pfloat tree_pmf;
            const pint picked = light_tree_sample(light_nodes, tree, ref, nref, u_tree, &tree_pmf);
            li = tree ? picked : li;
            *pick_pmf = tree ? *pick_pmf * tree_pmf : *pick_pmf;
        }
    } else
#endif
    {
        /* With few lights the light point's first coordinate also picks the light (Mitsuba's
         * sample_reuse), so that the pick and the point are stratified together: on the Cornell
         * box (its light two triangles) 2% less error per sample, and one 1D sample fewer.  With
         * many, its remainder would keep too few bits for the point: a 1D sample of its own picks. */
        if (n_lights <= ALIAS_REUSE_MAX_LIGHTS)
            li = sample_alias(lights, n_lights, ulx, pick_pmf, &ulx);
        else {
            pfloat unused;
            li = sample_alias(lights, n_lights, sample_1d(key, dim + DIM_LIGHT_PICK), pick_pmf, &unused);
        }
    }
    pint sampled = active & (*pick_pmf > 0.0f);
    sampled &= light_sample_all(MESH_ARGS, shapes, materials, env_map, env_cdf, lights, li, sampled, ref, ulx, uly, ls);
#ifdef HAS_TEXTURES
    texture_light_emission(tri_uv, textures, tex_data, materials, lights, li, sampled, ulx, uly, ls);
#endif
    sampled &= (ls->pdf > 0.0f) & (pv3_max3(ls->Le) > 0.0f);
    const pvec3 to = pv3_sub(ls->p, ref);
    const pfloat len = pv3_length(to, sampled);
    *wi = pv3_div(to, sampled ? len : PFLOAT(1.0f));
    *dist = len;
#ifdef HAS_INFINITE_LIGHTS
    const pint far = ls->far > 0.0f;
    *wi = pv3_sel(*wi, ls->n, far);
    *dist = far ? ls->far : *dist;
#endif
    return sampled;
}
#endif

/* Shades the hits (prim, t, u, v) of the lanes of `hit`.  Sets *goes_on to the lanes whose
 * paths go on (s then holds their next rays) and *with_shadow to those with a light sample to
 * test (*shadow).  Lanes outside `hit` keep their state.  `slot`: each lane's AOV entry. */
RT_INLINE void path_shade(PATH_PARAMS, pint slot, SampleKey key, pint hit, pint prim, pfloat t, pfloat u,
                          pfloat v, PathState *s, pint *goes_on, pint *with_shadow, ShadowRay *shadow
                          INSTANCE_SHADE_PARAMS)
{
    *goes_on = PINT(0);
    *with_shadow = PINT(0);
    shadow->o = shadow->d = shadow->contribution = pv3_zero(); /* defined in every lane */
    prim = hit ? prim : PINT(ANY_PRIM);
    const pvec3 o = s->o, d = s->d;
    pvec3 p_err;
    pvec3 p = hit_point(MESH_ARGS, shapes, prim, o, d, t, u, v, &p_err);
    pvec3 ng = hit_normal(MESH_ARGS, shapes, prim, p, hit);
    const pvec3 wo = pv3_neg(d);
#ifdef HAS_INSTANCES
    /* a hit in an instance was found in its group's space: p (its error bound grown) and ng move
     * to the world here; the shading frame is found in the group's space (with wo moved there)
     * and its normal moved after, by M^-T (cl/accel/instances.h) */
    const pint in_inst = hit & (inst >= 0);
    const pint xi = in_inst ? inst : PINT(0);
    const pvec3 ng_obj = ng;
    pvec3 wo_obj = wo;
    LaneXf xf;
    if (pany(in_inst)) {
        xf = lane_xf(instances, xi, in_inst MOTION_LANES_ARG(time_sample(key)));
        wo_obj = pv3_sel(wo, xf_apply(xf.w2o, wo, PFLOAT(0.0f)), in_inst);
        instance_point_to_world(&xf, in_inst, &p, &p_err);
        ng = pv3_sel(ng, pv3_normalize(xf_normal(&xf, ng), in_inst), in_inst);
    }
#endif
    const pint front = pv3_dot(ng, wo) >= 0.0f; /* the viewer is outside (dielectrics) */
    const pvec3 n = pv3_sel(pv3_neg(ng), ng, front); /* normal on the viewer's side */
    pint mat_index, light_index;
    hit_records(tri_material, tri_light, shape_material, shape_light, prim, &mat_index, &light_index);
    const puint dim = convert_puint(2 + DIMS_PER_BOUNCE * s->depth);
#ifdef HAS_MATERIAL_MIX
    /* a mix is shaded as one of its materials, picked by its weight (cl/materials/mix.h) */
    const pint top_index = mat_index;
    pint mix_index;
    pfloat mix_w;
    mat_index = mix_sample(materials, tri_uv, textures, tex_data, tri_color, hit, prim, u, v,
                           sample_1d(key, dim + DIM_MIX), mat_index, &mix_index, &mix_w);
    MaterialLanes m = material_lanes(materials, mat_index);
    mix_keep_top(materials, tri_uv, textures, tex_data, top_index, mat_index, prim, u, v, &m);
    /* a mix of two materials that are not mixes: the other one, evaluated beside the picked one */
    const MixOther mo = mix_other(MESH_ARGS, face_normal, materials, tri_uv, textures, tex_data, tri_color, hit, prim, u, v,
                                  p, ng, n, front, wo, mix_index, mix_w);
#else
    MaterialLanes m = material_lanes(materials, mat_index);
#endif
#ifdef HAS_TEXTURES
    texture_material(tri_uv, textures, tex_data, hit & pnot(IS_SHAPE(prim)), prim, u, v, p, ng, &m);
#endif
#ifdef HAS_VERTEX_COLORS
    vertex_color_material(tri_color, hit, prim, u, v, &m);
#endif
    /* the BSDF's frame: the shading normal (interpolated, normal- or bump-mapped) on wo's side,
     * or n (cl/scene/shading.h) */
#ifdef HAS_INSTANCES
    ShadingLanes sh = shading_lanes(MESH_ARGS, face_normal, tri_uv, textures, tex_data, materials, mat_index, hit, prim, u,
                                    v, pv3_sel(ng, ng_obj, in_inst),
                                    pv3_sel(n, pv3_sel(pv3_neg(ng_obj), ng_obj, front), in_inst), front,
                                    pv3_sel(wo, wo_obj, in_inst), hit & ((m.flags & MATERIAL_FLAG_ANISOTROPIC) != 0));
    if (pany(in_inst)) { /* no maps nor anisotropy in instances (loaders/instancing.py): n alone moves */
        sh.n = pv3_sel(sh.n, pv3_normalize(xf_normal(&xf, sh.n), in_inst), in_inst);
#ifdef HAS_NORMAL_MAPS
        sh.base = pv3_sel(sh.base, sh.n, in_inst);
        sh.tilt = pv3_sel(sh.tilt, sh.n, in_inst);
#endif
    }
#else
    const ShadingLanes sh = shading_lanes(MESH_ARGS, face_normal, tri_uv, textures, tex_data, materials, mat_index, hit,
                                          prim, u, v, ng, n, front, wo,
                                          hit & ((m.flags & MATERIAL_FLAG_ANISOTROPIC) != 0));
#endif
    /* alpha cut-outs (MATERIAL_FLAG_MASK, Mitsuba's mask): the surface is met with probability
     * `opacity`; one-sided BSDFs (MATERIAL_FLAG_ONE_SIDED) reflect nothing seen from behind */
    const pint masked = hit & ((m.flags & MATERIAL_FLAG_MASK) != 0);
    const pfloat opacity = masked ? pclamp(m.opacity, 0.0f, 1.0f) : PFLOAT(1.0f);
    const pint surface = hit & pnot(((m.flags & MATERIAL_FLAG_ONE_SIDED) != 0) & pnot(sh.front));
#ifdef HAS_AOVS
    aov_hit(aov_path, slot, hit, s->depth, &m, sh.n, wo, p, t, s->beta);
#endif

    /* -- emission seen by the path ---------------------------------------------------------- */
    const pvec3 Le = emitted(&m, ng, wo);
    const pint glows = hit & (pv3_max3(Le) > 0.0f);
    if (pany(glows)) {
        pfloat w = PFLOAT(1.0f);
        if (integrator == INTEGRATOR_NEE) w = s->pdf > 0.0f ? PFLOAT(0.0f) : w;
#ifdef HAS_LIGHTS
        /* MIS against light sampling: light_pdf of the hit light, from the ray's origin */
        const pint mis = glows & (s->pdf > 0.0f) & (light_index >= 0);
        if (integrator == INTEGRATOR_MIS && pany(mis)) {
            const pint li = mis ? light_index : PINT(0);
#ifdef HAS_MEDIA
            const pvec3 from = s->ref; /* the last scattering vertex: null boundaries move o, not it */
#else
            const pvec3 from = o;
#endif
#ifdef LIGHT_TREE
            const pfloat pmf = light_pick_pmf(lights, light_nodes, mis, li, from, s->nref);
#else
            const pfloat pmf = light_pick_pmf(lights, light_nodes, mis, li, from, pv3_zero());
#endif
            w = mis ? power_heuristic(s->pdf, pmf * light_pdf(shapes, lights, li, from, p, ng)) : w;
        }
#endif
        s->L = pv3_sel(s->L, pv3_add(s->L, pv3_scale(pv3_mul(s->beta, Le), w)), glows);
    }

    const pint segments = s->depth + 1;
    const pint going = hit & (max_depth >= 0 ? segments < max_depth : PTRUE);
    if (!pany(going)) return;

    /* The spawn point on the viewer's side: the reference point of light sampling, not p
     * itself (for an emitter whose own surface holds p, the inside of an emissive sphere, p is
     * neither inside nor outside it), and the origin of a BSDF sample that leaves on that side,
     * so light_pdf() at a BSDF hit sees the same point; and the one on the other side. */
    const pvec3 ref = offset_ray_origin_bound(p, p_err, n);
    const pvec3 below = offset_ray_origin_bound(p, p_err, pv3_neg(n));

    /* -- next-event estimation -------------------------------------------------------------- */
#ifdef HAS_LIGHTS
    pint nee = going & surface & bsdf_has_nondelta_lobes(&m) & (opacity > 0.0f);
#ifdef HAS_MATERIAL_MIX
    nee |= going & mo.surface & bsdf_has_nondelta_lobes(&mo.m) & (opacity > 0.0f);
#endif
    /* n_lights: HAS_LIGHTS is compiled in for scenes without lights too (PYOPENCL_RT_KERNEL_FEATURES=all) */
    if (integrator != INTEGRATOR_BSDF && n_lights > 0 && pany(nee)) { /* (a scalar test: a lane mask is -1, not 1) */
        LightSample ls;
        pfloat pick_pmf, dist;
        pvec3 wi;
        const pint sampled = nee_light_sample(PATH_ARGS, key, dim, nee, ref, sh.n, &ls, &pick_pmf, &wi, &dist);
        if (pany(sampled)) {
            pfloat bpdf;
            pvec3 f = bsdf_eval(&m, sampled & surface, sh.n, sh.t, sh.front, wo, wi, &bpdf);
            f = shading_eval(&sh, wi, f, &bpdf);
#ifdef HAS_MATERIAL_MIX
            f = mix_blend_eval(&mo, sampled, f, wo, wi, &bpdf);
#endif
            if (pany(masked)) { /* Mitsuba's mask: the nested BSDF's f and pdf times the opacity */
                f = pv3_scale(f, opacity);
                bpdf *= opacity;
            }
            const pint lit = sampled & (pv3_max3(f) > 0.0f) & (dist > 0.0f);
            if (pany(lit)) {
                const pfloat lpdf = pick_pmf * ls.pdf;
                const pfloat w = nee_mis_weight(integrator, ls.delta, lpdf, bpdf);
                const pvec3 so = pv3_sel(below, ref, pv3_dot(n, wi) > 0.0f);
                const pvec3 sp = offset_ray_origin_bound(ls.p, ls.err, ls.n);
                shadow->o = so;
                shadow->d = pv3_sub(sp, so);
#ifdef HAS_INFINITE_LIGHTS
                shadow->d = pv3_sel(shadow->d, pv3_scale(wi, ls.far), ls.far > 0.0f);
#endif
                shadow->contribution = pv3_scale(pv3_mul(pv3_mul(s->beta, f), ls.Le), w / lpdf);
                *with_shadow = lit;
            }
        }
    }
#endif
    /* -- BSDF sampling continues the path ---------------------------------------------------- */
    pfloat ubx, uby, pdf;
    sample_2d(key, dim + DIM_BSDF, &ubx, &uby);
#ifdef AUDIT_INDEPENDENT_BSDF /* variance audits only (tools/glass_env_samplers.py): BSDF directions unstratified */
    ubx = rng_uniform(key.a, key.b, key.c, dim + DIM_BSDF);
    uby = rng_uniform(key.a, key.b, key.c, dim + DIM_BSDF + 1u);
#endif
    pfloat ulobe = sample_1d(key, dim + DIM_BSDF_LOBE);
#ifdef AUDIT_INDEPENDENT_LOBE /* variance audits only (tools/glass_env_samplers.py): the lobe choice unstratified */
    ulobe = rng_uniform(key.a, key.b, key.c, dim + DIM_BSDF_LOBE);
#endif
    /* a masked surface lets the path through with probability 1 - opacity (Mitsuba's mask: the
     * lobe sample u >= opacity; a null, delta bounce of weight 1 that counts as a segment), else
     * its nested BSDF samples with u / opacity and pdf times opacity */
    const pint passes = masked & (ulobe >= opacity);
    ulobe = masked & pnot(passes) ? ulobe / opacity : ulobe;
    pvec3 wi;
    pint delta;
    pvec3 weight = bsdf_sample(&m, going & surface & pnot(passes), sh.n, sh.t, sh.front, wo, ubx, uby, ulobe, &wi,
                               &pdf, &delta);
    weight = shading_sample(&sh, wi, weight, &pdf);
#ifdef HAS_MATERIAL_MIX
    weight = mix_blend_sample(&mo, &m, &sh, going & surface & pnot(passes), wo, wi, delta, weight, &pdf);
#endif
    if (pany(masked)) {
        pdf *= opacity;
        weight = pv3_sel(weight, pv3_splat((float3)(1.0f)), passes);
        wi = pv3_sel(wi, d, passes);
        pdf = passes ? PFLOAT(0.0f) : pdf;
        delta |= passes;
    }
    pint on = going & ((pdf > 0.0f) | delta) & (pv3_max3(weight) > 0.0f);
    if (!pany(on)) return;
    const pvec3 beta = pv3_mul(s->beta, weight);
    const pfloat eta = dielectric_eta(&m, sh.front);
    const pfloat eta_scale = (pv3_dot(wi, sh.n) < 0.0f) & pnot(passes) ? s->eta_scale * (eta * eta) : s->eta_scale;
    const pint roulette = segments >= rr_depth;
#ifdef RR_NO_ETA
    const pfloat q = pfmin(pv3_max3(beta), PFLOAT(0.95f));
#else
    const pfloat q = pfmin(pv3_max3(beta) * eta_scale, PFLOAT(0.95f));
#endif
    if (pany(roulette & on)) on &= pnot(roulette) | (sample_1d(key, dim + DIM_RR) < q);
    s->beta = pv3_sel(s->beta, pv3_sel(beta, pv3_div(beta, q), roulette), on);
    /* off the side wi leaves to: ng's if dot(ng, wi) > 0, else -ng's; that is n's (ref) when
     * it agrees with front */
    s->o = pv3_sel(s->o, pv3_sel(below, ref, (pv3_dot(ng, wi) > 0.0f) == front), on);
    s->d = pv3_sel(s->d, wi, on);
    s->pdf = on ? (delta ? PFLOAT(0.0f) : pdf) : s->pdf;
    s->eta_scale = on ? eta_scale : s->eta_scale;
    s->depth = on ? segments : s->depth;
#ifdef LIGHT_TREE
    s->nref = pv3_sel(s->nref, sh.n, on);
#endif
    *goes_on = on;
}

#endif
