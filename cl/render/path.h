/* One path's integrator, shared by both schedules: the wavefront's generate and shade stages
 * (cl/wavefront/) and the megakernel (cl/megakernel/path.cl) call these same functions, so the
 * two compute the same samples with the same random numbers, and their images are equal bit for
 * bit.  Only where the state lives differs: structure-of-arrays buffers between stages, or
 * registers.
 *
 *   camera_ray      the camera ray of (pixel, pass): box-filtered pixel jitter, thin lens
 *   path_emission   Le of an emitter hit by the path (or of the environment, HAS_ENVIRONMENT,
 *                   when it left the scene), weighted by MIS against light sampling (power
 *                   heuristic; weight 1 for camera rays), or by 1 (INTEGRATOR 1, BSDF sampling
 *                   only) or 0 after the first segment (INTEGRATOR 2, light sampling only)
 *   path_shade_hit  at a hit: its emission; one light sample (picked by power with the alias
 *                   table) whose contribution, weighted by MIS (weight 1 for delta lights), comes
 *                   back with its shadow ray (not with INTEGRATOR 1; infinitely distant lights get
 *                   a shadow ray of length ls.far along their exact direction); one BSDF sample
 *                   that continues the path, with Russian roulette after rr_depth bounces keeping
 *                   it with probability min(max(throughput) * eta_scale, 0.95) (eta_scale: the
 *                   product of eta^2 over the refractions so far, so that radiance compressed by
 *                   refraction is not rouletted away; RR_NO_ETA drops it).  A delta (perfectly
 *                   specular) sample stores pdf = 0, which marks the next segment like a camera
 *                   ray: the emitter it hits gets MIS weight 1 (light sampling cannot find it).
 *                   Materials with delta lobes only skip light sampling.
 *
 * max_depth counts path segments, as in Mitsuba: 1 shows emitters only, 2 adds direct lighting;
 * a negative value means no limit (Russian roulette ends paths).
 *
 * PATH_ARGS passes the scene buffers of WAVE_PARAMS by their names: both schedules' kernels take
 * WAVE_PARAMS, so the names are in scope in either. */
#ifndef PYOPENCL_RT_PATH_H
#define PYOPENCL_RT_PATH_H

#include "render/lights.h"
#ifdef HAS_TEXTURES
#include "scene/textures.h"
#endif
#ifdef HAS_AOVS
#include "render/aov.h"
#endif

#ifndef INTEGRATOR
#define INTEGRATOR 0
#endif

RT_INLINE float max3(float3 v) { return fmax(v.x, fmax(v.y, v.z)); }

/* What a path carries from one vertex to the next. */
typedef struct {
    float3 o, d;     /* the ray that reaches the next vertex */
    float3 beta;     /* throughput */
    float3 L;        /* radiance gathered so far (unoccluded light samples are added by the caller) */
    float pdf;       /* solid-angle pdf of the BSDF sample that made d; 0 = camera or delta */
    float eta_scale; /* product of eta^2 over the refractions so far */
    int depth;       /* segments traced before this ray */
} PathState;

/* A light sample's shadow ray, from o to o + d (t in (0, 1)), and what it adds if unoccluded. */
typedef struct {
    float3 o, d, contribution;
} ShadowRay;

#define PATH_PARAMS                                                                                   \
    __global const float4 *tris, __global const Sphere *spheres, __global const int *tri_material,   \
    __global const int *tri_light, __global const int *sphere_material,                              \
    __global const int *sphere_light, __global const Material *materials,                            \
    __global const Light *lights, const int n_lights, __global const float *env_map,                 \
    __global const float *env_cdf, __global const float2 *tri_uv, __global const Texture *textures,  \
    __global const float4 *tex_data, __global Material *mat_scratch, __global float *aov_path,      \
    const int max_depth, const int rr_depth
#define PATH_ARGS                                                                                     \
    tris, spheres, tri_material, tri_light, sphere_material, sphere_light, materials, lights,          \
    n_lights, env_map, env_cdf, tri_uv, textures, tex_data, mat_scratch, aov_path, max_depth, rr_depth

