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

#include "render/lanes.h"

#define SPAWN_ORIGIN 0.03125f          /* below this magnitude use the absolute offset */
#define SPAWN_FLOAT_SCALE 1.52587890625e-05f /* 2^-16: absolute offset near the origin */
#define SPAWN_INT_SCALE 256.0f         /* ulps per unit of normal */

RT_INLINE pfloat spawn_component(pfloat p, pfloat n)
{
    const pint of = convert_pint(SPAWN_INT_SCALE * n);
    const pfloat pi = as_pfloat(as_pint(p) + (p < 0.0f ? -of : of));
    return pabs(p) < SPAWN_ORIGIN ? p + SPAWN_FLOAT_SCALE * n : pi;
}

/* p moved off the surface to the side n points to (n: unit geometric normal on that side). */
RT_INLINE pvec3 offset_ray_origin(pvec3 p, pvec3 n)
{
    return pv3(spawn_component(p.x, n.x), spawn_component(p.y, n.y), spawn_component(p.z, n.z));
}

/* The point of triangle (p0, p1, p2) with barycentrics u, v of p1, p2 (as intersect_triangle
 * returns them), and in *err a bound on the absolute error of each coordinate. */
#define SPAWN_GAMMA7 4.172325134e-07f /* 7 * 2^-24 / (1 - 7 * 2^-24), rounded up */
RT_INLINE pvec3 triangle_point(pvec3 p0, pvec3 p1, pvec3 p2, pfloat u, pfloat v, pvec3 *err)
{
    const pfloat w = 1.0f - u - v;
    const pvec3 a = pv3_scale(p0, w), b = pv3_scale(p1, u), c = pv3_scale(p2, v);
    *err = pv3_scale(pv3_add(pv3_add(pv3_abs(a), pv3_abs(b)), pv3_abs(c)), PFLOAT(SPAWN_GAMMA7));
    return pv3_add(pv3_add(a, b), c);
}

/* x one float step away from 0 in the direction of off's sign (x itself for off = 0) */
RT_INLINE pfloat spawn_away(pfloat x, pfloat off)
{
    const pfloat moved = pnextafter_inf(x, off > 0.0f);
    return ((off > 0.0f) | (off < 0.0f)) ? moved : x;
}

/* p (error bound err per coordinate) moved off the surface to the side n points to: by pbrt's
 * dot(|n|, err) along n, rounded away from p, or by offset_ray_origin's, whichever moves
 * each coordinate farther. */
RT_INLINE pvec3 offset_ray_origin_bound(pvec3 p, pvec3 err, pvec3 n)
{
    const pvec3 off = pv3_scale(n, pv3_dot(pv3_abs(n), err));
    const pvec3 po = pv3_add(p, off);
    const pvec3 pb = pv3(spawn_away(po.x, off.x), spawn_away(po.y, off.y), spawn_away(po.z, off.z));
    const pvec3 pw = offset_ray_origin(p, n);
    const pvec3 db = pv3_abs(pv3_sub(pb, p)), dw = pv3_abs(pv3_sub(pw, p));
    return pv3(db.x > dw.x ? pb.x : pw.x, db.y > dw.y ? pb.y : pw.y, db.z > dw.z ? pb.z : pw.z);
}

/* Signed distance of q from the plane of triangle (p0, p1, p2), along its unit normal
 * (p1 - p0) x (p2 - p0): the side of a light's plane a shading point is on.  Taken from q - p0,
 * not from q - p for a point p sampled on the triangle: p's rounding error (gamma(7) |p|, see
 * triangle_point) grows with the distance from the origin, and a shading point closer to the
 * plane than that got the wrong side, so the shadow ray's far end was offset through the light
 * and the light's own triangle blocked it (tests/test_robustness.py).  Within its rounding bound
 * of 0 (rare lanes, only those in `live`) it is recomputed in double from the float vertices;
 * without fp64 it is then 0 (edge-on). */
#define PLANE_DOUBT 3.814697265625e-06f /* 2^-18: |n.a| this close to 0 (relative): sign in doubt */
RT_INLINE float plane_distance_double(float3 p0, float3 p1, float3 p2, float3 q)
{
#ifdef cl_khr_fp64
    const double3 q0 = convert_double3(p0);
    const double3 dn = cross(convert_double3(p1) - q0, convert_double3(p2) - q0);
    const double dl = length(dn);
    return dl > 0.0 ? (float)(dot(dn, convert_double3(q) - q0) / dl) : 0.0f;
#else
    return 0.0f;
#endif
}

RT_INLINE pfloat plane_distance(pvec3 p0, pvec3 p1, pvec3 p2, pvec3 q, pint live)
{
    const pvec3 e1 = pv3_sub(p1, p0), e2 = pv3_sub(p2, p0), a = pv3_sub(q, p0);
    const pvec3 n = pv3_cross(e1, e2);
    const pvec3 n_abs = pv3(pabs(e1.y * e2.z) + pabs(e1.z * e2.y), pabs(e1.z * e2.x) + pabs(e1.x * e2.z),
                            pabs(e1.x * e2.y) + pabs(e1.y * e2.x));
    const pfloat h = pv3_dot(n, a);
    pfloat r = h / pv3_length(n, live);
    const pint doubt = live & (pabs(h) <= PLANE_DOUBT * pv3_dot(n_abs, pv3_abs(a)));
    if (pany(doubt))
        for (int k = 0; k < PACKET_WIDTH; ++k)
            if (PLANE_I(doubt, k))
                PLANE(r, k) = plane_distance_double(pv3_lane(p0, k), pv3_lane(p1, k), pv3_lane(p2, k), pv3_lane(q, k));
    return r;
}

#endif
