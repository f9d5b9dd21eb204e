/* Mitsuba 3's thin principled BSDF ("principledthin"): the Disney BSDF of a thin sheet (Burley
 * 2015), as Mitsuba 3 implements it (src/bsdfs/principledthin.cpp; the formulas and lobe
 * probabilities are Mitsuba's, this code is ours).  A sheet has no inside: light passes through
 * without bending, so the material is symmetric (two-sided) and a transmitted path keeps its
 * index (dielectric_eta is 1).
 *
 * Parameters (Material fields): albedo = base_color; roughness, anisotropic, spec_trans,
 * spec_tint, sheen, sheen_tint, flatness, diff_trans (in [0, 2], Mitsuba's range: halved here);
 * ior = the sheet's eta; rates = the sampling rates of the specular reflection, specular
 * transmission, diffuse transmission and diffuse reflection.
 *
 * Lobes (local frame: z the normal on wo's side; wo^ = wi mirrored to wo's side, h =
 * normalize(wo + wi^); GGX of principled.h's alphas, Smith's separable G, F_d the exact Fresnel
 * reflectance at eta; d = diff_trans / 2):
 *   specular reflection    spec_trans lerp(F_d, Schlick(tint R0(eta)), spec_tint) D G / (4 cos_o)
 *   specular transmission  spec_trans base (1 - F_d) D' G' / (4 cos_o), D', G' of the roughness
 *                          scaled by 0.65 eta - 0.35, wi = the reflection about h mirrored through
 *                          the sheet
 *   diffuse reflection     (1 - spec_trans)(1 - d) base / pi (diffuse + retro, or the fake
 *                          subsurface by flatness) + sheen
 *   diffuse transmission   (1 - spec_trans) d base / pi
 * Sampling: lobe probabilities spec_trans rate / 2 (specular reflection, transmission),
 * (1 - spec_trans)(1 - d) rate and (1 - spec_trans) d rate (diffuse), normalised; the pdf the
 * mixture, the weight f cos / pdf.  Anisotropy is relative to dp/du, as Mitsuba's sh_frame
 * (MATERIAL_FLAG_ANISOTROPIC: dispatch.h's bsdf_frame).
 */
#ifndef PYOPENCL_RT_PRINCIPLEDTHIN_H
#define PYOPENCL_RT_PRINCIPLEDTHIN_H

#include "materials/principled.h"
#include "materials/record.h"

/* f * |cos_i| and *pdf for local wo (wo.z > 0) and wi. */
RT_INLINE pvec3 principledthin_eval(const PrincipledParams *P, pint active, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    const pint ok = active & (wo.z > 0.0f);
    *pdf = PFLOAT(0.0f);
    if (!pany(ok)) return pv3_zero();
    const pfloat cos_i = wo.z, cos_o = wi.z; /* Mitsuba's names: its wi is our wo */
    const pint reflect = cos_o > 0.0f, refract = cos_o < 0.0f;
    const pfloat st = P->spec_trans, dt = P->diff_trans / 2.0f, eta = P->eta;
    const pvec3 wo_r = pv3(wi.x, wi.y, pabs(wi.z));
    const pvec3 wh = pv3_normalize(pv3_add(wo, wo_r), ok);
    const pint refl_mm = mi_mac_mic(wh, wo, wi, cos_i, PTRUE), trans_mm = mi_mac_mic(wh, wo, wi, cos_i, PINT(0));
    const pint spec_reflect = ok & (st > 0.0f) & reflect & refl_mm;
    const pint spec_trans = ok & refract & (st > 0.0f) & trans_mm;
    const pint diffuse_reflect = ok & reflect & (st < 1.0f) & (dt < 1.0f);
    const pint diffuse_trans = ok & refract & (st < 1.0f) & (dt > 0.0f);
    pfloat ax, ay, bx, by;
    principled_alphas(P->anisotropic, P->roughness, &ax, &ay);
    principled_alphas(P->anisotropic, (0.65f * eta - 0.35f) * P->roughness, &bx, &by);
    const pfloat woh = pv3_dot(wo, wh);
    pfloat cos_t, eta_ti;
    const pfloat F_d = mi_fresnel(woh, eta, &cos_t, &eta_ti);
    const pfloat lum = mi_luminance(P->base);
    const pvec3 tint = principled_tint(P->base, lum);
    pvec3 value = pv3_zero();
    if (pany(spec_reflect)) {
        const pfloat r0 = ((eta - 1.0f) / (eta + 1.0f)) * ((eta - 1.0f) / (eta + 1.0f));
        const pvec3 fs = mi_schlick3(pv3_scale(tint, r0), mi_schlick_w(woh, eta));
        const pfloat t = P->spec_tint;
        const pvec3 F = pv3(mi_lerp(F_d, fs.x, t), mi_lerp(F_d, fs.y, t), mi_lerp(F_d, fs.z, t));
        const pfloat dg = mf_d(wh, ax, ay, PINT(0)) * (mf_g1(wo, wh, ax, ay, PINT(0)) * mf_g1(wi, wh, ax, ay, PINT(0)));
        value = pv3_sel(value, pv3_add(value, pv3_scale(pv3_scale(F, st), dg / (4.0f * cos_i))), spec_reflect);
    }
    if (pany(spec_trans)) {
        const pfloat dg = mf_d(wh, bx, by, PINT(0)) * (mf_g1(wo, wh, bx, by, PINT(0)) * mf_g1(wi, wh, bx, by, PINT(0)));
        value = pv3_sel(value, pv3_add(value, pv3_scale(pv3_scale(P->base, st * (1.0f - F_d)), dg / (4.0f * cos_i))),
                        spec_trans);
    }
    if (pany(diffuse_reflect)) {
        const pfloat cos_d = pv3_dot(wh, wi);
        const pfloat k = principled_diffuse_factor(P->roughness, P->flatness, cos_i, cos_o, cos_d);
        const pfloat c = (1.0f - st) * cos_o;
        pvec3 d = pv3(c * P->base.x * INV_PI_F * (1.0f - dt) * k, c * P->base.y * INV_PI_F * (1.0f - dt) * k,
                      c * P->base.z * INV_PI_F * (1.0f - dt) * k);
        const pfloat sh = P->sheen * (1.0f - st) * schlick_weight(pabs(cos_d));
        const pfloat stt = P->sheen_tint;
        const pvec3 cs = pv3(mi_lerp(PFLOAT(1.0f), tint.x, stt), mi_lerp(PFLOAT(1.0f), tint.y, stt),
                             mi_lerp(PFLOAT(1.0f), tint.z, stt));
        d = pv3_sel(d, pv3_add(d, pv3_scale(pv3_scale(cs, sh), (1.0f - dt) * pabs(cos_o))), P->sheen > 0.0f);
        value = pv3_sel(value, pv3_add(value, d), diffuse_reflect);
    }
    if (pany(diffuse_trans)) {
        const pfloat c = (1.0f - st) * dt;
        const pvec3 d = pv3_scale(pv3_scale(P->base, c * INV_PI_F), pabs(cos_o));
        value = pv3_sel(value, pv3_add(value, d), diffuse_trans);
    }
    /* the pdf */
    pfloat p_sr = st * P->rate0 / 2.0f, p_st = st * P->rate1 / 2.0f;
    pfloat p_cr = P->rate3 * (1.0f - st) * (1.0f - dt), p_ct = P->rate2 * (1.0f - st) * dt;
    lobe_probs4(&p_sr, &p_st, &p_cr, &p_ct);
    const pfloat jac = pabs(1.0f / (4.0f * pv3_dot(wo_r, wh)));
    pfloat p = PFLOAT(0.0f);
    const pint rm = refl_mm & reflect, tm = trans_mm & refract;
    if (pany(rm & (p_sr > 0.0f))) p = rm ? p + p_sr * mf_vndf_pdf(wo, wh, ax, ay, PINT(0)) * jac : p;
    if (pany(tm & (p_st > 0.0f))) p = tm ? p + p_st * mf_vndf_pdf(wo, wh, bx, by, PINT(0)) * jac : p;
    p = reflect ? p + p_cr * (INV_PI_F * cos_o) : p;
    p = refract ? p + p_ct * (INV_PI_F * -cos_o) : p;
    const pint good = ok & pisfinite(value.x + value.y + value.z) & pisfinite(p) & (p >= 0.0f);
    *pdf = good ? p : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), value, good);
}

