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
 *                   The normal is the BSDF's (the geometric normal, or the shading normal of
 *                   cl/scene/shading.h) on the viewer's side, in world space.
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

/* A new camera path: nothing recorded yet. */
RT_INLINE void aov_start(__global float *aov, int slot)
{
    __global float *a = aov + (size_t)slot * AOV_FLOATS;
    for (int k = 0; k < AOV_FLOATS; ++k) a[k] = 0.0f;
    a[AOV_PENDING] = 1.0f;
}

/* The hits of the lanes of `hit` (path in `slot`) after `depth` segments, at p (camera-relative)
 * at distance t along the ray, with n the normal on the viewer's side and beta the throughput up
 * to it; lane by lane (each lane writes its own path's record). */
RT_INLINE void aov_hit(__global float *aov, pint slot, pint hit, pint depth, const MaterialLanes *m, pvec3 n, pvec3 wo,
                       pvec3 p, pfloat t, pvec3 beta)
{
    const pint albedo_wanted = hit & bsdf_has_nondelta_lobes(m);
    const pvec3 albedo = material_albedo_aov(m, n, wo);
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        if (!PLANE_I(hit, k)) continue;
        __global float *a = aov + (size_t)PLANE_I(slot, k) * AOV_FLOATS;
        if (PLANE_I(depth, k) == 0) {
            vstore3(pv3_lane(p, k), 0, a + AOV_POSITION);
            a[AOV_DEPTH] = PLANE(t, k);
            a[AOV_HIT] = 1.0f;
        }
        if (a[AOV_PENDING] != 0.0f && PLANE_I(albedo_wanted, k)) {
            vstore3(clamp(pv3_lane(beta, k) * pv3_lane(albedo, k), 0.0f, 1.0f), 0, a + AOV_ALBEDO);
            vstore3(pv3_lane(n, k), 0, a + AOV_NORMAL);
            a[AOV_PENDING] = 0.0f;
        }
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
