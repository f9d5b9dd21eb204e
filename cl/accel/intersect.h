/* Ray/primitive intersection: triangle (watertight), box (slab test), sphere (stable quadratic).
 *
 * Rays are o + t*d with t in [tmin, tmax].  Directions need not be normalised.
 */
#ifndef PYOPENCL_RT_INTERSECT_H
#define PYOPENCL_RT_INTERSECT_H

#include "render/lanes.h"

/* ---------------------------------------------------------------------------------------------
 * Watertight ray/triangle intersection (Woop, Benthin & Wald, JCGT 2013).
 *
 * The ray is transformed so that it runs along +z from the origin (a shear and a permutation of
 * axes that depend on the ray alone).  The 2D edge functions U, V, W of the projected triangle are
 * then evaluated in a way that gives the same value for an edge shared by two triangles, so a ray
 * through an edge or a vertex hits at least one of them.  When an edge function rounds to exactly
 * zero the paper recomputes it in double precision; we do the same where the device has fp64.
 * --------------------------------------------------------------------------------------------- */
typedef struct {
    uint4 perm;       /* (kx, ky, kz, 3): kz is the dominant axis of d; applied with shuffle() */
    float sx, sy, sz; /* shear constants */
} RayShear;

RT_INLINE float comp3(float3 v, int k) { return k == 0 ? v.x : (k == 1 ? v.y : v.z); }

RT_INLINE RayShear ray_shear(float3 d)
{
    RayShear r;
    const float3 ad = fabs(d);
    const uint kz = (ad.x > ad.y) ? ((ad.x > ad.z) ? 0u : 2u) : ((ad.y > ad.z) ? 1u : 2u);
    uint kx = kz == 2u ? 0u : kz + 1u;
    uint ky = kx == 2u ? 0u : kx + 1u;
    const float dz = comp3(d, (int)kz);
    if (dz < 0.0f) { const uint tmp = kx; kx = ky; ky = tmp; } /* keep the winding */
    r.perm = (uint4)(kx, ky, kz, 3u);
    const float4 dp = shuffle((float4)(d, 0.0f), r.perm);
    r.sx = dp.x / dz;
    r.sy = dp.y / dz;
    r.sz = 1.0f / dz;
    return r;
}

#define SLIVER_CANCELLATION 0.03125f   /* 2^-5: |n| below this share of its products: refine */
#define NUM_DOUBT 3.814697265625e-06f  /* 2^-18: n.a this close to 0 (relative): sign in doubt */

/* The plane of triangle (p0, p1, p2): its normal n = (p1 - p0) x (p2 - p0), the magnitudes of
 * the products each component of n is made of (*n_abs: the rounding bound of n.a below), and in
 * *sliver whether n cancelled by more than SLIVER_CANCELLATION (see intersect_triangle).  The
 * same arithmetic on a Tri8's eight triangles: tri_plane4 / tri_plane8 (bvh_wide.tpl.h), which the single-ray
 * and the packet tests (bvh_packet.h) take their planes from. */
RT_INLINE float3 triangle_plane(float3 p0, float3 p1, float3 p2, float3 *n_abs, int *sliver)
{
    const float3 e1 = p1 - p0, e2 = p2 - p0;
    const float3 n = cross(e1, e2);
    *n_abs = fabs(e1.yzx * e2.zxy) + fabs(e1.zxy * e2.yzx);
    *sliver = fabs(n.x) + fabs(n.y) + fabs(n.z) < SLIVER_CANCELLATION * (n_abs->x + n_abs->y + n_abs->z);
    return n;
}

/* The edge functions U, V, W (Woop et al.) of the triangle whose vertices, relative to the ray's
 * origin and permuted to (kx, ky, kz), are A, B, C, sheared by (sx, sy) (ray_shear): declares the
 * sheared ax, ay, bx, by, cx, cy and U, V, W of type T (float, or a vector of lanes: the wide and
 * packet tests, bvh_wide.tpl.h and bvh_packet.h, in the same order). */
