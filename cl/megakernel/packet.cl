/* The packet megakernel: the megakernel (path.cl) with PACKET_WIDTH paths per work-item, whose
 * rays are traced together, one packet per bounce (cl/accel/bvh_packet.h), for CPU devices on
 * small scenes, where a packet's rays share most of the BVH nodes they visit.
 *
 * Work-item i renders the samples i * PACKET_BLOCK .. + PACKET_BLOCK of the launch (numbered as
 * in path.cl: sample first_pixel + j of pass first_pass, wrapping into the next passes), keeping
 * PACKET_WIDTH of them in flight in its lanes: when a lane's path ends its radiance is written
 * and the lane takes the next sample of the block, so the packets stay full until the block runs
 * out.  Each bounce: one packet closest-hit for every lane, each lane's hit shaded in turn with
 * path_shade_hit (scalar code, the functions both other schedules call), one packet any-hit for
 * the lanes with a shadow ray.  A sample's computation is path.cl's step for step, so its value
 * is the same bit for bit; only where a ray meets two triangles at exactly the same distance
 * can the packet traversal report the other one (tests/render/test_megakernel.py).
 * mat_scratch (textures) is indexed by work-item, as in path.cl: a lane's shading is done with
 * it before the next lane's starts. */
#include "render/path.h"
#include "accel/bvh_packet.h"

/* PACKET_WIDTH and PACKET_BLOCK come from the host (pyopencl_rt/render/megakernel.py) */
#ifndef PACKET_BLOCK
#error "PACKET_BLOCK: samples per work-item, defined by the host"
#endif

/* The camera ray of launch sample j (path.cl's numbering), its SampleKey and its ring entry. */
RT_INLINE PathState packet_sample(__global const Camera *camera, int j, int first_pixel, int first_pass,
                                  int n_pixels, __global const int *pixel_list, int n_listed, int ring_size,
                                  uint seed, SampleKey *sk, int *out)
{
    const int n_take = n_listed > 0 ? n_listed : n_pixels;
    const int linear = first_pixel + j;
    const int pass = first_pass + linear / n_take;
    const int pixel = n_listed > 0 ? pixel_list[linear % n_take] : linear % n_take;
    *out = n_listed > 0 ? j : (pass % ring_size) * n_pixels + pixel;
    *sk = sampler_key(seed, (uint)pixel, (uint)camera->width, (uint)pass);
    float3 o, d;
    camera_ray(camera, *sk, pixel, &o, &d);
    return path_start(o, d);
}

