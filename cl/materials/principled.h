/* Mitsuba 3's principled BSDF ("principled"): the Disney BSDF (Burley 2012, 2015) as Mitsuba 3
 * implements it (src/bsdfs/principled.cpp and principledhelpers.h; the formulas and lobe
 * probabilities are Mitsuba's, this code is ours).
 *
 * Parameters (Material fields): albedo = base_color; roughness, anisotropic, metallic,
 * spec_trans, spec_tint, sheen, sheen_tint, clearcoat, clearcoat_gloss, flatness; ior = eta (the
 * host derives it from `specular` as Mitsuba does: 2 / (1 - sqrt(0.08 specular)) - 1); rates =
 * the sampling rates of the main specular lobe, the clearcoat and the diffuse reflection.
 *
 * Lobes (Mitsuba's frame: z the outward normal, wi toward the viewer (our wo), wo toward the
 * light (our wi); brdf = (1 - metallic)(1 - spec_trans), bsdf = (1 - metallic) spec_trans; GGX
 * with ax = max(0.001, r^2 / a), ay = max(0.001, r^2 a), a = sqrt(1 - 0.9 anisotropic), Smith's
 * separable G; F_d the exact dielectric Fresnel at eta; h the half vector, outward):
 *   specular reflection   F_p D G / (4 |cos_i|), F_p = (1 - metallic)(1 - spec_tint) F_d
 *                         + metallic Schlick(base) + (1 - metallic) spec_tint Schlick(tint R0(eta))
 *                         from outside, bsdf F_d from inside
 *   specular transmission sqrt(base) bsdf (1 - F_d) D G eta'^2 |wi.h wo.h| / (|cos_i| (wi.h + eta' wo.h)^2)
 *                         / eta'^2 (radiance), eta' = eta or 1 / eta seen from wi's side
 *   clearcoat             0.25 clearcoat Schlick(0.04) D_GTR1 G_0.25 |cos_o| (Mitsuba's form: no
 *                         1 / (4 cos_i cos_o)), GTR1 alpha = lerp(0.1, 0.001, clearcoat_gloss)
 *   diffuse               brdf base / pi (lerp((1 - Fi/2)(1 - Fo/2) + retro, subsurface, flatness))
 *   sheen                 sheen (1 - metallic) Schlick weight(h.wo) lerp(1, base / lum, sheen_tint)
 * (diffuse, sheen and clearcoat from outside only).  Sampling: Mitsuba's lobe probabilities
 * (rates times: 1 - bsdf (1 - F_d), bsdf (1 - F_d), clearcoat / 4, brdf from outside; F_d,
 * 1 - F_d from inside, F_d at the sampled visible normal), the pdf the mixture of the lobes'
 * densities, the weight f cos / pdf.
 *
 * Sides: a lane with a transmitting part (bsdf > 0) is the interface of a solid, outside on the
 * side the geometric normal faces (`front`), as the dielectric; a lane without is two-sided, as
 * every opaque material here (Mitsuba's principled is black from behind).
 *
 * Anisotropy is relative to dp/du, as Mitsuba's sh_frame (MATERIAL_FLAG_ANISOTROPIC: dispatch.h's
 * bsdf_frame).  Deviation from Mitsuba: sheen needs the diffuse lobe (brdf > 0), as Mitsuba's scalar
 * variants compute it.
 *
 * Over the lanes (cl/render/lanes.h): PrincipledParams holds each lane's parameters; lanes outside
 * `active` give 0 (*pdf = 0, *delta = 0).  principledthin.h shares the helpers here.
 */
#ifndef PYOPENCL_RT_PRINCIPLED_H
#define PYOPENCL_RT_PRINCIPLED_H

#include "materials/microfacet.h"
#include "materials/record.h"

typedef struct {
    pvec3 base;
    pfloat roughness, anisotropic, metallic, spec_trans, spec_tint, sheen, sheen_tint, clearcoat, clearcoat_gloss,
        flatness, diff_trans, eta;
    pfloat rate0, rate1, rate2, rate3;
} PrincipledParams;

