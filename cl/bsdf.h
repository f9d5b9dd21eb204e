/* BSDF dispatch on Material.type.  Each material lives in cl/materials/<name>.h with its
 * documentation at the top; this file only routes calls.  Materials compiled in are chosen by
 * the host (defines HAS_MATERIAL_<NAME>), so a scene pays only for what it uses. */
#ifndef PYOPENCL_RT_BSDF_H
#define PYOPENCL_RT_BSDF_H

#include "materials/diffuse.h"

#define MATERIAL_DIFFUSE 0

RT_INLINE float3 material_albedo(__global const Material *m) { return vload3(0, m->albedo); }
RT_INLINE float3 material_emission(__global const Material *m) { return vload3(0, m->emission); }

/* f * |cos(theta_i)| for directions wo (toward the viewer) and wi (toward the light); n is the
 * unit geometric normal flipped to wo's side.  *pdf: solid-angle pdf of sampling wi. */
RT_INLINE float3 bsdf_eval(__global const Material *m, float3 n, float3 wo, float3 wi, float *pdf)
{
    return diffuse_eval(material_albedo(m), n, wi, pdf);
}

/* Samples wi; returns f * |cos| / pdf, sets *wi and *pdf (0 when the sample failed). */
RT_INLINE float3 bsdf_sample(__global const Material *m, float3 n, float3 wo, float2 u, float3 *wi, float *pdf)
{
    return diffuse_sample(material_albedo(m), n, u, wi, pdf);
}

#endif