/* Samples wi: u2 picks the lobe (specular reflection, specular transmission, diffuse reflection,
 * diffuse transmission), (u0, u1) the direction.  Returns f |cos| / pdf, sets *pdf and *delta
 * (always 0); *wi as principled_sample's. */
RT_INLINE pvec3 principledthin_sample(const PrincipledParams *P, pint active, pvec3 wo, pfloat u0, pfloat u1,
                                      pfloat u2, pvec3 *wi, pfloat *pdf, pint *delta)
{
    *delta = PINT(0);
    *pdf = PFLOAT(0.0f);
    *wi = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    const pint up = active & (wo.z > 0.0f);
    if (!pany(up)) return pv3_zero();
    const pfloat st = P->spec_trans, dt = P->diff_trans / 2.0f;
    pfloat p_sr = st * P->rate0 / 2.0f, p_st = st * P->rate1 / 2.0f;
    pfloat p_cr = P->rate3 * (1.0f - st) * (1.0f - dt), p_ct = P->rate2 * (1.0f - st) * dt;
    lobe_probs4(&p_sr, &p_st, &p_cr, &p_ct);
    pint s_sr, s_st, s_cr, s_ct;
    pick_lobe4(up, u2, p_sr, p_st, p_cr, &s_sr, &s_st, &s_cr, &s_ct);
    pvec3 li = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f));
    pint ok = s_cr | s_ct;
    const pint spec = s_sr | s_st;
    if (pany(spec)) {
        pfloat ax, ay;
        principled_alphas(P->anisotropic, s_st ? (0.65f * P->eta - 0.35f) * P->roughness : P->roughness, &ax, &ay);
        const pvec3 m = mf_sample_vndf(wo, ax, ay, PINT(0), u0, u1, spec);
        pvec3 w = reflect_about(wo, m);
        w.z = s_st ? -w.z : w.z;
        li = pv3_sel(li, w, spec);
        ok |= s_sr & mi_mac_mic(m, wo, w, wo.z, PTRUE) & (w.z > 0.0f);
        ok |= s_st & mi_mac_mic(m, wo, w, wo.z, PINT(0)) & (w.z < 0.0f);
    }
    if (pany(s_cr | s_ct)) {
        const pvec3 c = sample_cosine_hemisphere(u0, u1);
        li = pv3_sel(li, pv3(c.x, c.y, s_ct ? -c.z : c.z), s_cr | s_ct);
    }
    *wi = li;
    if (!pany(ok)) return pv3_zero();
    pfloat q;
    const pvec3 f = principledthin_eval(P, ok, wo, li, &q);
    return sample_weight(f, q, ok, pdf);
}

#define MATERIAL_CASE_PRINCIPLEDTHIN(X) \
    X(PRINCIPLEDTHIN, principledthin, PrincipledParams, principled_params(m), principledthin_eval(&P, K, lo, li, &q), \
      principledthin_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d), pnot(PINT(0)), m->albedo)

#endif