#define SHEARED_EDGES(T, Ax, Ay, Az, Bx, By, Bz, Cx, Cy, Cz, sx, sy) \
    const T ax = (Ax) - (sx) * (Az), ay = (Ay) - (sy) * (Az); \
    const T bx = (Bx) - (sx) * (Bz), by = (By) - (sy) * (Bz); \
    const T cx = (Cx) - (sx) * (Cz), cy = (Cy) - (sy) * (Cz); \
    T U = cx * by - cy * bx; \
    T V = ax * cy - ay * cx; \
    T W = bx * ay - by * ax

/* Returns 1 and sets *t, *u, *v (barycentrics of v1 and v2) on a hit with tmin < t < tmax. */
RT_INLINE int intersect_triangle(float3 o, float3 d, RayShear s, float3 p0, float3 p1, float3 p2,
                              float tmin, float tmax, float *t, float *u, float *v)
{
    const float3 a = p0 - o, b = p1 - o, c = p2 - o;
    /* vertices relative to the origin, axes permuted to (kx, ky, kz) */
    const float4 ap = shuffle((float4)(a, 0.0f), s.perm);
    const float4 bp = shuffle((float4)(b, 0.0f), s.perm);
    const float4 cp = shuffle((float4)(c, 0.0f), s.perm);
    SHEARED_EDGES(float, ap.x, ap.y, ap.z, bp.x, bp.y, bp.z, cp.x, cp.y, cp.z, s.sx, s.sy);
#ifdef cl_khr_fp64
    if (U == 0.0f || V == 0.0f || W == 0.0f) {
        U = (float)((double)cx * (double)by - (double)cy * (double)bx);
        V = (float)((double)ax * (double)cy - (double)ay * (double)cx);
        W = (float)((double)bx * (double)ay - (double)by * (double)ax);
    }
#endif
    if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f))
        return 0;
    const float det = U + V + W;
    if (det == 0.0f)
        return 0;
    /* The distance comes from the plane equation with the normal built from edge vectors, not
     * from the paper's T = U*Az + V*Bz + W*Cz: for a long sliver whose far vertices are much
     * farther than the hit, T cancels catastrophically and its sign can flip, so a ray leaving a
     * thin closed mesh from inside was judged "behind" and escaped (tests/accel/test_traversal.py). */
    float3 n_abs;
    int sliver;
    const float3 n = triangle_plane(p0, p1, p2, &n_abs, &sliver);
    const float den = dot(n, d);
    const float num = dot(n, a);
    /* On a sliver the float32 cross product cancels (|n| much smaller than the products it is
     * made of) and its direction is off by ~eps / sin(angle): the sign of n.a was wrong from
     * origins near the plane (a spawned ray re-hit its own triangle) and t was off by up to 5e-2
     * (tests/test_robustness.py).  When n cancelled by more than 32x, or n.a is within its
     * rounding bound of zero, t is recomputed in double from the float vertices (exact
     * differences); without fp64 a hit whose sign is in doubt is rejected, as pbrt does. */
    const int doubt = fabs(num) <= NUM_DOUBT * dot(n_abs, fabs(a));
    float tt;
#ifdef cl_khr_fp64
    if (sliver || doubt) {
        const double3 q0 = convert_double3(p0);
        const double3 dn = cross(convert_double3(p1) - q0, convert_double3(p2) - q0);
        const double dden = dot(dn, convert_double3(d));
        if (dden == 0.0)
            return 0;
        tt = (float)(dot(dn, q0 - convert_double3(o)) / dden);
    } else
#else
    if (doubt)
        return 0;
#endif
    {
        if (den == 0.0f)
            return 0;
        tt = num / den;
    }
    if (!(tt > tmin && tt < tmax))
        return 0;
    const float rcp = 1.0f / det;
    *t = tt;
    *u = V * rcp;
    *v = W * rcp;
    return 1;
}

/* safe_rcp (common.h) over the lanes: 1 / x with |x| below RCP_MIN_INPUT clamped to it (the packets',
 * the shapes' and the media grids' slab tests) */
RT_INLINE pfloat psafe_rcp(pfloat x)
{
    return 1.0f / (pabs(x) < RCP_MIN_INPUT ? pcopysign(PFLOAT(RCP_MIN_INPUT), x) : x);
}

