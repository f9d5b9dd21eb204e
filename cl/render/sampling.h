/* Sampling routines and their densities, over the lanes (cl/render/lanes.h).  Local frames have
 * z up (the normal, or the cone axis); direction pdfs are with respect to solid angle.  Inputs u
 * are uniform in [0, 1). */
#ifndef PYOPENCL_RT_SAMPLING_H
#define PYOPENCL_RT_SAMPLING_H

#include "render/lanes.h"

/* Orthonormal, right-handed basis (t, b, n) around the unit vector n: cross(t, b) = n.
 * Duff et al. 2017, "Building an Orthonormal Basis, Revisited" (branchless, copysign picks the
 * hemisphere so 1 / (sign + n.z) never divides by a small number). */
RT_INLINE void make_onb(pvec3 n, pvec3 *t, pvec3 *b)
{
    const pfloat sign = pcopysign(PFLOAT(1.0f), n.z);
    const pfloat a = -1.0f / (sign + n.z);
    const pfloat c = n.x * n.y * a;
    *t = pv3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    *b = pv3(c, sign + n.y * n.y * a, -n.y);
}

/* (`local` is an OpenCL address-space keyword, hence v for the local-frame vector) */
RT_INLINE pvec3 to_world(pvec3 v, pvec3 t, pvec3 b, pvec3 n)
{
    return pv3_add(pv3_add(pv3_scale(t, v.x), pv3_scale(b, v.y)), pv3_scale(n, v.z));
}

RT_INLINE pvec3 to_local(pvec3 w, pvec3 t, pvec3 b, pvec3 n) { return pv3(pv3_dot(w, t), pv3_dot(w, b), pv3_dot(w, n)); }

/* sin and cos of |x| <= pi/4 by their Taylor series to x^9 / x^10: the truncation error is
 * below 2e-9, under float rounding, and there is no argument reduction (the library sin/cos
 * spent a visible share of shading reducing arguments, per `perf`, and are called lane by
 * lane). */
#define SIN_QUARTER(x, x2) ((x) * (1.0f + (x2) * (-1.0f / 6.0f + (x2) * (1.0f / 120.0f + (x2) * (-1.0f / 5040.0f + (x2) * (1.0f / 362880.0f))))))
#define COS_QUARTER(x2) (1.0f + (x2) * (-0.5f + (x2) * (1.0f / 24.0f + (x2) * (-1.0f / 720.0f + (x2) * (1.0f / 40320.0f + (x2) * (-1.0f / 3628800.0f))))))

/* Shirley & Chiu's concentric map of the square onto the unit disk: pdf 1/pi per unit area.
 * The angle is (pi/4) * ratio with |ratio| <= 1, or pi/2 minus that, which swaps sin and cos. */
RT_INLINE void sample_concentric_disk(pfloat ux, pfloat uy, pfloat *dx, pfloat *dy)
{
    const pfloat ox = 2.0f * ux - 1.0f, oy = 2.0f * uy - 1.0f;
    const pint wide_x = pabs(ox) > pabs(oy);
    const pfloat major = wide_x ? ox : oy, minor = wide_x ? oy : ox;
    const pfloat x = (0.25f * PI_F) * (minor / major);
    const pfloat x2 = x * x;
    const pfloat s = SIN_QUARTER(x, x2), c = COS_QUARTER(x2);
    const pint center = (ox == 0.0f) & (oy == 0.0f);
    *dx = center ? PFLOAT(0.0f) : major * (wide_x ? c : s); /* cos(pi/2 - a) = sin a */
    *dy = center ? PFLOAT(0.0f) : major * (wide_x ? s : c);
}

/* Cosine-weighted hemisphere (Malley's method: lift the uniform disk): pdf cos(theta) / pi. */
RT_INLINE pvec3 sample_cosine_hemisphere(pfloat ux, pfloat uy)
{
    pfloat dx, dy;
    sample_concentric_disk(ux, uy, &dx, &dy);
    return pv3(dx, dy, psqrt(pfmax(PFLOAT(0.0f), 1.0f - dx * dx - dy * dy)));
}

/* max(cos_theta, 0) / pi */
RT_INLINE pfloat pdf_cosine_hemisphere(pfloat cos_theta) { return pfmax(cos_theta, PFLOAT(0.0f)) * INV_PI_F; }

/* Uniform over the unit sphere: pdf 1 / (4 pi). */
RT_INLINE pvec3 sample_uniform_sphere(pfloat ux, pfloat uy)
{
    const pfloat z = 1.0f - 2.0f * ux;
    const pfloat r = psqrt(pfmax(PFLOAT(0.0f), (1.0f - z) * (1.0f + z)));
    const pfloat phi = 2.0f * PI_F * uy;
    return pv3(r * pcos(phi), r * psin(phi), z);
}

