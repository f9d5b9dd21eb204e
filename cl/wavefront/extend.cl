/* Stage 2: closest hit for every active path.  n_items = active-queue length. */
#include "render/lights.h"

__kernel void wf_extend(WAVE_PARAMS)
{
    const int i = get_global_id(0);
    if (i >= n_items) return;
    const int slot = queue_in[i];
    const Hit h = scene_closest_hit(nodes, tris, spheres, n_spheres, load3(ray_o, slot), load3(ray_d, slot),
                                    0.0f, INFINITY);
    hit_t[slot] = h.t;
    hit_prim[slot] = h.prim;
    hit_u[slot] = h.u;
    hit_v[slot] = h.v;
}
