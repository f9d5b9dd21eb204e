/* Stage 3: every active path at its new hit point (n_items = active-queue length): the shared
 * integrator step of cl/render/path.h (emission with MIS, one light sample, one BSDF sample with
 * Russian roulette) on the state this path keeps in the structure-of-arrays buffers; the light
 * sample goes to the shadow queue, the path to the next active queue or the termination queue.
 * With HAS_MEDIA the step is volpath_vertex (cl/render/volpath.h), the megakernel's: the free flight
 * to the hit of the extend stage, a scattering vertex (its light sample through the shadow queue, a
 * phase sample) or a null crossing, else the surface or the environment as without media. */
#include "render/path.h"
#ifdef HAS_MEDIA
#include "render/volpath.h"
#endif

/* What the shadow stage reads of a slot's light sample, and what the next stages read of a path
 * that goes on (the names of WAVE_PARAMS, `slot` and the step's results in scope) */
#define STORE_SHADOW_RAY()                                                                          \
    do {                                                                                            \
        store3(sh_o, slot, pv3_lane(shadow.o, 0));                                                  \
        store3(sh_d, slot, pv3_lane(shadow.d, 0));                                                  \
        store3(sh_contrib, slot, pv3_lane(shadow.contribution, 0));                                 \
    } while (0)
#define STORE_PATH()                                                                                \
    do {                                                                                            \
        store3(ray_o, slot, pv3_lane(s.o, 0));                                                      \
        store3(ray_d, slot, pv3_lane(s.d, 0));                                                      \
        store3(throughput, slot, pv3_lane(s.beta, 0));                                              \
        path_pdf[slot] = s.pdf;                                                                     \
        path_eta_scale[slot] = s.eta_scale;                                                         \
        path_depth[slot] = s.depth;                                                                 \
        STORE_NREF();                                                                               \
    } while (0)
#ifdef LIGHT_TREE
#define STORE_NREF() store3(path_nref, slot, pv3_lane(s.nref, 0))
#else
#define STORE_NREF() (void)0
#endif

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
        const SampleKey key = sampler_key(sampler, seed, (uint)path_pixel[slot], (uint)camera->width, (uint)path_pass[slot]);
        PathState s;
        s.o = pv3_from(load3(ray_o, slot));
        s.d = pv3_from(load3(ray_d, slot));
        s.beta = pv3_from(load3(throughput, slot));
        s.L = pv3_from(load3(radiance, slot));
        s.pdf = path_pdf[slot];
        s.eta_scale = path_eta_scale[slot];
        s.depth = path_depth[slot];
#ifdef LIGHT_TREE
        s.nref = pv3_from(load3(path_nref, slot));
#endif
#ifdef HAS_MEDIA
        /* the medium step first: volpath_vertex, the megakernel's step; the ray's hit (a miss
         * too) bounds its free flight */
        s.medium = vol_medium[slot];
        s.channel = vol_channel[slot];
        s.rng = vol_rng[slot];
        s.r = pv3_from(load3(vol_r, slot));
        s.ref = pv3_from(load3(vol_ref, slot));
        {
            ShadowRay shadow;
            pint shadow_medium;
            volpath_vertex(PATH_ARGS, MEDIA_PATH_ARGS, env_light, slot, key, PTRUE, prim, hit_t[slot], hit_u[slot],
                           hit_v[slot], &s, &alive, &queued_shadow, &shadow, &shadow_medium);
            alive = alive != 0;
            queued_shadow = queued_shadow != 0;
            if (queued_shadow) {
                STORE_SHADOW_RAY();
                sh_medium[slot] = shadow_medium;
            }
            /* the shadow stage's ratio tracking draws from the stream and weighs with r after this
             * vertex, ended path or not */
            vol_rng[slot] = s.rng;
            store3(vol_r, slot, pv3_lane(s.r, 0));
            if (alive) {
                STORE_PATH();
                vol_medium[slot] = s.medium;
                store3(vol_ref, slot, pv3_lane(s.ref, 0));
            }
        }
#else
        if (prim != PRIM_MISS) {
            ShadowRay shadow;
            path_shade(PATH_ARGS, slot, key, PTRUE, prim, hit_t[slot], hit_u[slot], hit_v[slot], &s, &alive,
                       &queued_shadow, &shadow INSTANCE_SHADE_ARGS(hit_inst[slot]));
            alive = alive != 0; /* masks: any non-zero value is true */
            queued_shadow = queued_shadow != 0;
            if (queued_shadow) STORE_SHADOW_RAY();
            if (alive) STORE_PATH();
        }
#ifdef HAS_ENVIRONMENT
        else {
            path_escape(lights, env_light, env_map, env_cdf, integrator, PTRUE, &s);
        }
#endif
#endif /* HAS_MEDIA */
        store3(radiance, slot, pv3_lane(s.L, 0));
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
