/* Traversal of the 8-wide BVH (pyopencl_rt/accel/bvh_wide.py, width=8) for AVX2 CPUs: closest hit
 * and any hit.
 *
 * The 4-wide traversal (bvh_wide.h) with eight lanes, from the same source (bvh_wide.tpl.h): eight child boxes per node in one float8
 * slab test and eight triangles per Tri8 packet in one float8 watertight test, one AVX2 register
 * each (as Embree's single-ray BVH8 kernels on AVX2).  cl/accel/traverse.h makes
 * bvh_closest_hit / bvh_any_hit these functions when BVH_WIDE8 is defined.
 *
 * Buffer: nodes (struct Wide8Node, 256 bytes = 8 float8s) then Tri8 packets (struct Tri8, 320 bytes
 * = 10 float8s), addressed in float8 units: a node is six float8s of child bounds (bmin_x, bmin_y,
 * bmin_z, bmax_x, bmax_y, bmax_z: lane i = child slot i), then int8 child and int8 count, with
 * bvh_wide.h's meaning (0 inner, > 0 leaf of count packets, -1 absent with an empty box).  A
 * packet is v0x, v0y, ..., v2z (float8 index 3 * vertex + axis), then int8 tri (-1 = padding lane,
 * NaN vertices).  The host makes every binary subtree of up to 8 triangles one leaf (one packet);
 * larger binary leaves (the SAH allows up to 64 triangles) span several packets.
 *
 * Stack: every 8-wide level descends three binary levels, so the depth is at most 20 and, with at
 * most 7 children pushed per node, WIDE8_STACK_SIZE = 144 entries cannot overflow (checked on the
 * host by validate_wide).  Entries are coded as in bvh_wide.h: a node offset is a multiple of 8
 * units and a slot is below 8, so a leaf's code -1 - (parent offset + slot) still decodes.
 */
#ifndef PYOPENCL_RT_BVH_WIDE8_H
#define PYOPENCL_RT_BVH_WIDE8_H

/* WideRay, wide_ray, WIDE_CODE, edge_double4, plane_t_double4, WN_ */
#include "accel/bvh_wide.h"

/* intersect_children8, tri_plane8, intersect_tri8, intersect_leaf8, occluded_leaf8, sort8,
 * wide_decode8, wide_closest_from8, wide_any_from8, bvh_wide_closest_hit8, bvh_wide_any_hit8 */
#define WN 8
#include "accel/bvh_wide.tpl.h"
#undef WN

#endif
