/* The megakernel, for CPU devices: each work-item follows whole paths (camera ray, every
 * bounce, every shadow ray) in registers, where the wavefront's structure-of-arrays round trips,
 * queue compaction and five launches per bounce cost more than the divergence they avoid.  Its
 * PACKET_WIDTH lanes (cl/render/lanes.h: 1, or 8 or 16 on x86 CPUs) are PACKET_WIDTH paths at
 * once: their rays are traced together (as packets, cl/accel/bvh_packet.h, in lanes) and their
 * hits shaded together by the one integrator (cl/render/path.h).  It computes the samples the
 * wavefront computes, with the same random numbers and arithmetic, so its image is the
 * wavefront's bit for bit at every width, except where two triangles give a ray exactly the same
 * distance (tests/render/test_megakernel.py, tests/render/test_path_lanes.py).
 *
 * Work-item i renders the samples i * PACKET_BLOCK .. + PACKET_BLOCK of the launch (sample
 * first_pixel + j of pass first_pass, wrapping into the next passes, as wf_generate numbers
 * them; with n_listed > 0, entries of pixel_list), PACKET_WIDTH at a time: when a lane's path
 * ends, its radiance (times its camera sample's filter weight) is written to its pass_ring entry
 * (entry j of the launch with n_listed > 0) and the lane starts the block's next sample, so the
 * lanes stay full until the block runs out.
 * PACKET_BLOCK and LANE_GROUP come from the host (pyopencl_rt/render/megakernel.py: groups of one
 * work-item on CPUs; one sample per work-item and the wave's group size on GPUs).  The rays it traces are counted in
 * counters[COUNTER_RAYS_EXTEND] and [COUNTER_RAYS_SHADOW]. */
#include "render/path.h"
#ifdef HAS_MEDIA
#include "render/volpath.h"
#endif
#include "megakernel/ray_counts.h"

#ifndef PACKET_BLOCK
#define PACKET_BLOCK 1
#endif
#ifndef LANE_GROUP
#define LANE_GROUP WAVE_LOCAL_SIZE
#endif

/* Where a work-item's next sample is: sample j of the launch (path.cl's numbering) as its pass,
 * its index in the pass (in pixel order, or into pixel_list) and its pass's ring slot, and, for
 * whole passes, its pixel's (x, y).  Stepped by increments: the divisions of path.cl's numbering
 * (five a sample) cost more than the rest of starting a path. */
typedef struct { int j, pass, index, slot, x, y; } SampleCursor;

RT_INLINE SampleCursor cursor_at(int j, int first_pixel, int first_pass, int n_pixels, int n_listed, int ring_size,
                                 int width)
{
    SampleCursor c;
    const int n_take = n_listed > 0 ? n_listed : n_pixels;
    const int linear = first_pixel + j;
    c.j = j;
    c.pass = first_pass + linear / n_take;
    c.index = linear % n_take;
    c.slot = c.pass % ring_size;
    c.x = c.index % width;
    c.y = c.index / width;
    return c;
}

RT_INLINE void cursor_step(SampleCursor *c, int n_take, int ring_size, int width)
{
    ++c->j;
    ++c->index;
    if (++c->x == width) { c->x = 0; ++c->y; }
    if (c->index == n_take) {
        c->index = c->x = c->y = 0;
        ++c->pass;
        c->slot = c->slot + 1 == ring_size ? 0 : c->slot + 1;
    }
}

/* The block's next samples, computed a vector at a time (lane k: the k-th sample after the cursor)
 * and handed out to the lanes whose paths end, a few at a time: the key and the camera ray of a
 * sample cost as much for one lane as for all of them, and two or three lanes end at a time. */
typedef struct {
    SampleKey key;
    pvec3 o, d;
    pfloat weight; /* the camera sample's filter weight */
    pint out;      /* its pass_ring entry */
    int count;     /* samples held, in lanes 0 .. count - 1 */
    int next;      /* the first not handed out yet */
} ReadySamples;

/* Fills r with the block's next samples (up to PACKET_WIDTH): each sample's pixel and ring entry
 * as the wavefront numbers them, then on the lanes its SampleKey (sampler_key) and its camera
 * ray (camera_ray). */
