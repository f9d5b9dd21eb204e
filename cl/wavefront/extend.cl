/* Stage 2: closest hit for every active path.  n_items = active-queue length. */
#include "render/lights.h"

__kernel void wf_extend(WAVE_PARAMS)
{
    const int i = get_global_id(0);
    if (i >= n_items) return;
    const int slot = queue_in[i];
    float t, u, v;
    int prim, inst = -1;
    scene_closest_hit(nodes, tris, shape_nodes, shapes, pv3_from(load3(ray_o, slot)), pv3_from(load3(ray_d, slot)),
                      PTRUE, &t, &prim, &u, &v CUTOUT_ARGS INSTANCE_HIT_ARGS(&inst)
                      SCENE_TIME_ARG(time_sample(sampler_key(sampler, seed, (uint)path_pixel[slot],
                                                               (uint)camera->width, (uint)path_pass[slot]))));
    hit_inst[slot] = inst;
    hit_t[slot] = t;
    hit_prim[slot] = prim;
    hit_u[slot] = u;
    hit_v[slot] = v;
}
