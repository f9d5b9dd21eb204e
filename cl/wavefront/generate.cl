/* Stage 1: n_items new camera paths into free slots, popped from the free stack (free_base
 * entries) and appended to the active queue (queue_base entries).  The first is the sample of
 * (first_pass, first_pixel); later ones take the following pixels, wrapping into the next pass.
 * Pixel jitter: box filter over the pixel.  A thin-lens camera (lens_radius > 0,
 * pyopencl_rt/device/abi.py) also samples the lens; lens_radius 0 is the pinhole, bit for bit. */
#include "render/lights.h"
#ifdef HAS_AOVS
#include "render/aov.h"
#endif

__kernel void wf_generate(WAVE_PARAMS)
{
    const int i = get_global_id(0);
    if (i >= n_items) return;
    const int linear = first_pixel + i;
    const int pass = first_pass + linear / n_pixels;
    const int pixel = linear % n_pixels;
    const int slot = free_q[free_base - 1 - i];
    queue_in[queue_base + i] = slot;

    const Camera cam = *camera;
    const SampleKey sk = sampler_key(seed, (uint)pixel, (uint)cam.width, (uint)pass);
    const int x = pixel % cam.width, y = pixel / cam.width;
    const float2 jitter = sample_2d(sk, DIM_PIXEL);
    const float sx = ((float)x + jitter.x) / (float)cam.width * 2.0f - 1.0f;
    const float sy = 1.0f - ((float)y + jitter.y) / (float)cam.height * 2.0f;
    const float3 dir = vload3(0, cam.forward) + sx * vload3(0, cam.right) + sy * vload3(0, cam.up);
    float3 d = normalize(dir), o = vload3(0, cam.origin);
    if (cam.lens_radius > 0.0f) {
        /* thin lens: from a point of the lens disk (concentric map, rng dims DIM_LENS and + 1)
         * through the point of the pinhole ray at distance focus_distance along forward */
        const float2 l = cam.lens_radius * sample_concentric_disk(sample_2d(sk, DIM_LENS));
        const float3 lens = l.x * normalize(vload3(0, cam.right)) + l.y * normalize(vload3(0, cam.up));
        d = normalize(cam.focus_distance * dir - lens);
        o += lens;
    }
    store3(ray_o, slot, o);
    store3(ray_d, slot, d);
    store3(throughput, slot, (float3)(1.0f));
    store3(radiance, slot, (float3)(0.0f));
    path_pixel[slot] = pixel;
    path_pass[slot] = pass;
    path_depth[slot] = 0;
    path_pdf[slot] = 0.0f; /* 0 = "specular/camera": emission seen directly gets full weight */
    path_eta_scale[slot] = 1.0f;
#ifdef HAS_AOVS
    aov_start(aov_path, slot);
#endif
}
