/* The lane megakernel: the megakernel (path.cl) with PACKET_WIDTH paths per work-item in the
 * lanes of its vectors (cl/render/path_lanes.h), for CPU devices on the scenes that header
 * covers.  Their rays are traced together as packets (cl/accel/bvh_packet.h) and their hits
 * shaded together; a sample's value is path.cl's bit for bit, except where two triangles give a
 * ray exactly the same distance (tests/render/test_path_lanes.py).
 *
 * Work-item i renders the samples i * PACKET_BLOCK .. + PACKET_BLOCK of the launch (numbered as
 * in path.cl: sample first_pixel + j of pass first_pass, wrapping into the next passes; with
 * n_listed > 0, entries of pixel_list), PACKET_WIDTH at a time: when a lane's path ends, its
 * radiance is written to its pass_ring entry and the lane starts the block's next sample, so
 * the lanes stay full until the block runs out.  PACKET_WIDTH and PACKET_BLOCK come from the
 * host (pyopencl_rt/render/megakernel.py). */
#include "render/path_lanes.h"
#include "megakernel/ray_counts.h"

#if !defined(PACKET_BLOCK) || !defined(LANE_GROUP)
#error "PACKET_BLOCK (samples per work-item) and LANE_GROUP (work-items per group) come from the host"
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

/* Starts the block's next samples in the lanes of `starting` (bit k: lane k), in lane order:
 * each sample's pixel and ring entry as path.cl numbers them, its SampleKey (sampler_key, per
 * lane) and its camera ray (camera_ray, on the lanes; a thin lens per lane in scalar code).
 * Returns the lanes started (all of `starting`, or fewer when the block runs out). */
RT_INLINE int start_lanes(__global const Camera *camera, int starting, SampleCursor *cur, int last, int n_pixels,
                          __global const int *pixel_list, int n_listed, int ring_size, uint seed, PathLanes *s,
                          pint *out)
{
    const Camera cam = *camera;
    const int n_take = n_listed > 0 ? n_listed : n_pixels;
    int started = 0;
    pint px, py;
    for (int k = 0; k < PACKET_WIDTH && cur->j < last; ++k) {
        if (!((starting >> k) & 1)) continue;
        int pixel = cur->index, x = cur->x, y = cur->y;
        if (n_listed > 0) { /* adaptive sampling: a pixel of the list */
            pixel = pixel_list[cur->index];
            x = pixel % cam.width;
            y = pixel / cam.width;
        }
        PLANE_I(*out, k) = n_listed > 0 ? cur->j : cur->slot * n_pixels + pixel;
        const SampleKey sk = sampler_key_xy(seed, (uint)pixel, (uint)x, (uint)y, (uint)cur->pass);
        PLANE_U(s->key.a, k) = sk.a; PLANE_U(s->key.b, k) = sk.b; PLANE_U(s->key.c, k) = sk.c;
        PLANE_I(px, k) = x;
        PLANE_I(py, k) = y;
        started |= 1 << k;
        cursor_step(cur, n_take, ring_size, cam.width);
    }
    if (!started) return 0;
    const pint on = pmask(started);
    /* camera_ray (path.h): the box-filtered jitter, the pinhole ray */
    pfloat jx, jy;
    sample_2d_lanes(s->key, PUINT(DIM_PIXEL), &jx, &jy);
    const pfloat sx = (convert_pfloat(px) + jx) / (float)cam.width * 2.0f - 1.0f;
    const pfloat sy = 1.0f - (convert_pfloat(py) + jy) / (float)cam.height * 2.0f;
    const pvec3 forward = pv3_splat((float3)(cam.forward[0], cam.forward[1], cam.forward[2]));
    const pvec3 right = pv3_splat((float3)(cam.right[0], cam.right[1], cam.right[2]));
    const pvec3 up = pv3_splat((float3)(cam.up[0], cam.up[1], cam.up[2]));
    pvec3 d = pv3_normalize(pv3_add(pv3_add(forward, pv3_scale(right, sx)), pv3_scale(up, sy)), on);
    pvec3 o = pv3_splat((float3)(cam.origin[0], cam.origin[1], cam.origin[2]));
    if (cam.lens_radius > 0.0f) {
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            if (!((started >> k) & 1)) continue;
            SampleKey sk;
            sk.a = PLANE_U(s->key.a, k); sk.b = PLANE_U(s->key.b, k); sk.c = PLANE_U(s->key.c, k);
            float3 lo, ld;
            camera_ray(camera, sk, PLANE_I(py, k) * cam.width + PLANE_I(px, k), &lo, &ld);
            pv3_set_lane(&o, k, lo);
            pv3_set_lane(&d, k, ld);
        }
    }
    /* path_start */
    s->o = pv3_sel(s->o, o, on);
    s->d = pv3_sel(s->d, d, on);
    s->beta = pv3_sel(s->beta, pv3_splat((float3)(1.0f)), on);
    s->L = pv3_sel(s->L, pv3_splat((float3)(0.0f)), on);
    s->pdf = on ? PFLOAT(0.0f) : s->pdf;
    s->eta_scale = on ? PFLOAT(1.0f) : s->eta_scale;
    s->depth = on ? PINT(0) : s->depth;
    return started;
}

