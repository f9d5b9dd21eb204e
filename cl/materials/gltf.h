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
 *
 * Over the lanes (cl/render/lanes.h): GltfParams holds each lane's parameters; lanes outside
 * `active` give 0 (*pdf = 0, *delta = 0).
 */
#ifndef PYOPENCL_RT_GLTF_H
#define PYOPENCL_RT_GLTF_H

#include "materials/microfacet.h"
#include "materials/record.h"

typedef struct {
    pvec3 base;
    pfloat metallic, alpha, f0d;
} GltfParams;

RT_INLINE pfloat gltf_luminance(pvec3 c) { return 0.2126f * c.x + 0.7152f * c.y + 0.0722f * c.z; }

/* mix(f0d, base, metallic) */
RT_INLINE pvec3 gltf_f0(const GltfParams *g)
{
    const pfloat f = g->f0d, t = g->metallic;
    return pv3(f + (g->base.x - f) * t, f + (g->base.y - f) * t, f + (g->base.z - f) * t);
}

/* probability of sampling the specular lobe for wo */
RT_INLINE pfloat gltf_spec_prob(const GltfParams *g, pfloat cos_o)
{
    const pfloat ws = gltf_luminance(fresnel_schlick(gltf_f0(g), cos_o));
    const pfloat wd = (1.0f - g->metallic) * gltf_luminance(g->base) * (1.0f - fresnel_schlick1(g->f0d, cos_o));
    const pfloat sum = ws + wd;
    return sum > 0.0f ? pclamp(ws / sum, 0.0f, 1.0f) : PFLOAT(1.0f);
}

RT_INLINE pvec3 gltf_diffuse(const GltfParams *g, pfloat cos_o, pfloat cos_i)
{
    return pv3_scale(g->base, (1.0f - g->metallic) * INV_PI_F * (1.0f - fresnel_schlick1(g->f0d, cos_o)) *
                                  (1.0f - fresnel_schlick1(g->f0d, cos_i)));
}

/* f * cos_i and *pdf for local wo, wi. */
RT_INLINE pvec3 gltf_eval(const GltfParams *g, pint active, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    const pfloat cos_o = wo.z, cos_i = wi.z;
    const pint ok = active & pnot((cos_o <= 0.0f) | (cos_i <= 0.0f));
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    const pfloat ps = gltf_spec_prob(g, cos_o);
    pvec3 f = pv3_scale(gltf_diffuse(g, cos_o, cos_i), cos_i);
    pfloat p = (1.0f - ps) * cos_i * INV_PI_F;
    const pint rough = ok & pnot(microfacet_is_smooth(g->alpha));
    if (pany(rough)) {
        const pvec3 hs = pv3_add(wo, wi);
        const pfloat len2 = pv3_dot(hs, hs);
        const pvec3 h = pv3_scale(hs, microfacet_rsqrt(len2));
        const pfloat wh = pv3_dot(wo, h);
        const pvec3 fs = pv3_scale(fresnel_schlick(gltf_f0(g), wh),
                                   ggx_d(h, g->alpha) * ggx_g2(wo, wi, g->alpha) / (4.0f * cos_o));
        const pfloat ph = ggx_vndf_pdf(wo, h, g->alpha) / (4.0f * wh);
        const pint spec = rough & (len2 > 1e-12f) & (wh > 0.0f) & pisfinite(fs.x + fs.y + fs.z) & pisfinite(ph);
        f = pv3_sel(f, pv3_add(f, fs), spec);
        p = spec ? p + ps * ph : p;
    }
    *pdf = ok ? p : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), f, ok);
}

/* Samples wi: u2 picks the lobe, (u0, u1) the direction.  Returns f cos / pdf; sets *pdf (0 for
 * the delta mirror and failures) and *delta (mask).  *wi: the sampled direction, also where the
 * sample failed after drawing one; (0, 0, 1) where none was drawn (wo below the surface, lanes
 * outside `active`). */
RT_INLINE pvec3 gltf_sample(const GltfParams *g, pint active, pvec3 wo, pfloat u0, pfloat u1, pfloat u2, pvec3 *wi,
                            pfloat *pdf, pint *delta)
{
    const pint up = active & pnot(wo.z <= 0.0f);
    const pfloat ps = gltf_spec_prob(g, wo.z);
    const pint spec = up & (u2 < ps);
    const pint smooth = spec & microfacet_is_smooth(g->alpha);
    const pint rough = spec & pnot(smooth);
    const pint diffuse = up & pnot(spec);
    pvec3 li = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    if (pany(rough)) li = pv3_sel(li, reflect_about(wo, ggx_sample_vndf(wo, g->alpha, u0, u1, rough)), rough);
    if (pany(diffuse)) li = pv3_sel(li, sample_cosine_hemisphere(u0, u1), diffuse);
    li = pv3_sel(li, pv3(-wo.x, -wo.y, wo.z), smooth);
    pfloat p;
    const pint drawn = (rough | diffuse) & pnot(li.z <= 0.0f);
    const pvec3 f = gltf_eval(g, drawn, wo, li, &p);
    const pvec3 w = pv3_div(f, p);
    const pint ok = drawn & (p > 0.0f) & pisfinite(w.x + w.y + w.z);
    *wi = li;
    *pdf = ok ? p : PFLOAT(0.0f);
    *delta = smooth;
    pvec3 r = pv3_sel(pv3_zero(), w, ok);
    if (pany(smooth)) r = pv3_sel(r, pv3_div(fresnel_schlick(gltf_f0(g), wo.z), ps), smooth);
    return r;
}

/* The parameters from the lanes' Material fields. */
RT_INLINE GltfParams gltf_params(const MaterialLanes *m)
{
    const pfloat r = (m->ior - 1.0f) / (m->ior + 1.0f);
    const GltfParams g = {.base = m->albedo, .metallic = pclamp(m->metallic, 0.0f, 1.0f), .alpha = m->alpha,
                          .f0d = pisfinite(r) ? r * r : PFLOAT(0.0f)};
    return g;
}

/* the albedo guide: the specular Fresnel term plus the diffuse base's share, (1 - metallic) base (1 - Fd) */
RT_INLINE pvec3 gltf_albedo(const MaterialLanes *m, pfloat cos_o)
{
    const GltfParams g = gltf_params(m);
    const pfloat s = 1.0f - fresnel_schlick1(g.f0d, cos_o);
    const pvec3 d = pv3_scale(pv3_scale(g.base, 1.0f - g.metallic), s);
    return pv3_add(fresnel_schlick(gltf_f0(&g), cos_o), d);
}

#define MATERIAL_CASE_GLTF(X) \
    X(GLTF, gltf, GltfParams, gltf_params(m), gltf_eval(&P, K, lo, li, &q), \
      gltf_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d), pnot(microfacet_is_smooth(m->alpha)) | (m->metallic < 1.0f), \
      gltf_albedo(m, cos_o))

#endif