RT_INLINE void ready_fill(__global const Camera *camera, __global const float *filter_cdf CAMERA_MOTION_PARAM,
                          SampleCursor *cur,
                          int last, int n_pixels, __global const int *pixel_list, int n_listed, int ring_size,
                          int sampler, uint seed, ReadySamples *r)
{
    const int width = camera->width;
    const int n_take = n_listed > 0 ? n_listed : n_pixels;
    pint px = PINT(0), py = PINT(0), pixels = PINT(0), passes = PINT(0), out = PINT(0);
    int n = 0;
    for (; n < PACKET_WIDTH && cur->j < last; ++n) {
        int pixel = cur->index, x = cur->x, y = cur->y;
        if (n_listed > 0) { /* adaptive sampling: a pixel of the list */
            pixel = pixel_list[cur->index];
            x = pixel % width;
            y = pixel / width;
        }
        PLANE_I(out, n) = n_listed > 0 ? cur->j : cur->slot * n_pixels + pixel;
        PLANE_I(pixels, n) = pixel;
        PLANE_I(passes, n) = cur->pass;
        PLANE_I(px, n) = x;
        PLANE_I(py, n) = y;
        cursor_step(cur, n_take, ring_size, width);
    }
    r->count = n;
    r->next = 0;
    if (!n) return;
    r->key = sampler_key_xy(sampler, seed, as_puint(pixels), as_puint(px), as_puint(py), as_puint(passes));
    camera_ray(camera, filter_cdf, r->key, px, py, pmask((int)((1u << n) - 1u)), &r->o, &r->d, &r->weight
               CAMERA_MOTION_ARG);
    r->out = out;
}

/* Starts the block's next samples in the lanes of `starting` (bit k: lane k), in lane order, from
 * r (refilled when it runs out).  Returns the lanes started (all of `starting`, or fewer when the
 * block runs out). */
RT_INLINE int start_lanes(__global const Camera *camera, __global const float *filter_cdf CAMERA_MOTION_PARAM,
                          int starting,
                          ReadySamples *r, SampleCursor *cur, int last, int n_pixels, __global const int *pixel_list,
                          int n_listed, int ring_size, int sampler, uint seed, int camera_medium, PathState *s,
                          SampleKey *key,
                          pint *out, pfloat *weight)
{
    int started = 0;
    while (starting) {
        if (r->next == r->count) {
            ready_fill(camera, filter_cdf CAMERA_MOTION_ARG, cur, last, n_pixels, pixel_list, n_listed, ring_size,
                       sampler, seed, r);
            if (!r->count) break;
        }
        pint from = PINT(0); /* each starting lane's entry of r */
        int bits = 0;
        for (int b = starting; b && r->next < r->count; b &= b - 1) {
            const int k = lowest_bit(b);
            PLANE_I(from, k) = r->next++;
            bits |= 1 << k;
        }
        starting &= ~bits;
        started |= bits;
        const pint on = pmask(bits);
        key->a = on ? as_puint(ppermute_int(as_pint(r->key.a), from)) : key->a;
        key->b = on ? as_puint(ppermute_int(as_pint(r->key.b), from)) : key->b;
        key->c = on ? as_puint(ppermute_int(as_pint(r->key.c), from)) : key->c;
        const pvec3 o = pv3(ppermute(r->o.x, from), ppermute(r->o.y, from), ppermute(r->o.z, from));
        const pvec3 d = pv3(ppermute(r->d.x, from), ppermute(r->d.y, from), ppermute(r->d.z, from));
        path_start(s, on, o, d);
#ifdef HAS_MEDIA
        path_start_media(s, on, camera_medium, *key);
#endif
        *weight = on ? ppermute(r->weight, from) : *weight;
        *out = on ? ppermute_int(r->out, from) : *out;
    }
    return started;
}