/* Dr.Jit's lerp a + (b - a) t, as b t + (a - a t) */
RT_INLINE pfloat mi_lerp(pfloat a, pfloat b, pfloat t) { return b * t + (a - a * t); }

/* Mitsuba's luminance of linear sRGB */
RT_INLINE pfloat mi_luminance(pvec3 c) { return c.x * 0.212671f + c.y * 0.715160f + c.z * 0.072169f; }

/* (1 - c)^5 of c clamped to [0, 1] */
RT_INLINE pfloat schlick_weight(pfloat c)
{
    const pfloat m = pclamp(1.0f - c, 0.0f, 1.0f);
    return (m * m) * (m * m) * m;
}

/* Mitsuba's fresnel(cos_i, eta): the reflectance, and the cosine of the transmitted direction
 * (signed, on the other side) and eta_ti = the index ratio transmitted / incident */
RT_INLINE pfloat mi_fresnel(pfloat cos_i, pfloat eta, pfloat *cos_t, pfloat *eta_ti)
{
    const pint outside = cos_i >= 0.0f;
    const pfloat rcp_eta = 1.0f / eta;
    const pfloat eta_it = outside ? eta : rcp_eta;
    const pfloat e_ti = outside ? rcp_eta : eta;
    const pfloat cos_t_sqr = 1.0f - (1.0f - cos_i * cos_i) * (e_ti * e_ti);
    const pfloat ci = pabs(cos_i), ct = psqrt(pfmax(cos_t_sqr, PFLOAT(0.0f)));
    const pfloat a_s = (ci - eta_it * ct) / (ci + eta_it * ct);
    const pfloat a_p = (ct - eta_it * ci) / (ct + eta_it * ci);
    pfloat r = 0.5f * (a_s * a_s + a_p * a_p);
    const pint matched = eta == 1.0f;
    r = (matched | (ci == 0.0f)) ? (matched ? PFLOAT(0.0f) : PFLOAT(1.0f)) : r;
    *cos_t = outside ? -ct : ct;
    *eta_ti = e_ti;
    return r;
}

/* Mitsuba's calc_schlick: R0 + (1 - R0) w, w the Schlick weight of cos_i, or of the transmitted
 * cosine where eta_it <= 1 */
RT_INLINE pfloat mi_schlick_w(pfloat cos_i, pfloat eta)
{
    const pint outside = cos_i >= 0.0f;
    const pfloat rcp_eta = 1.0f / eta;
    const pfloat eta_it = outside ? eta : rcp_eta, eta_ti = outside ? rcp_eta : eta;
    const pfloat ct2 = 1.0f - (1.0f - cos_i * cos_i) * (eta_ti * eta_ti);
    const pfloat ct = psqrt(pfmax(ct2, PFLOAT(0.0f)));
    return eta_it > 1.0f ? schlick_weight(pabs(cos_i)) : schlick_weight(ct);
}

RT_INLINE pvec3 mi_schlick3(pvec3 r0, pfloat w)
{
    return pv3(mi_lerp(w, PFLOAT(1.0f), r0.x), mi_lerp(w, PFLOAT(1.0f), r0.y), mi_lerp(w, PFLOAT(1.0f), r0.z));
}

/* Mitsuba's calc_dist_params */
RT_INLINE void principled_alphas(pfloat anisotropic, pfloat roughness, pfloat *ax, pfloat *ay)
{
    const pfloat r2 = roughness * roughness;
    const pfloat aspect = psqrt(1.0f - 0.9f * anisotropic);
    *ax = pfmax(PFLOAT(0.001f), r2 / aspect);
    *ay = pfmax(PFLOAT(0.001f), r2 * aspect);
}

/* Mitsuba's mac_mic_compatibility: wi and wo on the sides of m a reflection (or a refraction)
 * about it needs, m oriented by the sign of cos_i */
