/* Stage 3: shading of every active path at its new hit point.
 *
 *   emission   Le of an emitter hit by the path (or of the environment, HAS_ENVIRONMENT, when
 *              the path left the scene), weighted by MIS against light sampling
 *              (power heuristic; weight 1 for camera rays), or by 1 (INTEGRATOR 1, BSDF
 *              sampling only) or 0 after the first segment (INTEGRATOR 2, light sampling only);
 *   light      one light sample (picked by power with the alias table): its contribution,
 *              weighted by MIS (weight 1 for delta lights: point, directional), is queued with a
 *              shadow ray (not with INTEGRATOR 1); infinitely distant lights (directional,
 *              environment) get a shadow ray of length ls.far along their exact direction;
 *   BSDF       one BSDF sample continues the path; Russian roulette after rr_depth bounces
 *              keeps it with probability min(max(throughput), 0.95).  A delta (perfectly
 *              specular) sample stores path_pdf = 0, which marks the next segment like a camera
 *              ray: the emitter it hits gets MIS weight 1 (light sampling cannot find it).
 *              Materials with delta lobes only skip light sampling.
 *
 * max_depth counts path segments, as in Mitsuba: 1 shows emitters only, 2 adds direct
 * lighting; a negative value means no limit (Russian roulette ends paths).
 * n_items = active-queue length.
 */
#include "render/lights.h"
#ifdef HAS_TEXTURES
#include "scene/textures.h"
#endif
#ifdef HAS_AOVS
#include "render/aov.h"
#endif

/* random dimension of the BSDF's lobe choice (reflection or refraction, specular or diffuse);
 * the direction uses DIM_BSDF and DIM_BSDF + 1 */
#ifndef DIM_BSDF_LOBE
#define DIM_BSDF_LOBE 6
#endif

#ifndef INTEGRATOR
#define INTEGRATOR 0
#endif

RT_INLINE float max3(float3 v) { return fmax(v.x, fmax(v.y, v.z)); }