__kernel LANE_KERNEL void mk_path(WAVE_PARAMS)
{
    /* small groups (LANE_GROUP work-items of PACKET_BLOCK samples each): a launch of the CPU
     * wave size still has enough groups for every core */
    __local int group_rays[2 * LANE_GROUP];
    const int i = get_global_id(0);
    int n_extend = 0, n_shadow = 0;
    const int last = min((i + 1) * PACKET_BLOCK, n_items);
    SampleCursor cur = cursor_at(i * PACKET_BLOCK, first_pixel, first_pass, n_pixels, n_listed, ring_size, camera->width);
    /* idle lanes hold a harmless path (never traced) */
    PathState s;
    path_start(&s, PTRUE, pv3_zero(), pv3_splat((float3)(0.0f, 0.0f, 1.0f)));
    SampleKey key;
    key.a = key.b = key.c = PUINT(0);
#ifndef SAMPLER
    key.kind = sampler;
#endif
#ifdef HAS_MEDIA
    path_start_media(&s, PTRUE, MEDIUM_VACUUM, key);
#endif
    pint out = PINT(0);
    pfloat weight = PFLOAT(1.0f); /* the camera samples' filter weights */
    ReadySamples ready;
    ready.count = ready.next = 0;
    int live = start_lanes(camera, filter_cdf CAMERA_MOTION_ARG, (1 << PACKET_WIDTH) - 1, &ready, &cur, last, n_pixels,
                           pixel_list, n_listed, ring_size, sampler, seed, camera_medium, &s, &key, &out,
                           &weight); /* bit k: lane k holds a path */
    while (live) {
        const pint live_lanes = pmask(live);
        /* -- extend: the live lanes' rays ------------------------------------------------------ */
        pfloat t, u, v;
        pint prim, inst = PINT(-1);
        scene_closest_hit(nodes, tris, shape_nodes, shapes, s.o, s.d, live_lanes, &t, &prim, &u, &v CUTOUT_ARGS
                          INSTANCE_HIT_ARGS(&inst) SCENE_TIME_ARG(time_sample(key)));
        n_extend += popcount(live);
#ifdef HAS_MEDIA
        /* -- the media along the rays, then the surfaces or the environment (render/volpath.h) */
        pint shadow_medium, goes_on, with_shadow;
        ShadowRay shadow;
        volpath_vertex(PATH_ARGS, MEDIA_PATH_ARGS, env_light, PINT(0), key, live_lanes, prim, t, u, v, &s, &goes_on,
                       &with_shadow, &shadow, &shadow_medium);
#else
        pint hit = live_lanes & (prim != PRIM_MISS), escaped = live_lanes & pnot(hit);
#ifdef HAS_ENVIRONMENT
        path_escape(lights, env_light, env_map, env_cdf, integrator, escaped, &s);
#endif
        pint goes_on, with_shadow;
        ShadowRay shadow;
        path_shade(PATH_ARGS, PINT(0), key, hit, prim, t, u, v, &s, &goes_on, &with_shadow, &shadow
                   INSTANCE_SHADE_ARGS(inst));
#endif
        /* -- shadow: the lanes with a light sample (after the emission of this hit, as the
         * wavefront's shadow stage adds it) ---------------------------------------------------- */
        if (pany(with_shadow)) {
            n_shadow += popcount(pbits(with_shadow));
#ifdef HAS_MEDIA
            /* through media and null boundaries: the transmittance, 0 where a surface blocks */
            const pvec3 tr = shadow_transmittance(nodes, tris, MESH_ARGS, face_normal, shape_nodes, shapes, tri_material,
                                                  shape_material, materials, MEDIA_PATH_ARGS, shadow.o, shadow.d,
                                                  shadow_medium, s.channel, &s.rng, s.r, with_shadow);
            s.L = pv3_sel(s.L, pv3_add(s.L, pv3_mul(shadow.contribution, tr)), with_shadow);
#else
            const pint occluded = scene_occluded(nodes, tris, shape_nodes, shapes, shadow.o, shadow.d, with_shadow,
                                                 PFLOAT(1.0f) CUTOUT_ARGS INSTANCE_ARGS
                                                 SCENE_TIME_ARG(time_sample(key)));
            s.L = pv3_sel(s.L, pv3_add(s.L, shadow.contribution), with_shadow & pnot(occluded));
#endif
        }
        /* -- ended paths: their radiance out, the block's next samples in -------------------- */
        const int ended = live & ~pbits(goes_on);
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            if (!((ended >> k) & 1)) continue;
            float3 L = clamp_sample(pv3_lane(s.L, k), max_component) * PLANE(weight, k);
            if (!(isfinite(L.x) && isfinite(L.y) && isfinite(L.z))) {
                atomic_inc(&counters[COUNTER_NONFINITE]);
                L = (float3)(0.0f);
            }
            store3(pass_ring, PLANE_I(out, k), L);
        }
        live &= ~ended;
        if (ended && (ready.next < ready.count || cur.j < last))
            live |= start_lanes(camera, filter_cdf CAMERA_MOTION_ARG, ended, &ready, &cur, last, n_pixels, pixel_list,
                                n_listed, ring_size, sampler, seed, camera_medium, &s, &key, &out, &weight);
    }
    add_group_ray_counts(group_rays, LANE_GROUP, n_extend, n_shadow, counters);
}
