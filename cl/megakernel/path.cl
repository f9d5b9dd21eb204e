/* The megakernel: one work-item follows one sample's whole path (camera ray, every bounce,
 * every shadow ray) in registers, for CPU devices, where the wavefront's structure-of-arrays
 * round trips, queue compaction and five launches per bounce cost more than the divergence they
 * avoid (a CPU runs each work-item as scalar code either way).  It computes exactly what the
 * wavefront stages compute, in the same order, with the same random numbers, so its image is the
 * wavefront's bit for bit (tests/render/test_megakernel.py).
 *
 * Work-item i renders sample first_pixel + i of pass first_pass (wrapping into the next passes,
 * as wf_generate numbers them) and writes its radiance into that pass's buffer of the ring;
 * the host launches whole passes, so every pass is complete when the launch is.  With
 * n_listed > 0 (adaptive sampling) a pass covers only the pixels pixel_list[0..n_listed),
 * first_pixel counts entries of that list, and work-item i writes entry i of the ring (the host
 * reads the launch's n_items results in order).  The rays it
 * traces are counted in counters[COUNTER_RAYS_EXTEND] and [COUNTER_RAYS_SHADOW].
 * mat_scratch (textures) is indexed by work-item: n_items is at most the wave size. */
#include "render/path.h"
#include "megakernel/ray_counts.h"

__kernel void mk_path(WAVE_PARAMS)
{
    __local int group_rays[2 * WAVE_LOCAL_SIZE]; /* add_group_ray_counts (ray_counts.h) */
    const int i = get_global_id(0);
    int n_extend = 0, n_shadow = 0;
    if (i < n_items) {
        const int n_take = n_listed > 0 ? n_listed : n_pixels;
        const int linear = first_pixel + i;
        const int pass = first_pass + linear / n_take;
        const int pixel = n_listed > 0 ? pixel_list[linear % n_take] : linear % n_take;
        const int out = n_listed > 0 ? i : (pass % ring_size) * n_pixels + pixel;  /* its pass_ring entry */
        const SampleKey sk = sampler_key(seed, (uint)pixel, (uint)camera->width, (uint)pass);
        float3 o, d;
        camera_ray(camera, sk, pixel, &o, &d);
        PathState s = path_start(o, d);
        int goes_on = 1;
        while (goes_on) {
            const Hit h = scene_closest_hit(nodes, tris, spheres, n_spheres, s.o, s.d, 0.0f, INFINITY);
            ++n_extend;
            if (h.prim == PRIM_MISS) {
#ifdef HAS_ENVIRONMENT
                path_escape(lights, env_map, env_cdf, &s);
#endif
                break;
            }
            ShadowRay shadow;
            const int result = path_shade_hit(PATH_ARGS, i, sk, h.prim, h.t, h.u, h.v, &s, &shadow);
            if (result & 2) {  /* after the emission of this hit, as the wavefront's shadow stage adds it */
                ++n_shadow;
                if (!scene_occluded(nodes, tris, spheres, n_spheres, shadow.o, shadow.d, 0.0f, 1.0f))
                    s.L += shadow.contribution;
            }
            goes_on = result & 1;
        }
        float3 L = s.L;
        if (!(isfinite(L.x) && isfinite(L.y) && isfinite(L.z))) {
            atomic_inc(&counters[COUNTER_NONFINITE]);
            L = (float3)(0.0f);
        }
        store3(pass_ring, out, L);
    }
    add_group_ray_counts(group_rays, WAVE_LOCAL_SIZE, n_extend, n_shadow, counters);
}
