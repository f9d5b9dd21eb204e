/* The megakernel: one work-item follows one sample's whole path (camera ray, every bounce,
 * every shadow ray) in registers, for CPU devices, where the wavefront's structure-of-arrays
 * round trips, queue compaction and five launches per bounce cost more than the divergence they
 * avoid (a CPU runs each work-item as scalar code either way).  It computes exactly what the
 * wavefront stages compute, in the same order, with the same random numbers, so its image is the
 * wavefront's bit for bit (tests/render/test_megakernel.py).
 *
 * Work-item i renders sample first_pixel + i of pass first_pass (wrapping into the next passes,
 * as wf_generate numbers them) and writes its radiance into that pass's buffer of the ring;
 * the host launches whole passes, so every pass is complete when the launch is.  The rays it
 * traces are counted in counters[COUNTER_RAYS_EXTEND] and [COUNTER_RAYS_SHADOW].
 * mat_scratch (textures) is indexed by work-item: n_items is at most the wave size. */
#include "render/lights.h"
#ifdef HAS_TEXTURES
#include "scene/textures.h"
#endif
#ifndef DIM_BSDF_LOBE
#define DIM_BSDF_LOBE 6
#endif
#ifndef INTEGRATOR
#define INTEGRATOR 0
#endif

RT_INLINE float mk_max3(float3 v) { return fmax(v.x, fmax(v.y, v.z)); }

