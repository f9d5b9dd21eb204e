/* Sampling routines and their densities.  Local frames have z up (the normal, or the cone axis);
 * direction pdfs are with respect to solid angle.  Inputs u are uniform in [0, 1). */
#ifndef PYOPENCL_RT_SAMPLING_H
#define PYOPENCL_RT_SAMPLING_H

#include "common.h"

/* Orthonormal, right-handed basis (t, b, n) around the unit vector n: cross(t, b) = n.
 * Duff et al. 2017, "Building an Orthonormal Basis, Revisited" (branchless, copysign picks the
 * hemisphere so 1 / (sign + n.z) never divides by a small number). */
RT_INLINE void make_onb(float3 n, float3 *t, float3 *b)
{
    const float sign = copysign(1.0f, n.z);
    const float a = -1.0f / (sign + n.z);
    const float c = n.x * n.y * a;
    *t = (float3)(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    *b = (float3)(c, sign + n.y * n.y * a, -n.y);
}

/* (`local` is an OpenCL address-space keyword, hence v for the local-frame vector) */
RT_INLINE float3 to_world(float3 v, float3 t, float3 b, float3 n)
{
    return v.x * t + v.y * b + v.z * n;
}

RT_INLINE float3 to_local(float3 w, float3 t, float3 b, float3 n)
{
    return (float3)(dot(w, t), dot(w, b), dot(w, n));
}

/* sin and cos of |x| <= pi/4 by their Taylor series to x^9 / x^10: the truncation error is
 * below 2e-9, under float rounding, and there is no argument reduction (the library sin/cos
 * spent a visible share of the shade stage reducing arguments, per `perf`). */
/* The two series as expressions of x and x2 = x * x, for floats or vectors of them (the lane
 * sampler, cl/render/path_lanes.h, evaluates the same polynomials). */
#define SIN_QUARTER(x, x2) ((x) * (1.0f + (x2) * (-1.0f / 6.0f + (x2) * (1.0f / 120.0f + (x2) * (-1.0f / 5040.0f + (x2) * (1.0f / 362880.0f))))))
#define COS_QUARTER(x2) (1.0f + (x2) * (-0.5f + (x2) * (1.0f / 24.0f + (x2) * (-1.0f / 720.0f + (x2) * (1.0f / 40320.0f + (x2) * (-1.0f / 3628800.0f))))))
RT_INLINE float2 sincos_quarter(float x)
{
    const float x2 = x * x;
    return (float2)(SIN_QUARTER(x, x2), COS_QUARTER(x2));
}

/* Shirley & Chiu's concentric map of the square onto the unit disk: pdf 1/pi per unit area.
 * The angle is (pi/4) * ratio with |ratio| <= 1, or pi/2 minus that, which swaps sin and cos. */
RT_INLINE float2 sample_concentric_disk(float2 u)
{
    const float2 o = 2.0f * u - 1.0f;
    if (o.x == 0.0f && o.y == 0.0f)
        return (float2)(0.0f, 0.0f);
    if (fabs(o.x) > fabs(o.y)) {
        const float2 sc = sincos_quarter((0.25f * PI_F) * (o.y / o.x));
        return o.x * (float2)(sc.y, sc.x);
    }
    const float2 sc = sincos_quarter((0.25f * PI_F) * (o.x / o.y));
    return o.y * (float2)(sc.x, sc.y); /* cos(pi/2 - a) = sin a, sin(pi/2 - a) = cos a */
}

/* Cosine-weighted hemisphere (Malley's method: lift the uniform disk): pdf cos(theta) / pi. */
RT_INLINE float3 sample_cosine_hemisphere(float2 u)
{
    const float2 d = sample_concentric_disk(u);
    const float z = sqrt(fmax(0.0f, 1.0f - d.x * d.x - d.y * d.y));
    return (float3)(d.x, d.y, z);
}

/* max(cos_theta, 0) / pi */
RT_INLINE float pdf_cosine_hemisphere(float cos_theta) { return fmax(cos_theta, 0.0f) * INV_PI_F; }

/* Uniform over the unit sphere: pdf 1 / (4 pi). */
RT_INLINE float3 sample_uniform_sphere(float2 u)
{
    const float z = 1.0f - 2.0f * u.x;
    const float r = sqrt(fmax(0.0f, (1.0f - z) * (1.0f + z)));
    const float phi = 2.0f * PI_F * u.y;
    return (float3)(r * cos(phi), r * sin(phi), z);
}

/* 1 / (4 pi) */
RT_INLINE float pdf_uniform_sphere(void) { return 0.25f * INV_PI_F; }

/* Uniform over the cone of directions with cos(theta) >= cos_max around +z, cos_max in (-1, 1):
 * pdf 1 / (2 pi (1 - cos_max)).  1 - cos(theta) is computed directly (not as 1 - cos) so narrow
 * cones keep their precision; cos(theta) is clamped to [cos_max, 1] against rounding. */
RT_INLINE float3 sample_uniform_cone(float2 u, float cos_max)
{
    const float one_minus_cos = u.x * (1.0f - cos_max);
    const float cos_theta = clamp(1.0f - one_minus_cos, cos_max, 1.0f);
    const float sin_theta = sqrt(fmax(0.0f, one_minus_cos * (2.0f - one_minus_cos)));
    const float phi = 2.0f * PI_F * u.y;
    return (float3)(sin_theta * cos(phi), sin_theta * sin(phi), cos_theta);
}

/* 1 / (2 pi (1 - cos_max)), inside the cone (the caller checks cos(theta) >= cos_max). */
RT_INLINE float pdf_uniform_cone(float cos_max) { return 1.0f / (2.0f * PI_F * (1.0f - cos_max)); }

/* Uniform barycentrics (b1, b2) = weights of v1 and v2 (Heitz 2019, "A Low-Distortion Map Between
 * Triangle and Square"): p = (1 - b1 - b2) v0 + b1 v1 + b2 v2 has pdf 1 / area.  b1, b2 >= 0 and
 * b1 + b2 = max(u.x, u.y) < 1. */
RT_INLINE float2 sample_triangle_barycentrics(float2 u)
{
    float b1, b2;
    if (u.y > u.x) {
        b1 = 0.5f * u.x;
        b2 = u.y - b1;
    } else {
        b2 = 0.5f * u.y;
        b1 = u.x - b2;
    }
    return (float2)(b1, b2);
}

/* Picks light i with probability lights[i].pmf from the alias table built on the host
 * (pyopencl_rt/render/sampling.py): column floor(u n) is kept with probability alias_prob, else its
 * alias is taken, the fractional part of u n deciding.  Sets *pmf = lights[i].pmf. */
RT_INLINE int sample_alias(__global const Light *lights, int n, float u, float *pmf)
{
    const float x = u * (float)n;
    int i = min((int)x, n - 1);
    const float frac = x - (float)i;
    if (frac >= lights[i].alias_prob)
        i = lights[i].alias;
    *pmf = lights[i].pmf;
    return i;
}

/* Veach's power heuristic (beta = 2): pdf_a^2 / (pdf_a^2 + pdf_b^2), computed as
 * 1 / (1 + (pdf_b / pdf_a)^2) so large pdfs do not overflow.  1 when pdf_b == 0 (also for
 * pdf_a == 0), 1 for pdf_a = inf, 0 for pdf_b = inf, 0.5 when both are inf; never NaN for
 * non-NaN inputs. */
RT_INLINE float power_heuristic(float pdf_a, float pdf_b)
{
    if (pdf_b == 0.0f)
        return 1.0f;
    if (isinf(pdf_a))
        return isinf(pdf_b) ? 0.5f : 1.0f;
    const float r = pdf_b / pdf_a;
    return 1.0f / (1.0f + r * r);
}

#endif