RT_INLINE void camera_ray(__global const Camera *camera, SampleKey sk, int pixel, float3 *origin,
                          float3 *direction)
{
    const Camera cam = *camera;
    const int x = pixel % cam.width, y = pixel / cam.width;
    const float2 jitter = sample_2d(sk, DIM_PIXEL);
    const float sx = ((float)x + jitter.x) / (float)cam.width * 2.0f - 1.0f;
    const float sy = 1.0f - ((float)y + jitter.y) / (float)cam.height * 2.0f;
    const float3 dir = vload3(0, cam.forward) + sx * vload3(0, cam.right) + sy * vload3(0, cam.up);
    float3 d = normalize(dir), o = vload3(0, cam.origin);
    if (cam.lens_radius > 0.0f) {
        /* thin lens: from a point of the lens disk (concentric map, dims DIM_LENS and + 1)
         * through the point of the pinhole ray at distance focus_distance along forward;
         * lens_radius 0 is the pinhole, bit for bit */
        const float2 l = cam.lens_radius * sample_concentric_disk(sample_2d(sk, DIM_LENS));
        const float3 lens = l.x * normalize(vload3(0, cam.right)) + l.y * normalize(vload3(0, cam.up));
        d = normalize(cam.focus_distance * dir - lens);
        o += lens;
    }
    *origin = o;
    *direction = d;
}

RT_INLINE PathState path_start(float3 o, float3 d)
{
    PathState s;
    s.o = o;
    s.d = d;
    s.beta = (float3)(1.0f);
    s.L = (float3)(0.0f);
    s.pdf = 0.0f;
    s.eta_scale = 1.0f;
    s.depth = 0;
    return s;
}

#ifdef HAS_ENVIRONMENT
/* The environment seen by a path that left the scene, weighted as emission at a hit. */
RT_INLINE void path_escape(__global const Light *lights, __global const float *env_map,
                           __global const float *env_cdf, PathState *s)
{
    __global const Light *lt = lights + ENV_LIGHT;
    const float3 Le = env_radiance(lt, env_map, s->d);
    if (max3(Le) > 0.0f) {
        float w = 1.0f;
#if INTEGRATOR == 2
        if (s->pdf > 0.0f) w = 0.0f;
#elif INTEGRATOR == 0
        if (s->pdf > 0.0f) w = power_heuristic(s->pdf, lt->pmf * env_pdf(lt, env_cdf, s->d));
#endif
        s->L += s->beta * Le * w;
    }
}
#endif

/* Shade the hit (prim, t, u, v) of the path's ray.  Returns bit 0 set when the path goes on (s
 * then holds its next ray) and bit 1 set when *shadow holds a light sample to test.  `slot`
 * indexes this path's mat_scratch and AOV entries. */