RT_INLINE pint mi_mac_mic(pvec3 m, pvec3 wi, pvec3 wo, pfloat cos_i, pint reflection)
{
    const pvec3 mm = pv3_sel(m, pv3_neg(m), cos_i < 0.0f);
    const pfloat o = pv3_dot(wo, mm);
    return (pv3_dot(wi, mm) > 0.0f) & (reflection ? o > 0.0f : o < 0.0f);
}

/* Mitsuba's refract(wi, m, cos_t, eta_ti) */
RT_INLINE pvec3 mi_refract(pvec3 wi, pvec3 m, pfloat cos_t, pfloat eta_ti)
{
    return pv3_sub(pv3_scale(m, pv3_dot(wi, m) * eta_ti + cos_t), pv3_scale(wi, eta_ti));
}

/* GTR1 (Burley 2012), the clearcoat's distribution, as Mitsuba's GTR1Isotropic */
RT_INLINE pfloat gtr1_d(pvec3 m, pfloat alpha)
{
    const pfloat c2 = m.z * m.z, a2 = alpha * alpha;
    const pfloat r = (a2 - 1.0f) / (PI_F * plog(a2) * (1.0f + (a2 - 1.0f) * c2));
    return r * m.z > 1e-20f ? r : PFLOAT(0.0f);
}

RT_INLINE pfloat gtr1_pdf(pvec3 m, pfloat alpha) { return m.z < 0.0f ? PFLOAT(0.0f) : m.z * gtr1_d(m, alpha); }

RT_INLINE pvec3 gtr1_sample(pfloat alpha, pfloat u0, pfloat u1)
{
    const pfloat phi = 2.0f * PI_F * u0;
    const pfloat a2 = alpha * alpha;
    const pfloat c2 = (1.0f - ppow(a2, 1.0f - u1)) / (1.0f - a2);
    const pfloat s = psqrt(pfmax(PFLOAT(0.0f), 1.0f - c2)), c = psqrt(pfmax(PFLOAT(0.0f), c2));
    return pv3(pcos(phi) * s, psin(phi) * s, c);
}

/* Mitsuba's smith_ggx1 (the clearcoat's masking, alpha 0.25) */
RT_INLINE pfloat mi_smith_ggx1(pvec3 v, pvec3 h, float alpha)
{
    const pfloat c = pabs(v.z), c2 = c * c;
    const pfloat t2 = (1.0f - c2) / c2;
    pfloat r = 2.0f / (1.0f + psqrt(1.0f + (alpha * alpha) * t2));
    r = v.z == 1.0f ? PFLOAT(1.0f) : r;
    return pv3_dot(v, h) * v.z <= 0.0f ? PFLOAT(0.0f) : r;
}

/* base / lum (1 where lum <= 0) */
RT_INLINE pvec3 principled_tint(pvec3 base, pfloat lum)
{
    const pint pos = lum > 0.0f;
    return pv3(pos ? base.x / lum : PFLOAT(1.0f), pos ? base.y / lum : PFLOAT(1.0f), pos ? base.z / lum : PFLOAT(1.0f));
}

/* The diffuse, retro-reflection and fake-subsurface factor and the sheen's Schlick weight */
RT_INLINE pfloat principled_diffuse_factor(pfloat roughness, pfloat flatness, pfloat cos_i, pfloat cos_o, pfloat cos_d)
{
    const pfloat fo = schlick_weight(pabs(cos_o)), fi = schlick_weight(pabs(cos_i));
    const pfloat f_diff = (1.0f - 0.5f * fi) * (1.0f - 0.5f * fo);
    const pfloat rr = 2.0f * roughness * (cos_d * cos_d);
    const pfloat f_retro = rr * (fo + fi + fo * fi * (rr - 1.0f));
    const pfloat fss90 = rr / 2.0f;
    const pfloat fss = mi_lerp(PFLOAT(1.0f), fss90, fo) * mi_lerp(PFLOAT(1.0f), fss90, fi);
    const pfloat f_ss = 1.25f * (fss * (1.0f / (pabs(cos_o) + pabs(cos_i)) - 0.5f) + 0.5f);
    return flatness != 0.0f ? mi_lerp(f_diff + f_retro, f_ss, flatness) : f_diff + f_retro;
}