__kernel void mk_lanes(WAVE_PARAMS)
{
    /* small groups (LANE_GROUP work-items of PACKET_BLOCK samples each): a launch of the CPU
     * wave size still has enough groups for every core */
    __local int group_rays[2 * LANE_GROUP];
    const int i = get_global_id(0);
    int n_extend = 0, n_shadow = 0;
    const int last = min((i + 1) * PACKET_BLOCK, n_items);
    SampleCursor cur = cursor_at(i * PACKET_BLOCK, first_pixel, first_pass, n_pixels, n_listed, ring_size, camera->width);
    PathLanes s;
    /* idle lanes hold a harmless path (never traced: their tmax is below tmin) */
    const PathState idle = path_start((float3)(0.0f), (float3)(0.0f, 0.0f, 1.0f));
    SampleKey idle_key;
    idle_key.a = idle_key.b = idle_key.c = 0u;
    for (int k = 0; k < PACKET_WIDTH; ++k) lanes_set_path(&s, k, idle, idle_key);
    pint out = PINT(0);
    int live = start_lanes(camera, (1 << PACKET_WIDTH) - 1, &cur, last, n_pixels, pixel_list, n_listed, ring_size,
                           seed, &s, &out); /* bit k: lane k holds a path */
    while (live) {
        const pint live_lanes = pmask(live);
        /* -- extend: the live lanes' rays, one packet ---------------------------------------- */
        const PacketRay r = packet_rays(s.o, s.d);
        pfloat t = live_lanes ? PFLOAT(INFINITY) : PFLOAT(-1.0f); /* idle lanes: tmax < tmin */
        pint prim = PINT(PRIM_MISS);
        pfloat u, v;
        packet_closest_hit(nodes, &r, PFLOAT(0.0f), &t, &prim, &u, &v);
        n_extend += bit_count(live);
        const pint hit = live_lanes & (prim != PRIM_MISS);
        pint goes_on, with_shadow;
        pvec3 so, sd, contribution;
        shade_lanes(tris, tri_material, tri_light, materials, lights, n_lights, max_depth, rr_depth, hit, prim, u, v,
                    &s, &goes_on, &with_shadow, &so, &sd, &contribution);
        /* -- shadow: the lanes with a light sample, one packet ------------------------------- */
        if (pany(with_shadow)) {
            n_shadow += bit_count(pbits(with_shadow));
            const PacketRay sr = packet_rays(so, sd);
            const pint occluded = packet_any_hit(nodes, &sr, PFLOAT(0.0f), with_shadow ? PFLOAT(1.0f) : PFLOAT(-1.0f));
            s.L = pv3_sel(s.L, pv3_add(s.L, contribution), with_shadow & ~occluded);
        }
        /* -- ended paths: their radiance out, the block's next samples in -------------------- */
        const int ended = live & ~pbits(goes_on);
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            if (!((ended >> k) & 1)) continue;
            float3 L = pv3_lane(s.L, k);
            if (!(isfinite(L.x) && isfinite(L.y) && isfinite(L.z))) {
                atomic_inc(&counters[COUNTER_NONFINITE]);
                L = (float3)(0.0f);
            }
            store3(pass_ring, PLANE_I(out, k), L);
        }
        live &= ~ended;
        if (ended && cur.j < last)
            live |= start_lanes(camera, ended, &cur, last, n_pixels, pixel_list, n_listed, ring_size, seed, &s, &out);
    }
    add_group_ray_counts(group_rays, LANE_GROUP, n_extend, n_shadow, counters);
}
