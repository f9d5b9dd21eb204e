/* Which traversal the kernels call as bvh_closest_hit / bvh_any_hit: the binary BVH (cl/accel/bvh.h,
 * GPUs), the 4-wide BVH with BVH_WIDE or the 8-wide one with BVH_WIDE8 (CPUs).  The layout is chosen
 * on the host (pyopencl_rt/accel/device_bvh.py), which uploads the matching node buffer.
 * (The host expands each #include once, wherever it first appears, so bvh_wide.h is included
 * here for both wide layouts rather than only from bvh_wide8.h.) */
#ifndef PYOPENCL_RT_TRAVERSE_H
#define PYOPENCL_RT_TRAVERSE_H

#include "accel/bvh.h"
#if defined(BVH_WIDE) || defined(BVH_WIDE8)
#include "accel/bvh_wide.h"
#endif
#if defined(BVH_WIDE8)
#include "accel/bvh_wide8.h"
#define bvh_closest_hit bvh_wide_closest_hit8
#define bvh_any_hit bvh_wide_any_hit8
#elif defined(BVH_WIDE)
#define bvh_closest_hit bvh_wide_closest_hit4
#define bvh_any_hit bvh_wide_any_hit4
#endif

#endif