__kernel void wf_shade(WAVE_PARAMS)
{
    /* Queue pushes are gathered per work-group: each work-item leaves a flag in local memory,
     * work-item 0 turns the flags into offsets (a serial exclusive scan) and reserves room with
     * one global atomic per queue.  Three contended global atomics per path cost ~20% of this
     * stage on two CPU cores, and local atomics still cost a locked instruction each on PoCL
     * (15% in perf), while the scan is a short loop. */
    __local uchar group_flags[WAVE_LOCAL_SIZE];
    __local int group_offset[WAVE_LOCAL_SIZE], group_offset_shadow[WAVE_LOCAL_SIZE];
    __local int group_base[3];
    const int lid = get_local_id(0);

    const int i = get_global_id(0);
    const int active = i < n_items;
    const int slot = active ? queue_in[i] : 0;
    int alive = 0, queued_shadow = 0;
    if (active) {
        const int prim = hit_prim[slot];
        const int depth = path_depth[slot];
        const int pixel = path_pixel[slot];
        const uint pass = (uint)path_pass[slot];
        const SampleKey sk = sampler_key(seed, (uint)pixel, (uint)camera->width, pass);
        float3 beta = load3(throughput, slot);
        float3 L = load3(radiance, slot);

        if (prim != PRIM_MISS) {
            const float3 o = load3(ray_o, slot), d = load3(ray_d, slot);
            float3 p_err;
            const float3 p = hit_point(tris, spheres, prim, o, d, hit_t[slot], hit_u[slot], hit_v[slot], &p_err);
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
                mat_scratch[slot] = texture_material(m, textures, tex_data,
                                                     triangle_uv(tri_uv, prim, hit_u[slot], hit_v[slot]));
                m = mat_scratch + slot;
            }
    #endif
    #ifdef HAS_AOVS
            aov_hit(aov_path, slot, depth, m, n, wo, p, hit_t[slot], beta);
    #endif
            const uint dim = 2 + DIMS_PER_BOUNCE * (uint)depth;

            /* -- emission seen by the path -------------------------------------------------- */
            const float3 Le = emitted(m, ng, wo);
            if (max3(Le) > 0.0f) {
                float w = 1.0f;
                const float prev_pdf = path_pdf[slot];
    #if INTEGRATOR == 2
                if (prev_pdf > 0.0f) w = 0.0f;
    #elif INTEGRATOR == 0 && defined(HAS_LIGHTS)
                if (prev_pdf > 0.0f && light_index >= 0) {
                    __global const Light *lt = lights + light_index;
                    w = power_heuristic(prev_pdf, lt->pmf * light_pdf(spheres, lt, o, p, ng));
                }
    #endif
                L += beta * Le * w;
            }

            const int segments = depth + 1;
            if (max_depth < 0 || segments < max_depth) {
                /* -- next-event estimation ------------------------------------------------------ */
    #if defined(HAS_LIGHTS) && INTEGRATOR != 1
              if (bsdf_has_nondelta_lobes(m)) {
                /* The reference point is the spawn point on the viewer's side, not p itself: for an
                 * emitter whose own surface holds p (the inside of an emissive sphere), p is neither
                 * inside nor outside it.  It is also the origin that a BSDF-sampled ray leaves from,
                 * so light_pdf() at a BSDF hit sees the same point. */
                const float3 ref = offset_ray_origin_bound(p, p_err, n);
                float pick_pmf;
                const int li = sample_alias(lights, n_lights, sample_1d(sk, dim + DIM_LIGHT_PICK), &pick_pmf);
                LightSample ls;
                const float2 ul = sample_2d(sk, dim + DIM_LIGHT_POINT);
                int sampled = pick_pmf > 0.0f && light_sample_all(tris, spheres, materials, env_map, env_cdf, lights + li, ref, ul, &ls);
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
                        store3(sh_o, slot, so);
    #ifdef HAS_INFINITE_LIGHTS
                        store3(sh_d, slot, ls.far > 0.0f ? wi * ls.far : sp - so);
    #else
                        store3(sh_d, slot, sp - so);
    #endif
                        store3(sh_contrib, slot, beta * f * ls.Le * (w / lpdf));
                        queued_shadow = 1;
                    }
                }
              }
    #endif
                /* -- BSDF sampling continues the path -------------------------------------------- */
                float3 wi;
                float pdf;
                int delta;
                const float2 ud = sample_2d(sk, dim + DIM_BSDF);
                const float3 u = (float3)(ud.x, ud.y, sample_1d(sk, dim + DIM_BSDF_LOBE));
                const float3 weight = bsdf_sample(m, n, front, wo, u, &wi, &pdf, &delta);
                if ((pdf > 0.0f || delta) && max3(weight) > 0.0f) {
                    beta *= weight;
                    alive = 1;
                    float eta_scale = path_eta_scale[slot];
                    if (dot(wi, n) < 0.0f) { const float eta = dielectric_eta(m, front); eta_scale *= eta * eta; }
                    if (segments >= rr_depth) {
#ifdef RR_NO_ETA
                        const float q = fmin(max3(beta), 0.95f);
#else
                        const float q = fmin(max3(beta) * eta_scale, 0.95f);
#endif
                        if (sample_1d(sk, dim + DIM_RR) >= q) alive = 0;
                        else beta /= q;
                    }
                    if (alive) {
                        store3(ray_o, slot, offset_ray_origin_bound(p, p_err, dot(ng, wi) > 0.0f ? ng : -ng));
                        store3(ray_d, slot, wi);
                        store3(throughput, slot, beta);
                        path_pdf[slot] = delta ? 0.0f : pdf;
                        path_eta_scale[slot] = eta_scale;
                        path_depth[slot] = segments;
                    }
                }
            }
        }
    #ifdef HAS_ENVIRONMENT
        else {
            /* -- the environment seen by a path that left the scene, weighted as emission above */
            const float3 d = load3(ray_d, slot);
            __global const Light *lt = lights + ENV_LIGHT;
            const float3 Le = env_radiance(lt, env_map, d);
            if (max3(Le) > 0.0f) {
                float w = 1.0f;
                const float prev_pdf = path_pdf[slot];
        #if INTEGRATOR == 2
                if (prev_pdf > 0.0f) w = 0.0f;
        #elif INTEGRATOR == 0
                if (prev_pdf > 0.0f) w = power_heuristic(prev_pdf, lt->pmf * env_pdf(lt, env_cdf, d));
        #endif
                L += beta * Le * w;
            }
        }
    #endif
        store3(radiance, slot, L);
    } /* active */

    /* flags: bit 0 = active, bit 1 = alive (else terminated), bit 2 = shadow ray queued */
    group_flags[lid] = (uchar)(active | (alive << 1) | (queued_shadow << 2));
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) {
        int n_alive = 0, n_term = 0, n_shadow = 0;
        for (int k = 0; k < (int)get_local_size(0); ++k) {
            const uchar f = group_flags[k];
            group_offset[k] = (f & 2) ? n_alive : n_term;
            group_offset_shadow[k] = n_shadow;
            n_alive += (f & 3) == 3;
            n_term += (f & 3) == 1;
            n_shadow += (f >> 2) & 1;
        }
        /* COUNTER_QUEUE_OUT, COUNTER_SHADOW and COUNTER_TERM are counters[0..2] */
        group_base[COUNTER_QUEUE_OUT] = n_alive ? atomic_add(&counters[COUNTER_QUEUE_OUT], n_alive) : 0;
        group_base[COUNTER_TERM] = n_term ? atomic_add(&counters[COUNTER_TERM], n_term) : 0;
        group_base[COUNTER_SHADOW] = n_shadow ? atomic_add(&counters[COUNTER_SHADOW], n_shadow) : 0;
    }
    barrier(CLK_LOCAL_MEM_FENCE);
    if (active) {
        if (alive) queue_out[group_base[COUNTER_QUEUE_OUT] + group_offset[lid]] = slot;
        else term_q[group_base[COUNTER_TERM] + group_offset[lid]] = slot;
    }
    if (queued_shadow) shadow_q[group_base[COUNTER_SHADOW] + group_offset_shadow[lid]] = slot;
}
