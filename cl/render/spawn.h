/* Spawning rays off surfaces without self-intersection.
 *
 * The origin of a spawned ray is moved off the surface along the geometric normal by a fixed
 * number of float ulps (Wächter & Binder, "A Fast and Robust Method for Avoiding
 * Self-Intersection", Ray Tracing Gems ch. 6): an offset proportional to the magnitude of each
 * coordinate, so it scales with the hit point's own rounding error at any distance from the
 * origin, plus a small absolute offset near zero where ulps become tiny.
 *
 * That offset is only a bound on the error of p when p's error is a few ulps of p's own
 * coordinates, which holds for a point interpolated from the triangle's vertices with the hit's
 * barycentrics (triangle_point below), but not for p = o + t*d: that point carries the rounding
 * of o and of t*d, a few ulps of |o| + t|d|, so a camera or a previous hit 1000x farther away
 * than the surface is large puts p on the wrong side of the surface by more than the offset
 * (tests/test_robustness.py measured 2.7% self-hits for origins up to 1e3 triangle sizes away).
 * triangle_point() also returns pbrt's bound on p's error (Pharr, Jakob & Humphreys, PBR 4th
 * ed., 6.8.6: gamma(7) * sum |b_i p_i|), and offset_ray_origin_bound() offsets by that bound
 * and by Wächter & Binder's, whichever is larger in each coordinate.
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

/* The point of triangle (p0, p1, p2) with barycentrics u, v of p1, p2 (as intersect_triangle
 * returns them), and in *err a bound on the absolute error of each coordinate. */
#define SPAWN_GAMMA7 4.172325134e-07f /* 7 * 2^-24 / (1 - 7 * 2^-24), rounded up */
RT_INLINE float3 triangle_point(float3 p0, float3 p1, float3 p2, float u, float v, float3 *err)
{
    const float w = 1.0f - u - v;
    *err = SPAWN_GAMMA7 * (fabs(w * p0) + fabs(u * p1) + fabs(v * p2));
    return w * p0 + u * p1 + v * p2;
}

RT_INLINE float spawn_away(float x, float off)
{
    return off > 0.0f ? nextafter(x, INFINITY) : (off < 0.0f ? nextafter(x, -INFINITY) : x);
}

/* p (error bound err per coordinate) moved off the surface to the side n points to: by pbrt's
 * dot(|n|, err) along n, rounded away from p, or by offset_ray_origin's, whichever moves
 * each coordinate farther. */
RT_INLINE float3 offset_ray_origin_bound(float3 p, float3 err, float3 n)
{
    const float3 off = dot(fabs(n), err) * n;
    const float3 po = p + off;
    const float3 pb = (float3)(spawn_away(po.x, off.x), spawn_away(po.y, off.y), spawn_away(po.z, off.z));
    const float3 pw = offset_ray_origin(p, n);
    return select(pw, pb, isgreater(fabs(pb - p), fabs(pw - p)));
}

/* Signed distance of q from the plane of triangle (p0, p1, p2), along its unit normal
 * (p1 - p0) x (p2 - p0): the side of a light's plane a shading point is on.  Taken from q - p0,
 * not from q - p for a point p sampled on the triangle: p's rounding error (gamma(7) |p|, see
 * triangle_point) grows with the distance from the origin, and a shading point closer to the
 * plane than that got the wrong side, so the shadow ray's far end was offset through the light
 * and the light's own triangle blocked it (tests/test_robustness.py).  Within its rounding bound
 * of 0 it is recomputed in double from the float vertices; without fp64 it is then 0 (edge-on). */
#define PLANE_DOUBT 3.814697265625e-06f /* 2^-18: |n.a| this close to 0 (relative): sign in doubt */
RT_INLINE float plane_distance(float3 p0, float3 p1, float3 p2, float3 q)
{
    const float3 e1 = p1 - p0, e2 = p2 - p0, a = q - p0;
    const float3 n = cross(e1, e2);
    const float3 n_abs = fabs(e1.yzx * e2.zxy) + fabs(e1.zxy * e2.yzx);
    const float h = dot(n, a);
    if (fabs(h) <= PLANE_DOUBT * dot(n_abs, fabs(a))) {
#ifdef cl_khr_fp64
        const double3 q0 = convert_double3(p0);
        const double3 dn = cross(convert_double3(p1) - q0, convert_double3(p2) - q0);
        const double dl = length(dn);
        return dl > 0.0 ? (float)(dot(dn, convert_double3(q) - q0) / dl) : 0.0f;
#else
        return 0.0f;
#endif
    }
    return h / length(n);
}

#endif
