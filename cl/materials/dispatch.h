/* BSDF dispatch on Material.type.  Each material lives in cl/materials/<name>.h with its
 * documentation at the top; this file only routes calls and unpacks the Material record
 * (pyopencl_rt/device/abi.py documents its fields).
 *
 * Materials compiled in: all of them, unless the host defines MATERIALS_SELECTED together with
 * HAS_MATERIAL_<NAME> for the types a scene uses (Scene.material_defines() gives that set), so
 * a scene need pay only for what it uses.  MATERIAL_DIFFUSE is always compiled (the fallback).
 *
 * Interface (used by cl/wavefront/shade.cl):
 *   n      the unit geometric normal flipped to wo's side
 *   front  1 when wo lies on the side the geometric normal points to (the outside: a sphere's
 *          outward normal, a triangle's (v1 - v0) x (v2 - v0)); dielectrics refract into the
 *          inside then, with relative index ior, else out of it with 1 / ior
 *   wo, wi unit directions away from the surface (toward the viewer / toward the light)
 *
 *   bsdf_eval(m, n, front, wo, wi, &pdf)   f(wo, wi) |cos(theta_i)|, and the solid-angle pdf of
 *            bsdf_sample drawing wi; both 0 for delta (perfectly specular) lobes
 *   bsdf_sample(m, n, front, wo, u, &wi, &pdf, &delta)   draws wi from u in [0,1)^3 (u.xy: the
 *            direction, u.z: the choice of lobe / reflection or refraction) and returns the
 *            weight f |cos| / pdf.  *delta = 1 for a sample of a delta lobe: then *pdf is 0
 *            (no density exists; callers skip MIS and treat the next emitter hit as seen by a
 *            specular path) and the weight is the lobe's (Fresnel) factor over its selection
 *            probability.  A failed sample returns weight 0 with *pdf = 0 and *delta = 0.
 *   bsdf_has_nondelta_lobes(m)  0 when every lobe is a delta lobe (light sampling is useless)
 */
#ifndef PYOPENCL_RT_BSDF_H
#define PYOPENCL_RT_BSDF_H

#include "materials/diffuse.h"
#include "materials/conductor.h"
#include "materials/dielectric.h"
#include "materials/gltf.h"

/* MATERIAL_<TYPE> and MATERIAL_FLAG_* come from the generated header (pyopencl_rt/device/abi.py). */

#ifndef MATERIALS_SELECTED
#define HAS_MATERIAL_CONDUCTOR
#define HAS_MATERIAL_DIELECTRIC
#define HAS_MATERIAL_GLTF
#endif

RT_INLINE float3 material_albedo(__global const Material *m) { return vload3(0, m->albedo); }
RT_INLINE float3 material_emission(__global const Material *m) { return vload3(0, m->emission); }

RT_INLINE ConductorParams conductor_params(__global const Material *m)
{
    ConductorParams c;
    c.f0 = vload3(0, m->specular);
    c.eta = vload3(0, m->eta);
    c.k = vload3(0, m->k);
    c.alpha = m->alpha;
    c.schlick = (m->flags & MATERIAL_FLAG_CONDUCTOR_F0) != 0;
    return c;
}

RT_INLINE GltfParams gltf_params(__global const Material *m)
{
    GltfParams g;
    g.base = vload3(0, m->albedo);
    g.metallic = clamp(m->metallic, 0.0f, 1.0f);
    g.alpha = m->alpha;
    const float r = (m->ior - 1.0f) / (m->ior + 1.0f);
    g.f0d = isfinite(r) ? r * r : 0.0f;
    return g;
}

RT_INLINE float dielectric_eta(__global const Material *m, int front)
{
    const float ior = m->ior > 0.0f ? m->ior : 1.0f;
    return front ? ior : 1.0f / ior;
}

RT_INLINE int bsdf_has_nondelta_lobes(__global const Material *m)
{
    switch (m->type) {
#ifdef HAS_MATERIAL_CONDUCTOR
    case MATERIAL_CONDUCTOR: return !microfacet_is_smooth(m->alpha);
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
    case MATERIAL_DIELECTRIC: return !dielectric_is_smooth(m->alpha, m->ior);
#endif
#ifdef HAS_MATERIAL_GLTF
    case MATERIAL_GLTF: return !microfacet_is_smooth(m->alpha) || m->metallic < 1.0f;
#endif
    default: return 1;
    }
}

RT_INLINE float3 bsdf_eval(__global const Material *m, float3 n, int front, float3 wo, float3 wi, float *pdf)
{
    const int type = m->type;
    if (type == MATERIAL_DIFFUSE) return diffuse_eval(material_albedo(m), n, wi, pdf);
    float3 t, b;
    make_onb(n, &t, &b);
    const float3 lo = to_local(wo, t, b, n), li = to_local(wi, t, b, n);
#ifdef HAS_MATERIAL_CONDUCTOR
    if (type == MATERIAL_CONDUCTOR) {
        const ConductorParams c = conductor_params(m);
        return conductor_eval(&c, lo, li, pdf);
    }
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
    if (type == MATERIAL_DIELECTRIC)
        return dielectric_eval(m->alpha, dielectric_eta(m, front), vload3(0, m->specular), lo, li, pdf);
#endif
#ifdef HAS_MATERIAL_GLTF
    if (type == MATERIAL_GLTF) {
        const GltfParams g = gltf_params(m);
        return gltf_eval(&g, lo, li, pdf);
    }
#endif
    return diffuse_eval(material_albedo(m), n, wi, pdf);
}

RT_INLINE float3 bsdf_sample(__global const Material *m, float3 n, int front, float3 wo, float3 u, float3 *wi,
                             float *pdf, int *delta)
{
    const int type = m->type;
    *delta = 0;
    if (type == MATERIAL_DIFFUSE) return diffuse_sample(material_albedo(m), n, u.xy, wi, pdf);
    float3 t, b;
    make_onb(n, &t, &b);
    const float3 lo = to_local(wo, t, b, n);
    float3 li = (float3)(0.0f, 0.0f, 1.0f);
    float3 w;
    int handled = 0;
#ifdef HAS_MATERIAL_CONDUCTOR
    if (type == MATERIAL_CONDUCTOR) {
        const ConductorParams c = conductor_params(m);
        w = conductor_sample(&c, lo, u, &li, pdf, delta);
        handled = 1;
    }
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
    if (type == MATERIAL_DIELECTRIC) {
        w = dielectric_sample(m->alpha, dielectric_eta(m, front), vload3(0, m->specular), lo, u, &li, pdf, delta);
        handled = 1;
    }
#endif
#ifdef HAS_MATERIAL_GLTF
    if (type == MATERIAL_GLTF) {
        const GltfParams g = gltf_params(m);
        w = gltf_sample(&g, lo, u, &li, pdf, delta);
        handled = 1;
    }
#endif
    if (!handled) return diffuse_sample(material_albedo(m), n, u.xy, wi, pdf);
    *wi = normalize(to_world(li, t, b, n));
    if (!isfinite(w.x + w.y + w.z) || !isfinite(wi->x + wi->y + wi->z)) {
        *pdf = 0.0f;
        *delta = 0;
        return (float3)(0.0f);
    }
    return w;
}

#endif
