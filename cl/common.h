/* Small helpers shared by every kernel. */
#ifndef PYOPENCL_RT_COMMON_H
#define PYOPENCL_RT_COMMON_H

/* OpenCL C lets the compiler fuse a*b - c*d into fma(a, b, -c*d) unless told otherwise.  The
 * watertight triangle test relies on the edge function of a shared edge being computed as the
 * exact negation in both triangles; a fused multiply-add breaks that symmetry and lets rays
 * through the edge miss both (tests/accel/test_intersect.py). */
#pragma OPENCL FP_CONTRACT OFF

#ifdef cl_khr_fp64
#pragma OPENCL EXTENSION cl_khr_fp64 : enable
#endif

/* Every device helper is forced inline: PoCL (LLVM) otherwise keeps hot helpers such as the
 * triangle and box tests as real calls, passing vectors and out-pointers through the stack
 * (seen with perf annotate: traversal spent a third of its time in call overhead). */
#define RT_INLINE inline __attribute__((always_inline))

/* Inline builtins on x86 CPUs (PoCL calls its own out of line). */
#include "cpu_builtins.h"

#define PI_F 3.14159265358979323846f
#define INV_PI_F 0.31830988618379067154f

RT_INLINE float3 load3(__global const float *p, int i) { return vload3(i, p); }
RT_INLINE void store3(__global float *p, int i, float3 v) { vstore3(v, i, p); }

/* Reciprocal of a direction for slab tests.  Components below 1e-18 in magnitude are clamped to
 * +-1e-18 first (as Embree's rcp_safe does): with a true 1/0 = inf, a ray lying exactly in the
 * plane of a box face computes 0 * inf = NaN and misses the box, leaking through edges that lie
 * in that plane.  With the clamp the product is 0 and the slab contains the ray. */
#define RCP_MIN_INPUT 1e-18f
RT_INLINE float safe_rcp(float x) { return 1.0f / (fabs(x) < RCP_MIN_INPUT ? copysign(RCP_MIN_INPUT, x) : x); }
RT_INLINE float3 safe_rcp3(float3 d) { return (float3)(safe_rcp(d.x), safe_rcp(d.y), safe_rcp(d.z)); }

/* pbrt-v4's Film "maxcomponentvalue": a camera sample's radiance scaled down, hue kept, so that its
 * largest component in pbrt's sensor space is at most the value.  pbrt's default sensor (cie1931)
 * records CIE XYZ, so the largest of X, Y, Z of our linear sRGB (the Rec. 709 / D65 matrix) is what
 * is bounded.  NaN and infinities pass through to the non-finite check after it.  The value is
 * MAX_COMPONENT_VALUE (a float literal) where one is compiled in, else the run-time `limit`
 * (+inf: none; PYOPENCL_RT_KERNEL_FEATURES=all); without either, the identity. */
RT_INLINE float3 clamp_sample(float3 L, float limit)
{
#if defined(MAX_COMPONENT_VALUE) || defined(MAX_COMPONENT_RUNTIME)
#ifdef MAX_COMPONENT_VALUE
    limit = MAX_COMPONENT_VALUE;
#endif
    const float x = 0.412453f * L.x + 0.357580f * L.y + 0.180423f * L.z;
    const float y = 0.212671f * L.x + 0.715160f * L.y + 0.072169f * L.z;
    const float z = 0.019334f * L.x + 0.119193f * L.y + 0.950227f * L.z;
    const float m = fmax(fmax(x, y), z);
    if (m > limit) L *= limit / m;
#endif
    return L;
}

#endif