/* 1 / (4 pi) */
RT_INLINE float pdf_uniform_sphere(void) { return 0.25f * INV_PI_F; }

/* Uniform over the cone of directions with cos(theta) >= cos_max around +z, cos_max in (-1, 1):
 * pdf 1 / (2 pi (1 - cos_max)).  1 - cos(theta) is computed directly (not as 1 - cos) so narrow
 * cones keep their precision; cos(theta) is clamped to [cos_max, 1] against rounding. */
RT_INLINE pvec3 sample_uniform_cone(pfloat ux, pfloat uy, pfloat cos_max)
{
    const pfloat one_minus_cos = ux * (1.0f - cos_max);
    const pfloat cos_theta = pfmin(pfmax(1.0f - one_minus_cos, cos_max), PFLOAT(1.0f));
    const pfloat sin_theta = psqrt(pfmax(PFLOAT(0.0f), one_minus_cos * (2.0f - one_minus_cos)));
    const pfloat phi = 2.0f * PI_F * uy;
    return pv3(sin_theta * pcos(phi), sin_theta * psin(phi), cos_theta);
}

/* 1 / (2 pi (1 - cos_max)), inside the cone (the caller checks cos(theta) >= cos_max). */
RT_INLINE pfloat pdf_uniform_cone(pfloat cos_max) { return 1.0f / (2.0f * PI_F * (1.0f - cos_max)); }

/* Uniform barycentrics (b1, b2) = weights of v1 and v2 (Heitz 2019, "A Low-Distortion Map Between
 * Triangle and Square"): p = (1 - b1 - b2) v0 + b1 v1 + b2 v2 has pdf 1 / area.  b1, b2 >= 0 and
 * b1 + b2 = max(u.x, u.y) < 1. */
RT_INLINE void sample_triangle_barycentrics(pfloat ux, pfloat uy, pfloat *b1, pfloat *b2)
{
    const pint upper = uy > ux;
    const pfloat h1 = 0.5f * ux, h2 = 0.5f * uy;
    *b1 = upper ? h1 : ux - h2;
    *b2 = upper ? uy - h1 : h2;
}

/* Picks light i with probability lights[i].pmf from the alias table built on the host
 * (pyopencl_rt/render/sampling.py): column floor(u n) is kept with probability alias_prob, else its
 * alias is taken, the fractional part of u n deciding.  Sets *pmf = lights[i].pmf, and *u_reused to
 * that fractional part rescaled to [0, 1) within the branch taken (pbrt-v4's uRemapped): uniform
 * and independent of the pick, with about 24 - log2(n) bits. */
RT_INLINE pint sample_alias(__global const Light *lights, int n, pfloat u, pfloat *pmf, pfloat *u_reused)
{
    const pfloat x = u * (float)n;
    pint i = convert_pint(x);
    i = i < n - 1 ? i : PINT(n - 1);
    const pfloat frac = x - convert_pfloat(i);
    __global const float *light_f = (__global const float *)lights;
    __global const int *light_i = (__global const int *)lights;
    const pint column = i * STRIDE_INDEX(Light);
    const pfloat prob = pgather(light_f, column + FIELD_INDEX(Light, alias_prob));
    const pint kept = frac < prob;
    const pint pick = kept ? i : pgather_int(light_i, column + FIELD_INDEX(Light, alias));
    *pmf = pgather(light_f, pick * STRIDE_INDEX(Light) + FIELD_INDEX(Light, pmf));
    *u_reused = pclamp(kept ? frac / prob : (frac - prob) / (1.0f - prob), 0.0f, 0x1.fffffep-1f);
    return pick;
}

/* Veach's power heuristic (beta = 2): pdf_a^2 / (pdf_a^2 + pdf_b^2), computed as
 * 1 / (1 + (pdf_b / pdf_a)^2) so large pdfs do not overflow.  1 when pdf_b == 0 (also for
 * pdf_a == 0), 1 for pdf_a = inf, 0 for pdf_b = inf, 0.5 when both are inf; never NaN for
 * non-NaN inputs. */
RT_INLINE pfloat power_heuristic(pfloat pdf_a, pfloat pdf_b)
{
    const pfloat r = pdf_b / pdf_a;
    pfloat w = 1.0f / (1.0f + r * r);
    w = pisinf(pdf_a) ? (pisinf(pdf_b) ? PFLOAT(0.5f) : PFLOAT(1.0f)) : w;
    return pdf_b == 0.0f ? PFLOAT(1.0f) : w;
}

#endif
