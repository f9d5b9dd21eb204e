/* Stage 1: n_items new camera paths into free slots, popped from the free stack (free_base
 * entries) and appended to the active queue (queue_base entries).  The first is the sample of
 * (first_pass, first_pixel); later ones take the following pixels, wrapping into the next pass.
 * With n_listed > 0 (adaptive sampling) a pass covers only the pixels pixel_list[0..n_listed),
 * and first_pixel counts entries of that list.
 * The camera ray: camera_ray() of cl/render/path.h; its filter weight waits in path_weight.  With
 * HAS_MEDIA the path also starts in the camera's medium (path_start_media of cl/render/volpath.h). */
#include "render/path.h"
#ifdef HAS_MEDIA
#include "render/volpath.h"
#endif

__kernel void wf_generate(WAVE_PARAMS)
{
    const int i = get_global_id(0);
    if (i >= n_items) return;
    const int n_take = n_listed > 0 ? n_listed : n_pixels;
    const int linear = first_pixel + i;
    const int pass = first_pass + linear / n_take;
    const int pixel = n_listed > 0 ? pixel_list[linear % n_take] : linear % n_take;
    const int slot = free_q[free_base - 1 - i];
    queue_in[queue_base + i] = slot;

    const SampleKey key = sampler_key(sampler, seed, (uint)pixel, (uint)camera->width, (uint)pass);
    pvec3 o, d;
    pfloat weight;
    camera_ray(camera, filter_cdf, key, pixel % camera->width, pixel / camera->width, PTRUE, &o, &d, &weight
               CAMERA_MOTION_ARG);
    path_weight[slot] = weight;
    store3(ray_o, slot, pv3_lane(o, 0));
    store3(ray_d, slot, pv3_lane(d, 0));
    store3(throughput, slot, (float3)(1.0f));
    store3(radiance, slot, (float3)(0.0f));
    path_pixel[slot] = pixel;
    path_pass[slot] = pass;
    path_depth[slot] = 0;
    path_pdf[slot] = 0.0f; /* 0 = "specular/camera": emission seen directly gets full weight */
    path_eta_scale[slot] = 1.0f;
#ifdef LIGHT_TREE
    store3(path_nref, slot, (float3)(0.0f));
#endif
#ifdef HAS_AOVS
    aov_start(aov_path, slot);
#endif
#ifdef HAS_MEDIA
    /* the path's medium state as the megakernel starts it (path_start_media) */
    PathState s;
    path_start(&s, PTRUE, o, d);
    path_start_media(&s, PTRUE, camera_medium, key);
    vol_medium[slot] = s.medium;
    vol_channel[slot] = s.channel;
    vol_rng[slot] = s.rng;
    store3(vol_r, slot, pv3_lane(s.r, 0));
    store3(vol_ref, slot, pv3_lane(s.ref, 0));
#endif
}
