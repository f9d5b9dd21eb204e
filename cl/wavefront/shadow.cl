/* Stage 4: any-hit test of every queued light sample; unoccluded ones add their contribution.
 * The shadow ray runs from the offset surface point to the offset light point, t in (0, 1). */
#include "render/lights.h"

__kernel void wf_shadow(WAVE_PARAMS)
{
    const int i = get_global_id(0);
    if (i >= counters[COUNTER_SHADOW]) return;
    const int slot = shadow_q[i];
    if (!scene_occluded(nodes, tris, spheres, n_spheres, pv3_from(load3(sh_o, slot)), pv3_from(load3(sh_d, slot)), PTRUE,
                        1.0f CUTOUT_ARGS INSTANCE_ARGS))
        store3(radiance, slot, load3(radiance, slot) + load3(sh_contrib, slot));
}