/* Four lobe weights scaled to sum to 1 (the lobe probabilities) */
RT_INLINE void lobe_probs4(pfloat *a, pfloat *b, pfloat *c, pfloat *d)
{
    const pfloat rcp = 1.0f / (*a + *b + *c + *d);
    *a *= rcp;
    *b *= rcp;
    *c *= rcp;
    *d *= rcp;
}

/* The lobe u2 picks among four of probabilities a, b, c and the rest, in the lanes of `up` */
RT_INLINE void pick_lobe4(pint up, pfloat u2, pfloat a, pfloat b, pfloat c, pint *s0, pint *s1, pint *s2, pint *s3)
{
    *s0 = up & (u2 < a);
    *s1 = up & (u2 >= a) & (u2 < a + b);
    *s2 = up & (u2 >= a + b) & (u2 < a + b + c);
    *s3 = up & (u2 >= a + b + c);
}

/* Mitsuba's lobe probabilities of the principled BSDF at F_d: specular reflection and
 * transmission, clearcoat, diffuse (wo's side: front) */
RT_INLINE void principled_lobes(const PrincipledParams *P, pint front, pfloat brdf, pfloat bsdf, pfloat F_d,
                                pfloat *p_refl, pfloat *p_trans, pfloat *p_cc, pfloat *p_diff)
{
    *p_refl = front ? P->rate0 * (1.0f - bsdf * (1.0f - F_d)) : F_d;
    *p_trans = front ? P->rate0 * bsdf * (1.0f - F_d) : 1.0f - F_d;
    *p_cc = front ? 0.25f * P->clearcoat * P->rate1 : PFLOAT(0.0f);
    *p_diff = front ? brdf * P->rate2 : PFLOAT(0.0f);
    lobe_probs4(p_refl, p_trans, p_cc, p_diff);
}

/* f / pdf (pdf = q) in the lanes of `ok` where it is finite and q > 0, with *pdf = q there; 0 elsewhere */
RT_INLINE pvec3 sample_weight(pvec3 f, pfloat q, pint ok, pfloat *pdf)
{
    const pvec3 w = pv3_div(f, q);
    ok &= (q > 0.0f) & pisfinite(w.x + w.y + w.z);
    *pdf = ok ? q : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), w, ok);
}

