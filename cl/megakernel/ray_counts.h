/* The megakernels' ray counts: each work-item's, summed over its work-group in local memory and
 * added to counters[] once per group (two global atomics per work-item, contended by every CPU
 * thread, cost 3.5% of the kernel: perf).  Every work-item of the group must call it (barrier). */
#ifndef PYOPENCL_RT_RAY_COUNTS_H
#define PYOPENCL_RT_RAY_COUNTS_H

#include "common.h"

/* group_rays: 2 * group_size ints of local memory */
RT_INLINE void add_group_ray_counts(__local int *group_rays, int group_size, int n_extend, int n_shadow,
                                    __global int *counters)
{
    const int lid = get_local_id(0);
    group_rays[lid] = n_extend;
    group_rays[group_size + lid] = n_shadow;
    barrier(CLK_LOCAL_MEM_FENCE);
    if (lid == 0) {
        int extend = 0, shadow = 0;
        for (int k = 0; k < group_size; ++k) {
            extend += group_rays[k];
            shadow += group_rays[group_size + k];
        }
        atomic_add(&counters[COUNTER_RAYS_EXTEND], extend);
        atomic_add(&counters[COUNTER_RAYS_SHADOW], shadow);
    }
}

#endif
