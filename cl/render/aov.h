/* Per-sample AOVs (arbitrary output variables), compiled with HAS_AOVS: the guide layers a
 * denoiser needs (albedo, normal) and the first hit's position and distance.  The offsets into
 * a path's AOV_FLOATS floats (aov_path[slot * AOV_FLOATS + ...]) come from the generated header
 * (pyopencl_rt/device/abi.py).
 *
 *   albedo, normal  recorded at the first hit whose material has a non-delta lobe, as Intel Open
 *                   Image Denoise asks for its guides: a mirror or glass surface passes the
 *                   albedo and normal of what is seen through it, the albedo multiplied by the
 *                   throughput of the delta bounces (their Fresnel weight and tint; sampling
 *                   reflection or refraction by Fresnel gives the Fresnel blend on average).
 *                   The normal is the geometric normal on the viewer's side, in world space.
 *                   A path that never reaches such a hit leaves both 0.
 *   position, depth the first hit (camera-relative; the host adds the camera's position) and its
 *                   distance from the ray's origin on the camera; hit = 1 when there is one.
 *
 * The albedo of a hit is the surface's reflectance seen from wo, clamped to [0, 1]: diffuse:
 * its albedo; rough conductor: its Fresnel reflectance at the viewing angle; rough dielectric:
 * its tint; glTF: the specular Fresnel term plus the diffuse base's share (its directional
 * albedo without the microfacet shadowing).
 */
#ifndef PYOPENCL_RT_AOV_H
#define PYOPENCL_RT_AOV_H

#include "materials/dispatch.h"

RT_INLINE float3 aov_albedo(__global const Material *m, float3 n, float3 wo)
{
    const float cos_o = clamp(dot(n, wo), 0.0f, 1.0f);
    float3 a = material_albedo(m);
#ifdef HAS_MATERIAL_CONDUCTOR
    if (m->type == MATERIAL_CONDUCTOR) {
        const ConductorParams c = conductor_params(m);
        a = conductor_fresnel(&c, cos_o);
    }
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
    if (m->type == MATERIAL_DIELECTRIC) a = vload3(0, m->specular);
#endif
#ifdef HAS_MATERIAL_GLTF
    if (m->type == MATERIAL_GLTF) {
        const GltfParams g = gltf_params(m);
        const float3 f0 = mix((float3)(g.f0d), g.base, g.metallic);
        a = fresnel_schlick(f0, cos_o) + (1.0f - g.metallic) * g.base * (1.0f - fresnel_schlick1(g.f0d, cos_o));
    }
#endif
    return clamp(a, 0.0f, 1.0f);
}

/* A new camera path: nothing recorded yet. */
RT_INLINE void aov_start(__global float *aov, int slot)
{
    __global float *a = aov + (size_t)slot * AOV_FLOATS;
    for (int k = 0; k < AOV_FLOATS; ++k) a[k] = 0.0f;
    a[AOV_PENDING] = 1.0f;
}

/* A hit of the path in `slot` after `depth` segments, at p (camera-relative) at distance t along
 * the ray, with n the normal on the viewer's side and beta the throughput up to it. */
RT_INLINE void aov_hit(__global float *aov, int slot, int depth, __global const Material *m, float3 n, float3 wo,
                       float3 p, float t, float3 beta)
{
    __global float *a = aov + (size_t)slot * AOV_FLOATS;
    if (depth == 0) {
        vstore3(p, 0, a + AOV_POSITION);
        a[AOV_DEPTH] = t;
        a[AOV_HIT] = 1.0f;
    }
    if (a[AOV_PENDING] != 0.0f && bsdf_has_nondelta_lobes(m)) {
        vstore3(clamp(beta * aov_albedo(m, n, wo), 0.0f, 1.0f), 0, a + AOV_ALBEDO);
        vstore3(n, 0, a + AOV_NORMAL);
        a[AOV_PENDING] = 0.0f;
    }
}

/* A finished path: its AOVs into its pass's ring entry. */
RT_INLINE void aov_finish(__global const float *aov, int slot, __global float *ring, int entry)
{
    __global const float *a = aov + (size_t)slot * AOV_FLOATS;
    __global float *r = ring + (size_t)entry * AOV_FLOATS;
    for (int k = 0; k < AOV_FLOATS; ++k) r[k] = a[k];
}

#endif