/* f cos and the pdf in Mitsuba's frame (wi toward the viewer, z outward) */
RT_INLINE pvec3 principled_eval_mi(const PrincipledParams *P, pint active, pvec3 wi, pvec3 wo, pfloat *pdf)
{
    const pfloat cos_i = wi.z, cos_o = wo.z;
    active &= cos_i != 0.0f;
    const pfloat metallic = P->metallic;
    const pfloat brdf = (1.0f - metallic) * (1.0f - P->spec_trans), bsdf = (1.0f - metallic) * P->spec_trans;
    const pint reflect = cos_i * cos_o > 0.0f, refract = cos_i * cos_o < 0.0f;
    const pint front = cos_i > 0.0f;
    const pfloat eta = P->eta, inv_eta = 1.0f / eta;
    const pfloat eta_path = front ? eta : inv_eta, inv_eta_path = front ? inv_eta : eta;
    pfloat ax, ay;
    principled_alphas(P->anisotropic, P->roughness, &ax, &ay);
    pvec3 wh = pv3_normalize(pv3_add(wi, pv3_scale(wo, reflect ? PFLOAT(1.0f) : eta_path)), active);
    wh = pv3_sel(wh, pv3_neg(wh), wh.z < 0.0f);
    const pfloat wih = pv3_dot(wi, wh), woh = pv3_dot(wo, wh);
    pfloat cos_t, eta_ti;
    const pfloat F_d = mi_fresnel(wih, eta, &cos_t, &eta_ti);
    const pint refl_ok = mi_mac_mic(wh, wi, wo, cos_i, PTRUE), refr_ok = mi_mac_mic(wh, wi, wo, cos_i, PINT(0));
    const pint spec_reflect = active & reflect & refl_ok & (F_d > 0.0f);
    const pint clearcoat = active & (P->clearcoat > 0.0f) & reflect & refl_ok & front;
    const pint spec_trans = active & (bsdf > 0.0f) & refract & refr_ok & (F_d < 1.0f);
    const pint diffuse = active & (brdf > 0.0f) & reflect & front;
    const pint sheen = diffuse & (P->sheen > 0.0f) & (1.0f - metallic > 0.0f);
    const pfloat D = mf_d(wh, ax, ay, PINT(0));
    const pfloat G = mf_g1(wi, wh, ax, ay, PINT(0)) * mf_g1(wo, wh, ax, ay, PINT(0));
    const pfloat lum = mi_luminance(P->base);
    const pvec3 tint = principled_tint(P->base, lum);
    pvec3 value = pv3_zero();
    if (pany(spec_reflect)) {
        const pint outside = wih >= 0.0f;
        const pfloat eta_it = outside ? eta : inv_eta;
        const pfloat w = mi_schlick_w(wih, eta);
        const pfloat r0 = ((eta_it - 1.0f) / (eta_it + 1.0f)) * ((eta_it - 1.0f) / (eta_it + 1.0f));
        const pvec3 fs = pv3_add(pv3_scale(mi_schlick3(P->base, w), metallic),
                                 pv3_scale(mi_schlick3(pv3_scale(tint, r0), w), (1.0f - metallic) * P->spec_tint));
        const pfloat fd = (1.0f - metallic) * (1.0f - P->spec_tint) * F_d;
        const pfloat fb = bsdf * F_d; /* from inside: the dielectric alone */
        const pvec3 Fp = pv3_sel(pv3(fb, fb, fb), pv3(fd + fs.x, fd + fs.y, fd + fs.z), front);
        value = pv3_sel(value, pv3_add(value, pv3_scale(Fp, D * G / (4.0f * pabs(cos_i)))), spec_reflect);
    }
    if (pany(spec_trans)) {
        const pfloat scale = inv_eta_path * inv_eta_path;
        const pfloat den = wih + eta_path * woh;
        const pfloat t = pabs((scale * (1.0f - F_d) * D * G * eta_path * eta_path * wih * woh) / (cos_i * (den * den)));
        const pvec3 sb = pv3(psqrt(P->base.x), psqrt(P->base.y), psqrt(P->base.z));
        value = pv3_sel(value, pv3_add(value, pv3_scale(pv3_scale(sb, bsdf), t)), spec_trans);
    }
    const pfloat cc_alpha = mi_lerp(PFLOAT(0.1f), PFLOAT(0.001f), P->clearcoat_gloss);
    if (pany(clearcoat)) {
        const pfloat fcc = mi_lerp(mi_schlick_w(wih, eta), PFLOAT(1.0f), PFLOAT(0.04f));
        const pfloat dcc = gtr1_d(wh, cc_alpha);
        const pfloat gcc = mi_smith_ggx1(wi, wh, 0.25f) * mi_smith_ggx1(wo, wh, 0.25f);
        const pfloat c = (P->clearcoat * 0.25f) * fcc * dcc * gcc * pabs(cos_o);
        value = pv3_sel(value, pv3(value.x + c, value.y + c, value.z + c), clearcoat);
    }
    const pfloat cos_d = pv3_dot(wh, wo);
    if (pany(diffuse)) {
        const pfloat k = principled_diffuse_factor(P->roughness, P->flatness, cos_i, cos_o, cos_d);
        const pfloat bc = brdf * pabs(cos_o);
        const pvec3 d =
            pv3(bc * P->base.x * INV_PI_F * k, bc * P->base.y * INV_PI_F * k, bc * P->base.z * INV_PI_F * k);
        value = pv3_sel(value, pv3_add(value, d), diffuse);
    }
    if (pany(sheen)) {
        const pfloat fd = schlick_weight(pabs(cos_d));
        const pfloat s = P->sheen * (1.0f - metallic) * fd;
        const pfloat st = P->sheen_tint;
        const pvec3 c = pv3(mi_lerp(PFLOAT(1.0f), tint.x, st), mi_lerp(PFLOAT(1.0f), tint.y, st),
                            mi_lerp(PFLOAT(1.0f), tint.z, st));
        value = pv3_sel(value, pv3_add(value, pv3_scale(pv3_scale(c, s), pabs(cos_o))), sheen);
    }
    /* the pdf: Mitsuba's lobe probabilities at F_d(wi.h) */
    pfloat p_refl, p_trans, p_cc, p_diff;
    principled_lobes(P, front, brdf, bsdf, F_d, &p_refl, &p_trans, &p_cc, &p_diff);
    const pfloat den = wih + eta_path * woh;
    const pfloat jac = pabs(reflect ? 1.0f / (4.0f * woh) : (eta_path * eta_path * woh) / (den * den));
    const pvec3 v = pv3_sel(pv3_neg(wi), wi, front); /* Mitsuba's mulsign(wi, cos_i): wi turned outward */
    const pfloat vndf = mf_vndf_pdf(v, wh, ax, ay, PINT(0));
    const pint refl_mm = refl_ok & reflect;
    pfloat p = PFLOAT(0.0f);
    p = refl_mm ? p + p_refl * vndf * jac : p;
    p = reflect ? p + p_diff * (INV_PI_F * cos_o) : p;
    p = (refr_ok & refract) ? p + p_trans * vndf * jac : p;
    if (pany(refl_mm & (p_cc > 0.0f))) p = refl_mm ? p + p_cc * gtr1_pdf(wh, cc_alpha) * jac : p;
    const pint good = active & pisfinite(value.x + value.y + value.z) & pisfinite(p) & (p >= 0.0f);
    *pdf = good ? p : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), value, good);
}