RT_INLINE int path_shade_hit(PATH_PARAMS, int slot, SampleKey sk, int prim, float t, float u, float v,
                             PathState *s, ShadowRay *shadow)
{
    int result = 0;
    const float3 o = s->o, d = s->d;
    float3 p_err;
    const float3 p = hit_point(tris, spheres, prim, o, d, t, u, v, &p_err);
    const float3 ng = hit_normal(tris, spheres, prim, p);
    const float3 wo = -d;
    const int front = dot(ng, wo) >= 0.0f; /* the viewer is outside (dielectrics) */
    const float3 n = front ? ng : -ng;      /* normal on the viewer's side */
    int mat_index, light_index;
#ifdef HAS_SPHERES
    if (IS_SPHERE(prim)) {
        mat_index = sphere_material[SPHERE_INDEX(prim)];
        light_index = sphere_light[SPHERE_INDEX(prim)];
    } else
#endif
    {
        mat_index = tri_material[prim];
        light_index = tri_light[prim];
    }
    __global const Material *m = materials + mat_index;
#ifdef HAS_TEXTURES
    /* textured material: shade with its effective copy in this path's scratch slot */
    if (!IS_SPHERE(prim) && material_has_textures(m)) {
        mat_scratch[slot] = texture_material(m, textures, tex_data, triangle_uv(tri_uv, prim, u, v));
        m = mat_scratch + slot;
    }
#endif
#ifdef HAS_AOVS
    aov_hit(aov_path, slot, s->depth, m, n, wo, p, t, s->beta);
#endif
    const uint dim = 2 + DIMS_PER_BOUNCE * (uint)s->depth;

    /* -- emission seen by the path ---------------------------------------------------------- */
    const float3 Le = emitted(m, ng, wo);
    if (max3(Le) > 0.0f) {
        float w = 1.0f;
#if INTEGRATOR == 2
        if (s->pdf > 0.0f) w = 0.0f;
#elif INTEGRATOR == 0 && defined(HAS_LIGHTS)
        if (s->pdf > 0.0f && light_index >= 0) {
            __global const Light *lt = lights + light_index;
            w = power_heuristic(s->pdf, lt->pmf * light_pdf(spheres, lt, o, p, ng));
        }
#endif
        s->L += s->beta * Le * w;
    }

    const int segments = s->depth + 1;
    if (max_depth >= 0 && segments >= max_depth) return 0;
    /* the bounce's samples, all at once (sample_bounce: lane j is id dim + j) */
    const float8 su = sample_bounce(sk, dim);
#if DIM_LIGHT_PICK != 0 || DIM_LIGHT_POINT != 1 || DIM_BSDF != 3 || DIM_RR != 5 || DIM_BSDF_LOBE != 6
#error "path_shade_hit reads sample_bounce's lanes by the DIM_* layout of cl/render/sampler.h"
#endif

    /* The spawn point on the viewer's side: the reference point of light sampling, not p
     * itself (for an emitter whose own surface holds p, the inside of an emissive sphere, p is
     * neither inside nor outside it), and the origin of a BSDF sample that leaves on that side,
     * so light_pdf() at a BSDF hit sees the same point.  Computed once for both. */
    const float3 ref = offset_ray_origin_bound(p, p_err, n);

    /* -- next-event estimation -------------------------------------------------------------- */
#if defined(HAS_LIGHTS) && INTEGRATOR != 1
    if (bsdf_has_nondelta_lobes(m)) {
        float pick_pmf;
        const int li = sample_alias(lights, n_lights, su.s0, &pick_pmf);
        const float2 ul = su.s12;
        LightSample ls;
        const int sampled = pick_pmf > 0.0f &&
                            light_sample_all(tris, spheres, materials, env_map, env_cdf, lights + li, ref, ul, &ls);
#ifdef HAS_TEXTURES
        if (sampled) texture_light_emission(tri_uv, textures, tex_data, materials, lights + li, ul, &ls);
#endif
        if (sampled && ls.pdf > 0.0f && max3(ls.Le) > 0.0f) {
            float3 wi = ls.p - ref;
            float dist = length(wi);
            wi /= dist;
#ifdef HAS_INFINITE_LIGHTS
            if (ls.far > 0.0f) { wi = ls.n; dist = ls.far; } /* exact direction, far end */
#endif
            float bpdf;
            const float3 f = bsdf_eval(m, n, front, wo, wi, &bpdf);
            if (max3(f) > 0.0f && dist > 0.0f) {
                const float lpdf = pick_pmf * ls.pdf;
#if INTEGRATOR == 0
                const float w = ls.delta ? 1.0f : power_heuristic(lpdf, bpdf);
#else
                const float w = 1.0f;
#endif
                const float3 so = dot(n, wi) > 0.0f ? ref : offset_ray_origin_bound(p, p_err, -n);
                const float3 sp = offset_ray_origin_bound(ls.p, ls.err, ls.n);
                shadow->o = so;
#ifdef HAS_INFINITE_LIGHTS
                shadow->d = ls.far > 0.0f ? wi * ls.far : sp - so;
#else
                shadow->d = sp - so;
#endif
                shadow->contribution = s->beta * f * ls.Le * (w / lpdf);
                result |= 2;
            }
        }
    }
#endif
    /* -- BSDF sampling continues the path ---------------------------------------------------- */
    float3 wi;
    float pdf;
    int delta;
    const float3 lobe_u = (float3)(su.s3, su.s4, su.s6);
    const float3 weight = bsdf_sample(m, n, front, wo, lobe_u, &wi, &pdf, &delta);
    if (!((pdf > 0.0f || delta) && max3(weight) > 0.0f)) return result;
    const float3 beta = s->beta * weight;
    float eta_scale = s->eta_scale;
    if (dot(wi, n) < 0.0f) { const float eta = dielectric_eta(m, front); eta_scale *= eta * eta; }
    float q = 1.0f;
    if (segments >= rr_depth) {
#ifdef RR_NO_ETA
        q = fmin(max3(beta), 0.95f);
#else
        q = fmin(max3(beta) * eta_scale, 0.95f);
#endif
        if (su.s5 >= q) return result;
    }
    s->beta = segments >= rr_depth ? beta / q : beta;
    /* off the side wi leaves to: ng's if dot(ng, wi) > 0, else -ng's; that is n's (ref) when
     * it agrees with front */
    s->o = (dot(ng, wi) > 0.0f) == front ? ref : offset_ray_origin_bound(p, p_err, -n);
    s->d = wi;
    s->pdf = delta ? 0.0f : pdf;
    s->eta_scale = eta_scale;
    s->depth = segments;
    return result | 1;
}

#endif
