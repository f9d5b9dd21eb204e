/* Stage 5: finished paths.  The radiance, times the camera sample's filter weight, goes to its
 * pass's buffer in the ring (one write per pixel and pass, so no float atomics and no order dependence), non-finite values are counted
 * and dropped, and the slot returns to the free stack (of free_base entries before). */
#include "render/lights.h"
#ifdef HAS_AOVS
#include "render/aov.h"
#endif

__kernel void wf_accumulate(WAVE_PARAMS)
{
    const int i = get_global_id(0);
    if (i >= counters[COUNTER_TERM]) return;
    const int slot = term_q[i];
    float3 L = clamp_sample(load3(radiance, slot), max_component) * path_weight[slot]; /* the camera sample's filter weight */
    if (!(isfinite(L.x) && isfinite(L.y) && isfinite(L.z))) {
        atomic_inc(&counters[COUNTER_NONFINITE]);
        L = (float3)(0.0f);
    }
    const int ring = path_pass[slot] % ring_size;
    store3(pass_ring, ring * n_pixels + path_pixel[slot], L);
#ifdef HAS_AOVS
    aov_finish(aov_path, slot, aov_ring, ring * n_pixels + path_pixel[slot]);
#endif
    atomic_inc(&counters[COUNTER_PASS_DONE + ring]);
    free_q[free_base + i] = slot;
}