__kernel void mk_packet(WAVE_PARAMS)
{
    __local int group_rays[2 * WAVE_LOCAL_SIZE];
    const int i = get_global_id(0), lid = get_local_id(0);
    int n_extend = 0, n_shadow = 0;
    const int last = min((i + 1) * PACKET_BLOCK, n_items);
    int next = i * PACKET_BLOCK;
    PathState s[PACKET_WIDTH];
    ShadowRay shadow[PACKET_WIDTH];
    SampleKey sk[PACKET_WIDTH];
    int out[PACKET_WIDTH];
    int live = 0; /* bit k: lane k holds a path */
    for (int k = 0; k < PACKET_WIDTH && next < last; ++k, ++next) {
        s[k] = packet_sample(camera, next, first_pixel, first_pass, n_pixels, pixel_list, n_listed, ring_size,
                             seed, &sk[k], &out[k]);
        live |= 1 << k;
    }
    while (live) {
        /* -- extend: every live lane's ray, one packet ---------------------------------------- */
        PacketRay r;
        pfloat t = PFLOAT(-1.0f); /* dead lanes: tmax < tmin */
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            const int on = (live >> k) & 1;
            packet_set_ray(&r, k, on ? s[k].o : (float3)(0.0f), on ? s[k].d : (float3)(0.0f, 0.0f, 1.0f));
            if (on) PLANE(t, k) = INFINITY;
        }
        pint prim = PINT(PRIM_MISS);
        pfloat u = PFLOAT(0.0f), v = PFLOAT(0.0f);
#ifdef HAS_TRIANGLES
        packet_closest_hit(nodes, &r, PFLOAT(0.0f), &t, &prim, &u, &v);
#endif
        int with_shadow = 0, ended = 0;
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            if (!((live >> k) & 1)) continue;
            ++n_extend;
            Hit h;
            h.t = PLANE(t, k); h.prim = PLANE_I(prim, k); h.u = PLANE(u, k); h.v = PLANE(v, k);
#ifdef HAS_SPHERES
            for (int q = 0; q < n_spheres; ++q) { /* as scene_closest_hit, after the triangles */
                float ts;
                if (intersect_sphere(s[k].o, s[k].d, vload3(0, spheres[q].center), spheres[q].radius, 0.0f, h.t, &ts)) {
                    h.t = ts; h.prim = SPHERE_PRIM(q); h.u = 0.0f; h.v = 0.0f;
                }
            }
#endif
            if (h.prim == PRIM_MISS) {
#ifdef HAS_ENVIRONMENT
                path_escape(lights, env_map, env_cdf, &s[k]);
#endif
                ended |= 1 << k;
                continue;
            }
            const int result = path_shade_hit(PATH_ARGS, i, sk[k], h.prim, h.t, h.u, h.v, &s[k], &shadow[k]);
            if (result & 2) with_shadow |= 1 << k;
            if (!(result & 1)) ended |= 1 << k;
        }
        /* -- shadow: the lanes with a light sample, one packet ---------------------------------- */
        if (with_shadow) {
            n_shadow += bit_count(with_shadow);
            int blocked = 0;
            PacketRay sr;
            pfloat smax = PFLOAT(-1.0f);
            for (int k = 0; k < PACKET_WIDTH; ++k) {
                int on = (with_shadow >> k) & 1;
#ifdef HAS_SPHERES
                for (int q = 0; on && q < n_spheres; ++q) {
                    float ts;
                    if (intersect_sphere(shadow[k].o, shadow[k].d, vload3(0, spheres[q].center), spheres[q].radius,
                                         0.0f, 1.0f, &ts)) {
                        blocked |= 1 << k;
                        on = 0;
                    }
                }
#endif
                packet_set_ray(&sr, k, on ? shadow[k].o : (float3)(0.0f), on ? shadow[k].d : (float3)(0.0f, 0.0f, 1.0f));
                if (on) PLANE(smax, k) = 1.0f;
            }
#ifdef HAS_TRIANGLES
            if (with_shadow & ~blocked) {
                const pint occluded = packet_any_hit(nodes, &sr, PFLOAT(0.0f), smax);
                for (int k = 0; k < PACKET_WIDTH; ++k)
                    if (PLANE_I(occluded, k)) blocked |= 1 << k;
            }
#endif
            for (int k = 0; k < PACKET_WIDTH; ++k)
                if (((with_shadow & ~blocked) >> k) & 1) s[k].L += shadow[k].contribution;
        }
        /* -- ended paths: write their radiance, start the block's next samples ------------------ */
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            if (!((ended >> k) & 1)) continue;
            float3 L = s[k].L;
            if (!(isfinite(L.x) && isfinite(L.y) && isfinite(L.z))) {
                atomic_inc(&counters[COUNTER_NONFINITE]);
                L = (float3)(0.0f);
            }
            store3(pass_ring, out[k], L);
            if (next < last) {
                s[k] = packet_sample(camera, next, first_pixel, first_pass, n_pixels, pixel_list, n_listed, ring_size,
                                     seed, &sk[k], &out[k]);
                ++next;
            } else {
                live &= ~(1 << k);
            }
        }
    }
    group_rays[lid] = n_extend;
    group_rays[WAVE_LOCAL_SIZE + lid] = n_shadow;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) {
        int extend = 0, shadow_rays = 0;
        for (int k = 0; k < WAVE_LOCAL_SIZE; ++k) {
            extend += group_rays[k];
            shadow_rays += group_rays[WAVE_LOCAL_SIZE + k];
        }
        atomic_add(&counters[COUNTER_RAYS_EXTEND], extend);
        atomic_add(&counters[COUNTER_RAYS_SHADOW], shadow_rays);
    }
}
