/* Spawning rays off surfaces without self-intersection.
 *
 * The origin of a spawned ray is moved off the surface along the geometric normal by a fixed
 * number of float ulps (Wächter & Binder, "A Fast and Robust Method for Avoiding
 * Self-Intersection", Ray Tracing Gems ch. 6): an offset proportional to the magnitude of each
 * coordinate, so it scales with the hit point's own rounding error at any distance from the
 * origin, plus a small absolute offset near zero where ulps become tiny.
 */
#ifndef PYOPENCL_RT_SPAWN_H
#define PYOPENCL_RT_SPAWN_H

#include "common.h"

#define SPAWN_ORIGIN 0.03125f          /* below this magnitude use the absolute offset */
#define SPAWN_FLOAT_SCALE 1.52587890625e-05f /* 2^-16: absolute offset near the origin */
#define SPAWN_INT_SCALE 256.0f         /* ulps per unit of normal */

RT_INLINE float spawn_component(float p, float n)
{
    const int of = (int)(SPAWN_INT_SCALE * n);
    const float pi = as_float(as_int(p) + (p < 0.0f ? -of : of));
    return fabs(p) < SPAWN_ORIGIN ? p + SPAWN_FLOAT_SCALE * n : pi;
}

/* p moved off the surface to the side n points to (n: unit geometric normal on that side). */
RT_INLINE float3 offset_ray_origin(float3 p, float3 n)
{
    return (float3)(spawn_component(p.x, n.x), spawn_component(p.y, n.y), spawn_component(p.z, n.z));
}

#endif