__kernel void mk_path(WAVE_PARAMS)
{
    const int i = get_global_id(0);
    if (i >= n_items) return;
    const int linear = first_pixel + i;
    const int pass_i = first_pass + linear / n_pixels;
    const int pixel = linear % n_pixels;
    const uint pass = (uint)pass_i;
    const int slot = i;

    const Camera cam = *camera;
    const SampleKey sk = sampler_key(seed, (uint)pixel, (uint)cam.width, pass);
    const int x = pixel % cam.width, y = pixel / cam.width;
    const float2 jitter = sample_2d(sk, DIM_PIXEL);
    const float sx = ((float)x + jitter.x) / (float)cam.width * 2.0f - 1.0f;
    const float sy = 1.0f - ((float)y + jitter.y) / (float)cam.height * 2.0f;
    const float3 dir = vload3(0, cam.forward) + sx * vload3(0, cam.right) + sy * vload3(0, cam.up);
    float3 d = normalize(dir), o = vload3(0, cam.origin);
    if (cam.lens_radius > 0.0f) {
        const float2 l = cam.lens_radius * sample_concentric_disk(sample_2d(sk, DIM_LENS));
        const float3 lens = l.x * normalize(vload3(0, cam.right)) + l.y * normalize(vload3(0, cam.up));
        d = normalize(cam.focus_distance * dir - lens);
        o += lens;
    }
    float3 beta = (float3)(1.0f), L = (float3)(0.0f);
    float path_pdf_v = 0.0f; /* 0 = "specular/camera": emission seen directly gets full weight */
    float eta_scale = 1.0f;  /* product of eta^2 over the refractions so far */
    int depth = 0, n_extend = 0, n_shadow = 0;
    for (;;) {
        const Hit h = scene_closest_hit(nodes, tris, spheres, n_spheres, o, d, 0.0f, INFINITY);
        ++n_extend;
        const int prim = h.prim;
        int alive = 0;
        if (prim == PRIM_MISS) {
#ifdef HAS_ENVIRONMENT
            __global const Light *lt = lights + ENV_LIGHT;
            const float3 Le = env_radiance(lt, env_map, d);
            if (mk_max3(Le) > 0.0f) {
                float w = 1.0f;
#if INTEGRATOR == 2
                if (path_pdf_v > 0.0f) w = 0.0f;
#elif INTEGRATOR == 0
                if (path_pdf_v > 0.0f) w = power_heuristic(path_pdf_v, lt->pmf * env_pdf(lt, env_cdf, d));
#endif
                L += beta * Le * w;
            }
#endif
            break;
        }
        float3 p_err;
        const float3 p = hit_point(tris, spheres, prim, o, d, h.t, h.u, h.v, &p_err);
        const float3 ng = hit_normal(tris, spheres, prim, p);
        const float3 wo = -d;
        const int front = dot(ng, wo) >= 0.0f;
        const float3 n = front ? ng : -ng;
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
        if (!IS_SPHERE(prim) && material_has_textures(m)) {
            mat_scratch[slot] = texture_material(m, textures, tex_data, triangle_uv(tri_uv, prim, h.u, h.v));
            m = mat_scratch + slot;
        }
#endif
        const uint dim = 2 + DIMS_PER_BOUNCE * (uint)depth;
        const float3 Le = emitted(m, ng, wo);
        if (mk_max3(Le) > 0.0f) {
            float w = 1.0f;
#if INTEGRATOR == 2
            if (path_pdf_v > 0.0f) w = 0.0f;
#elif INTEGRATOR == 0 && defined(HAS_LIGHTS)
            if (path_pdf_v > 0.0f && light_index >= 0) {
                __global const Light *lt = lights + light_index;
                w = power_heuristic(path_pdf_v, lt->pmf * light_pdf(spheres, lt, o, p, ng));
            }
#endif
            L += beta * Le * w;
        }
        const int segments = depth + 1;
        if (!(max_depth < 0 || segments < max_depth)) break;
#if defined(HAS_LIGHTS) && INTEGRATOR != 1
        if (bsdf_has_nondelta_lobes(m)) {
            const float3 ref = offset_ray_origin_bound(p, p_err, n);
            float pick_pmf;
            const int li = sample_alias(lights, n_lights, sample_1d(sk, dim + DIM_LIGHT_PICK), &pick_pmf);
            LightSample ls;
            const float2 ul = sample_2d(sk, dim + DIM_LIGHT_POINT);
            int sampled = pick_pmf > 0.0f && light_sample_all(tris, spheres, materials, env_map, env_cdf, lights + li, ref, ul, &ls);
#ifdef HAS_TEXTURES
            if (sampled) texture_light_emission(tri_uv, textures, tex_data, materials, lights + li, ul, &ls);
#endif
            if (sampled && ls.pdf > 0.0f && mk_max3(ls.Le) > 0.0f) {
                float3 wi = ls.p - ref;
                float dist = length(wi);
                wi /= dist;
#ifdef HAS_INFINITE_LIGHTS
                if (ls.far > 0.0f) { wi = ls.n; dist = ls.far; }
#endif
                float bpdf;
                const float3 f = bsdf_eval(m, n, front, wo, wi, &bpdf);
                if (mk_max3(f) > 0.0f && dist > 0.0f) {
                    const float lpdf = pick_pmf * ls.pdf;
#if INTEGRATOR == 0
                    const float w = ls.delta ? 1.0f : power_heuristic(lpdf, bpdf);
#else
                    const float w = 1.0f;
#endif
                    const float3 so = dot(n, wi) > 0.0f ? ref : offset_ray_origin_bound(p, p_err, -n);
                    const float3 sp = offset_ray_origin_bound(ls.p, ls.err, ls.n);
#ifdef HAS_INFINITE_LIGHTS
                    const float3 sd = ls.far > 0.0f ? wi * ls.far : sp - so;
#else
                    const float3 sd = sp - so;
#endif
                    ++n_shadow;
                    if (!scene_occluded(nodes, tris, spheres, n_spheres, so, sd, 0.0f, 1.0f))
                        L += beta * f * ls.Le * (w / lpdf);
                }
            }
        }
#endif
        float3 wi;
        float pdf;
        int delta;
        const float2 ud = sample_2d(sk, dim + DIM_BSDF);
        const float3 u = (float3)(ud.x, ud.y, sample_1d(sk, dim + DIM_BSDF_LOBE));
        const float3 weight = bsdf_sample(m, n, front, wo, u, &wi, &pdf, &delta);
        if (!((pdf > 0.0f || delta) && mk_max3(weight) > 0.0f)) break;
        beta *= weight;
        if (dot(wi, n) < 0.0f) { const float eta = dielectric_eta(m, front); eta_scale *= eta * eta; }
        if (segments >= rr_depth) {
#ifdef RR_NO_ETA
            const float q = fmin(mk_max3(beta), 0.95f);
#else
            const float q = fmin(mk_max3(beta) * eta_scale, 0.95f);
#endif
            if (sample_1d(sk, dim + DIM_RR) >= q) break;
            beta /= q;
        }
        o = offset_ray_origin_bound(p, p_err, dot(ng, wi) > 0.0f ? ng : -ng);
        d = wi;
        path_pdf_v = delta ? 0.0f : pdf;
        depth = segments;
    }
    if (!(isfinite(L.x) && isfinite(L.y) && isfinite(L.z))) {
        atomic_inc(&counters[COUNTER_NONFINITE]);
        L = (float3)(0.0f);
    }
    store3(pass_ring, (pass_i % ring_size) * n_pixels + pixel, L);
    atomic_add(&counters[COUNTER_RAYS_EXTEND], n_extend);
    atomic_add(&counters[COUNTER_RAYS_SHADOW], n_shadow);
}