/* ---------------------------------------------------------------------------------------------
 * Ray/box slab test.  inv_d = safe_rcp3(d) (finite, so no 0*inf = NaN for a ray in the plane of
 * a face: such a ray is inside that slab).  Returns the entry distance, or INFINITY on a miss.
 *
 * Conservative on purpose.  Rounding in the box test alone is covered by widening the far
 * distance by 1 + 2*gamma(3) (Ize 2013), but the watertight triangle test has its own rounding,
 * of a few ulp of |vertex - origin|: a ray that crosses exactly at a triangle edge lying on its
 * leaf box's boundary can be "inside" the triangle yet "outside" its box, and leak between two
 * triangles (long slivers do this; tests/accel/test_traversal.py).  So the far distance is widened
 * by 2^-20 (relative, which covers origins far from the box), and the host pads every box by
 * 2^-20 of the scene's largest coordinate (pyopencl_rt/accel/device_bvh.py: padded_nodes), which covers
 * origins near or inside it.
 * --------------------------------------------------------------------------------------------- */
#define SLAB_FAR_SCALE 1.00000095367431640625f /* 1 + 2^-20 */

RT_INLINE float intersect_box(float3 o, float3 inv_d, float3 bmin, float3 bmax, float tmin, float tmax)
{
    const float3 t0 = (bmin - o) * inv_d;
    const float3 t1 = (bmax - o) * inv_d;
    const float3 tn = fmin(t0, t1), tf = fmax(t0, t1);
    const float enter = fmax(fmax(tn.x, tn.y), fmax(tn.z, tmin));
    const float leave = fmin(fmin(tf.x, tf.y), tf.z) * SLAB_FAR_SCALE;
    return (enter <= fmin(leave, tmax)) ? enter : INFINITY;
}

/* ---------------------------------------------------------------------------------------------
 * Ray/sphere with a numerically stable quadratic.
 *
 * |o + t d - c|^2 = r^2 with f = o - c gives a t^2 + 2 b' t + cc = 0, where a = d.d, b' = f.d
 * (half the usual b, so the discriminant is b'^2 - a cc, with no factor 4), cc = f.f - r^2.
 * The discriminant is evaluated as a (r^2 - |f - (b'/a) d|^2) = a (r - l)(r + l), which avoids the
 * cancellation of b'^2 - a cc for a small sphere far away; the roots are q/a and cc/q with
 * q = -(b' + sign(b') sqrt(disc)), which avoids cancellation in -b' +- sqrt(disc)
 * (Haines et al., Ray Tracing Gems ch. 7).  Over the lanes (cl/render/lanes.h): returns the mask of
 * the lanes of `live` with a root in (tmin, tmax), *t set to the nearest there (else unchanged).
 * --------------------------------------------------------------------------------------------- */
RT_INLINE pint intersect_sphere(pvec3 o, pvec3 d, pvec3 center, pfloat radius, pfloat tmin, pfloat tmax, pfloat *t,
                               pint live)
{
    const pvec3 f = pv3_sub(o, center);
    const pfloat a = pv3_dot(d, d);
    const pfloat bh = pv3_dot(f, d);
    const pfloat cc = pv3_dot(f, f) - radius * radius;
    const pvec3 lvec = pv3_sub(f, pv3_scale(d, bh / a));
    const pfloat l = pv3_length(lvec, live);
    const pfloat disc = a * (radius - l) * (radius + l);
    const pfloat q = -(bh + pcopysign(psqrt(disc), bh));
    const pint tangent = q == 0.0f; /* ray origin at the centre's tangent point: both roots 0 */
    const pfloat r0 = tangent ? PFLOAT(0.0f) : q / a, r1 = tangent ? PFLOAT(0.0f) : cc / q;
    const pfloat t0 = r0 > r1 ? r1 : r0, t1 = r0 > r1 ? r0 : r1;
    const pint near = (t0 > tmin) & (t0 < tmax);
    const pint hit = live & (disc >= 0.0f) & (near | ((t1 > tmin) & (t1 < tmax)));
    *t = hit ? (near ? t0 : t1) : *t;
    return hit;
}

#endif