/* Our local frame (z = the normal on wo's side) to Mitsuba's: z flipped on the lanes that see
 * a transmitting principled surface from inside */
RT_INLINE pint principled_inside(const PrincipledParams *P, pint front)
{
    return pnot(front) & ((1.0f - P->metallic) * P->spec_trans > 0.0f);
}

/* f * |cos_i| and *pdf for local wo, wi. */
RT_INLINE pvec3 principled_eval(const PrincipledParams *P, pint active, pint front, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    const pint inside = principled_inside(P, front);
    const pvec3 mwi = pv3(wo.x, wo.y, inside ? -wo.z : wo.z), mwo = pv3(wi.x, wi.y, inside ? -wi.z : wi.z);
    const pint ok = active & (wo.z > 0.0f);
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    return principled_eval_mi(P, ok, mwi, mwo, pdf);
}

/* Samples wi: u2 picks the lobe (Mitsuba's order: diffuse, clearcoat, transmission, reflection),
 * (u0, u1) the direction.  Returns f |cos| / pdf, sets *pdf and *delta (always 0).  *wi: the
 * sampled direction, also where the sample failed after drawing one; (0, 0, 1) where none was
 * drawn (wo below the surface, lanes outside `active`). */
RT_INLINE pvec3 principled_sample(const PrincipledParams *P, pint active, pint front, pvec3 wo, pfloat u0, pfloat u1,
                                  pfloat u2, pvec3 *wi, pfloat *pdf, pint *delta)
{
    *delta = PINT(0);
    *pdf = PFLOAT(0.0f);
    *wi = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    const pint up = active & (wo.z > 0.0f);
    if (!pany(up)) return pv3_zero();
    const pint inside = principled_inside(P, front);
    const pvec3 mwi = pv3(wo.x, wo.y, inside ? -wo.z : wo.z);
    const pfloat cos_i = mwi.z;
    const pint mfront = cos_i > 0.0f;
    const pfloat metallic = P->metallic;
    const pfloat brdf = (1.0f - metallic) * (1.0f - P->spec_trans), bsdf = (1.0f - metallic) * P->spec_trans;
    pfloat ax, ay;
    principled_alphas(P->anisotropic, P->roughness, &ax, &ay);
    /* visible normals of Mitsuba's mulsign(wi, cos_i): mwi turned outward (wo, or wo rotated by pi
     * about the normal from inside) */
    const pvec3 v = pv3_sel(pv3(-wo.x, -wo.y, wo.z), wo, mfront);
    const pvec3 m = mf_sample_vndf(v, ax, ay, PINT(0), u0, u1, up);
    pfloat cos_t, eta_ti;
    const pfloat F_d = mi_fresnel(pv3_dot(mwi, m), P->eta, &cos_t, &eta_ti);
    pfloat p_refl, p_trans, p_cc, p_diff;
    principled_lobes(P, mfront, brdf, bsdf, F_d, &p_refl, &p_trans, &p_cc, &p_diff);
    pint s_diff, s_cc, s_trans, s_refl;
    pick_lobe4(up, u2, p_diff, p_cc, p_trans, &s_diff, &s_cc, &s_trans, &s_refl);
    pvec3 mwo = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    pint ok = PINT(0);
    if (pany(s_refl)) {
        const pvec3 w = reflect_about(mwi, m);
        mwo = pv3_sel(mwo, w, s_refl);
        ok |= s_refl & mi_mac_mic(m, mwi, w, cos_i, PTRUE) & (cos_i * w.z > 0.0f);
    }
    if (pany(s_trans)) {
        const pvec3 w = mi_refract(mwi, m, cos_t, eta_ti);
        mwo = pv3_sel(mwo, w, s_trans);
        ok |= s_trans & mi_mac_mic(m, mwi, w, cos_i, PINT(0)) & (cos_i * w.z < 0.0f);
    }
    if (pany(s_cc)) {
        const pvec3 mc = gtr1_sample(mi_lerp(PFLOAT(0.1f), PFLOAT(0.001f), P->clearcoat_gloss), u0, u1);
        const pvec3 w = reflect_about(mwi, mc);
        mwo = pv3_sel(mwo, w, s_cc);
        ok |= s_cc & mi_mac_mic(mc, mwi, w, cos_i, PTRUE) & (cos_i * w.z > 0.0f);
    }
    if (pany(s_diff)) {
        const pvec3 w = sample_cosine_hemisphere(u0, u1);
        mwo = pv3_sel(mwo, w, s_diff);
        ok |= s_diff & (cos_i * w.z > 0.0f);
    }
    const pvec3 li = pv3(mwo.x, mwo.y, inside ? -mwo.z : mwo.z);
    *wi = pv3_sel(*wi, li, up);
    if (!pany(ok)) return pv3_zero();
    pfloat q;
    const pvec3 f = principled_eval_mi(P, ok, mwi, mwo, &q);
    return sample_weight(f, q, ok, pdf);
}

/* The parameters from the lanes' Material fields. */
RT_INLINE PrincipledParams principled_params(const MaterialLanes *m)
{
    const PrincipledParams p = {
        .base = m->albedo, .roughness = m->roughness, .anisotropic = m->anisotropic, .metallic = m->metallic,
        .spec_trans = m->spec_trans, .spec_tint = m->spec_tint, .sheen = m->sheen, .sheen_tint = m->sheen_tint,
        .clearcoat = m->clearcoat, .clearcoat_gloss = m->clearcoat_gloss, .flatness = m->flatness,
        .diff_trans = m->diff_trans, .eta = m->ior, .rate0 = m->rate0, .rate1 = m->rate1, .rate2 = m->rate2,
        .rate3 = m->rate3};
    return p;
}

#define MATERIAL_CASE_PRINCIPLED(X) \
    X(PRINCIPLED, principled, PrincipledParams, principled_params(m), principled_eval(&P, K, front, lo, li, &q), \
      principled_sample(&P, K, front, lo, u0, u1, u2, &wl, &q, &d), pnot(PINT(0)), m->albedo)

#endif
