/* Lambertian diffuse reflection ("diffuse").
 *
 * f(wo, wi) = albedo / pi for wo and wi on the same side of the surface, 0 otherwise.  The
 * material is two-sided, as pbrt's DiffuseMaterial and Mitsuba's twosided(diffuse): the frame
 * is flipped to the side wo lies on.  Sampling is cosine-weighted (pdf = cos(theta_i) / pi), so
 * the sample weight f * cos / pdf is exactly the albedo.
 *
 * Parameters: albedo (linear RGB in [0, 1]).
 */
#ifndef PYOPENCL_RT_DIFFUSE_H
#define PYOPENCL_RT_DIFFUSE_H

#include "render/sampling.h"

/* n is the unit normal on the side of wo.  Returns f * |cos(theta_i)|, sets *pdf. */
RT_INLINE float3 diffuse_eval(float3 albedo, float3 n, float3 wi, float *pdf)
{
    const float cos_i = dot(n, wi);
    if (cos_i <= 0.0f) { *pdf = 0.0f; return (float3)(0.0f); }
    *pdf = cos_i * INV_PI_F;
    return albedo * (cos_i * INV_PI_F);
}

/* Samples wi; returns the weight f * cos / pdf (= albedo) and sets *pdf. */
RT_INLINE float3 diffuse_sample(float3 albedo, float3 n, float2 u, float3 *wi, float *pdf)
{
    float3 t, b;
    make_onb(n, &t, &b);
    const float3 h = sample_cosine_hemisphere(u);
    *wi = normalize(to_world(h, t, b, n));
    *pdf = pdf_cosine_hemisphere(h.z);
    if (*pdf <= 0.0f) return (float3)(0.0f);
    return albedo;
}

#endif
