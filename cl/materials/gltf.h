/* The glTF 2.0 metallic-roughness material ("gltf"): a diffuse base under a GGX specular layer,
 * Fresnel-weighted, blended between dielectric and metal by `metallic`.
 *
 * Parameters (Material fields):
 *   albedo     baseColor (linear RGB in [0, 1])
 *   metallic   in [0, 1]
 *   alpha      GGX alpha = roughness^2 (glTF's perceptual roughness squared); below 1e-3 the
 *              specular layer is a perfect mirror (a delta lobe)
 *   ior        index of refraction of the dielectric (KHR_materials_ior; glTF's default 1.5),
 *              giving F0_d = ((ior - 1) / (ior + 1))^2 = 0.04 for 1.5
 *
 * Model (the glTF specification's appendix B, with an energy-conserving diffuse weight):
 *   F(c)      = Schlick with F0 = mix(F0_d, baseColor, metallic)  (linear in F0, so this equals
 *               glTF's mix of the dielectric and the metal Fresnel terms)
 *   specular  f_s = D(h) G2(wo, wi) F(wo.h) / (4 cos_o cos_i)   (as the rough conductor)
 *   diffuse   f_d = (1 - metallic) baseColor / pi (1 - Fd(cos_o)) (1 - Fd(cos_i)),
 *             Fd = Schlick with F0_d.  glTF writes the diffuse weight as (1 - F(v.h)), which is
 *             not reciprocal and lets the albedo exceed 1 at grazing angles; the product of the
 *             two directional terms (as in Ashikhmin & Shirley 2000) is reciprocal and keeps
 *             the directional albedo <= 1 (checked by tests/scene/test_materials.py).
 *   f = f_s + f_d; two-sided (the frame is flipped to wo's side).
 *
 * Sampling: the specular lobe (visible normals, Heitz 2018) with probability
 *   p_s = lum(F(cos_o)) / (lum(F(cos_o)) + (1 - metallic) lum(baseColor) (1 - Fd(cos_o))),
 * else the cosine-weighted diffuse lobe; the pdf is the mixture p_s pdf_s + (1 - p_s) cos_i / pi
 * (one-sample MIS over the lobes), the weight f cos_i / pdf.  With a smooth specular layer the
 * mirror direction is a delta sample (weight F(cos_o) / p_s) and eval/pdf cover the diffuse
 * lobe only: pdf = (1 - p_s) cos_i / pi.
 */
#ifndef PYOPENCL_RT_GLTF_H
#define PYOPENCL_RT_GLTF_H

#include "materials/microfacet.h"

typedef struct {
    float3 base;
    float metallic, alpha, f0d;
} GltfParams;

RT_INLINE float gltf_luminance(float3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

RT_INLINE float3 gltf_f0(const GltfParams *g) { return mix((float3)(g->f0d), g->base, g->metallic); }

/* probability of sampling the specular lobe for wo */
RT_INLINE float gltf_spec_prob(const GltfParams *g, float cos_o)
{
    const float ws = gltf_luminance(fresnel_schlick(gltf_f0(g), cos_o));
    const float wd = (1.0f - g->metallic) * gltf_luminance(g->base) * (1.0f - fresnel_schlick1(g->f0d, cos_o));
    const float sum = ws + wd;
    return sum > 0.0f ? clamp(ws / sum, 0.0f, 1.0f) : 1.0f;
}

RT_INLINE float3 gltf_diffuse(const GltfParams *g, float cos_o, float cos_i)
{
    return g->base * ((1.0f - g->metallic) * INV_PI_F * (1.0f - fresnel_schlick1(g->f0d, cos_o)) *
                      (1.0f - fresnel_schlick1(g->f0d, cos_i)));
}

/* f * cos_i and *pdf for local wo, wi. */
RT_INLINE float3 gltf_eval(const GltfParams *g, float3 wo, float3 wi, float *pdf)
{
    *pdf = 0.0f;
    const float cos_o = wo.z, cos_i = wi.z;
    if (cos_o <= 0.0f || cos_i <= 0.0f) return (float3)(0.0f);
    const float ps = gltf_spec_prob(g, cos_o);
    float3 f = gltf_diffuse(g, cos_o, cos_i) * cos_i;
    float p = (1.0f - ps) * cos_i * INV_PI_F;
    if (!microfacet_is_smooth(g->alpha)) {
        const float3 hs = wo + wi;
        const float len2 = dot(hs, hs);
        if (len2 > 1e-12f) {
            const float3 h = hs * rsqrt(len2);
            const float wh = dot(wo, h);
            if (wh > 0.0f) {
                const float3 fs = fresnel_schlick(gltf_f0(g), wh) *
                                  (ggx_d(h, g->alpha) * ggx_g2(wo, wi, g->alpha) / (4.0f * cos_o));
                const float ph = ggx_vndf_pdf(wo, h, g->alpha) / (4.0f * wh);
                if (isfinite(fs.x + fs.y + fs.z) && isfinite(ph)) {
                    f += fs;
                    p += ps * ph;
                }
            }
        }
    }
    *pdf = p;
    return f;
}

/* Samples wi: u.z picks the lobe, u.xy the direction.  Returns f cos / pdf; sets *pdf (0 for
 * the delta mirror and failures) and *delta. */
RT_INLINE float3 gltf_sample(const GltfParams *g, float3 wo, float3 u, float3 *wi, float *pdf, int *delta)
{
    *pdf = 0.0f;
    *delta = 0;
    if (wo.z <= 0.0f) return (float3)(0.0f);
    const float ps = gltf_spec_prob(g, wo.z);
    if (u.z < ps) {
        if (microfacet_is_smooth(g->alpha)) {
            *wi = (float3)(-wo.x, -wo.y, wo.z);
            *delta = 1;
            return fresnel_schlick(gltf_f0(g), wo.z) / ps;
        }
        *wi = reflect_about(wo, ggx_sample_vndf(wo, g->alpha, u.xy));
    } else {
        *wi = sample_cosine_hemisphere(u.xy);
    }
    if (wi->z <= 0.0f) return (float3)(0.0f);
    float p;
    const float3 f = gltf_eval(g, wo, *wi, &p);
    if (!(p > 0.0f)) return (float3)(0.0f);
    const float3 w = f / p;
    if (!isfinite(w.x + w.y + w.z)) return (float3)(0.0f);
    *pdf = p;
    return w;
}

#endif
