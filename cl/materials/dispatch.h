/* BSDF dispatch on Material.type, over the lanes (cl/render/lanes.h).  Each material lives in
 * cl/materials/<name>.h with its documentation at the top; this file only gathers the Material
 * records into the lanes (pyopencl_rt/device/abi.py documents their fields) and routes calls.
 *
 * Materials compiled in: all of them, unless the host defines MATERIALS_SELECTED together with
 * HAS_MATERIAL_<NAME> for the types a scene uses (Scene.material_defines() gives that set), so
 * a scene need pay only for what it uses.  MATERIAL_DIFFUSE is always compiled (the fallback:
 * a type not compiled in shades as diffuse).
 *
 * Dispatch over lanes: a material type's code runs when some active lane has that type (pany),
 * over all lanes, and its results are selected into the lanes of that type.  Each lane gets
 * exactly what the one-material (width-1) code computes for it, so every width gives the same
 * bits.
 *
 * Interface (used by cl/render/path.h; all arguments per lane; masks as lanes.h defines them):
 *   m      the lanes' materials: material_lanes(materials, index) gathers the records
 *          (textures are applied to them by the caller, cl/scene/textures.h)
 *   active the mask of the lanes to compute; the others give weight / f 0, *pdf 0, *delta 0
 *          (bsdf_sample sets their *wi to n)
 *   n      the unit geometric normal flipped to wo's side
 *   tangent the frame's tangent direction (need not be unit nor orthogonal to n; Mitsuba's dp/du):
 *          the x axis of the local frame of the lanes with MATERIAL_FLAG_ANISOTROPIC (anisotropic
 *          conductors, dielectrics, principled), made orthogonal to n; where it is zero or parallel
 *          to n, and for every other lane, the local frame is make_onb(n) (any frame: their BSDFs
 *          are isotropic)
 *   front  mask: the lanes where wo lies on the side the geometric normal points to (the
 *          outside: a sphere's outward normal, a triangle's (v1 - v0) x (v2 - v0)); dielectrics
 *          refract into the inside then, with relative index ior, else out of it with 1 / ior
 *   wo, wi unit directions away from the surface (toward the viewer / toward the light)
 *
 *   bsdf_eval(m, active, n, front, wo, wi, &pdf)   f(wo, wi) |cos(theta_i)|, and the solid-angle
 *            pdf of bsdf_sample drawing wi; both 0 for delta (perfectly specular) lobes
 *   bsdf_sample(m, active, n, front, wo, u0, u1, u2, &wi, &pdf, &delta)   draws wi from u0, u1,
 *            u2 in [0, 1) (u0, u1: the direction, u2: the choice of lobe / reflection or
 *            refraction) and returns the weight f |cos| / pdf.  *delta (mask) is set for a
 *            sample of a delta lobe: then *pdf is 0 (no density exists; callers skip MIS and
 *            treat the next emitter hit as seen by a specular path) and the weight is the
 *            lobe's (Fresnel) factor over its selection probability.  A failed sample returns
 *            weight 0 with *pdf = 0 and *delta = 0 (a non-finite weight or direction of a
 *            non-diffuse lobe, too); its *wi means nothing.
 *   bsdf_has_nondelta_lobes(m)  mask: 0 where every lobe is a delta lobe (light sampling is
 *            useless)
 *   dielectric_eta(m, front)   the relative index eta = eta_t / eta_i seen by wo (ior or
 *            1 / ior; 1 for ior <= 0 and for principledthin, whose sheet does not bend light): a
 *            refracted sample scales radiance by 1 / eta^2
 *   material_albedo_aov(m, n, wo)   the albedo guide of cl/render/aov.h: the surface's
 *            reflectance seen from wo, clamped to [0, 1] (diffuse: its albedo; conductor: its
 *            Fresnel reflectance at the viewing angle; dielectric: its tint; glTF: the specular
 *            Fresnel term plus the diffuse base's share; the Mitsuba types: their diffuse
 *            reflectance or base colour, as Mitsuba's eval_diffuse_reflectance)
 *
 * A mix (materials/mix.h) never reaches these functions: cl/render/path.h resolves it to one of the
 * records it blends first (so the albedo AOV is that record's, the one picked for the path).
 *
 * The Mitsuba 3 types (plastic, roughplastic, principled, principledthin) read the Material
 * fields after the texture indices; material_lanes() gathers those only when some lane has such
 * a type.  roughplastic reads its table from the records themselves (MaterialLanes.records/rec).
 */
#ifndef PYOPENCL_RT_DISPATCH_H
#define PYOPENCL_RT_DISPATCH_H

#include "materials/diffuse.h"
#include "materials/conductor.h"
#include "materials/dielectric.h"
#include "materials/gltf.h"
#include "materials/plastic.h"
#include "materials/roughplastic.h"
#include "materials/principled.h"
#include "materials/principledthin.h"

/* MATERIAL_<TYPE> and MATERIAL_FLAG_* come from the generated header (pyopencl_rt/device/abi.py). */

#ifndef MATERIALS_SELECTED
#define HAS_MATERIAL_CONDUCTOR
#define HAS_MATERIAL_DIELECTRIC
#define HAS_MATERIAL_GLTF
#define HAS_MATERIAL_PLASTIC
#define HAS_MATERIAL_ROUGHPLASTIC
#define HAS_MATERIAL_PRINCIPLED
#define HAS_MATERIAL_PRINCIPLEDTHIN
#define HAS_MATERIAL_MIX
#endif
#if defined(HAS_MATERIAL_PLASTIC) || defined(HAS_MATERIAL_ROUGHPLASTIC) || defined(HAS_MATERIAL_PRINCIPLED) || \
    defined(HAS_MATERIAL_PRINCIPLEDTHIN)
#define HAS_MITSUBA_MATERIALS /* the Material fields after the texture indices are used */
#endif

/* The Material records' fields, per lane.  The fields of the Mitsuba types (fdr to rates) are
 * gathered only when some lane has such a type (else 0). */
typedef struct {
    pint type, flags;
    pvec3 albedo, emission, specular, eta, k;
    pfloat alpha, alpha_v, metallic, ior;
    pint tex_base, tex_mr, tex_emission; /* texture indices, -1 none */
    pfloat opacity; /* MATERIAL_FLAG_MASK: the record's opacity (times its texture, cl/scene/textures.h); else 1 */
    pfloat fdr, spec_weight, roughness, anisotropic, spec_trans, spec_tint, sheen, sheen_tint, clearcoat,
        clearcoat_gloss, flatness, diff_trans, rate0, rate1, rate2, rate3;
    __global const float *records; /* the Material array as floats, and each lane's record in it */
    pint rec;
} MaterialLanes;

/* materials[index] in each lane (index valid in every lane) */
RT_INLINE MaterialLanes material_lanes(__global const Material *materials, pint index)
{
    const pint i = index * STRIDE_INDEX(Material); /* the lanes' records, as float indices */
    __global const float *f = (__global const float *)materials;
    MaterialLanes m;
    /* m.x = the lanes' field x of their records */
#define GATHER_INT(x) m.x = pgather_int((__global const int *)materials, i + FIELD_INDEX(Material, x));
#define GATHER_VEC3(x) m.x = pv3_gather(f, i + FIELD_INDEX(Material, x));
#define GATHER_FLOAT(x) m.x = pgather(f, i + FIELD_INDEX(Material, x));
    GATHER_INT(type) GATHER_INT(flags) GATHER_INT(tex_base) GATHER_INT(tex_mr) GATHER_INT(tex_emission)
    GATHER_VEC3(albedo) GATHER_VEC3(emission) GATHER_VEC3(specular) GATHER_VEC3(eta) GATHER_VEC3(k)
    GATHER_FLOAT(alpha) GATHER_FLOAT(alpha_v) GATHER_FLOAT(metallic) GATHER_FLOAT(ior)
    m.records = f;
    m.rec = i;
    m.opacity = PFLOAT(1.0f);
    const pint masked = (m.flags & MATERIAL_FLAG_MASK) != 0;
    if (pany(masked)) m.opacity = masked ? pgather(f, i + FIELD_INDEX(Material, opacity)) : m.opacity;
    m.fdr = m.spec_weight = m.roughness = m.anisotropic = m.spec_trans = m.spec_tint = m.sheen = m.sheen_tint =
        m.clearcoat = m.clearcoat_gloss = m.flatness = m.diff_trans = m.rate0 = m.rate1 = m.rate2 = m.rate3 =
            PFLOAT(0.0f);
#ifdef HAS_MITSUBA_MATERIALS
    if (pany(m.type >= MATERIAL_PLASTIC)) {
        GATHER_FLOAT(fdr) GATHER_FLOAT(spec_weight) GATHER_FLOAT(roughness) GATHER_FLOAT(anisotropic)
        GATHER_FLOAT(spec_trans) GATHER_FLOAT(spec_tint) GATHER_FLOAT(sheen) GATHER_FLOAT(sheen_tint)
        GATHER_FLOAT(clearcoat) GATHER_FLOAT(clearcoat_gloss) GATHER_FLOAT(flatness) GATHER_FLOAT(diff_trans)
        m.rate0 = pgather(f, i + FIELD_INDEX(Material, rates));
        m.rate1 = pgather(f, i + FIELD_INDEX(Material, rates) + 1);
        m.rate2 = pgather(f, i + FIELD_INDEX(Material, rates) + 2);
        m.rate3 = pgather(f, i + FIELD_INDEX(Material, rates) + 3);
    }
#endif
#undef GATHER_INT
#undef GATHER_VEC3
#undef GATHER_FLOAT
    return m;
}

/* The microfacet distribution of a conductor or dielectric (microfacet.h): alpha (alpha_u) and,
 * with MATERIAL_FLAG_ANISOTROPIC, alpha_v; *smooth: the lanes whose alphas are all below the
 * smooth threshold (a delta lobe). */
RT_INLINE Microfacet microfacet_params(const MaterialLanes *m, pint *smooth)
{
    const pfloat ay = (m->flags & MATERIAL_FLAG_ANISOTROPIC) != 0 ? m->alpha_v : m->alpha;
    *smooth = microfacet_is_smooth(m->alpha) & microfacet_is_smooth(ay);
    const Microfacet d = {.ax = pfmax(m->alpha, PFLOAT(1e-4f)), .ay = pfmax(ay, PFLOAT(1e-4f)),
                          .beckmann = (m->flags & MATERIAL_FLAG_BECKMANN) != 0,
                          .separable = (m->flags & MATERIAL_FLAG_SEPARABLE) != 0};
    return d;
}

/* Each type's parameters from the lanes' Material fields (abi.MATERIAL documents the mapping). */
RT_INLINE ConductorParams conductor_params(const MaterialLanes *m)
{
    ConductorParams c = {.f0 = m->specular, .eta = m->eta, .k = m->k,
                         .schlick = (m->flags & MATERIAL_FLAG_CONDUCTOR_F0) != 0};
    c.d = microfacet_params(m, &c.smooth);
    return c;
}

/* a dielectric's distribution and the relative index seen by wo (dielectric_eta) */
typedef struct {
    Microfacet d;
    pint smooth;
    pfloat eta;
} DielectricParams;

RT_INLINE GltfParams gltf_params(const MaterialLanes *m)
{
    const pfloat r = (m->ior - 1.0f) / (m->ior + 1.0f);
    const GltfParams g = {.base = m->albedo, .metallic = pclamp(m->metallic, 0.0f, 1.0f), .alpha = m->alpha,
                          .f0d = pisfinite(r) ? r * r : PFLOAT(0.0f)};
    return g;
}

RT_INLINE PlasticParams plastic_params(const MaterialLanes *m)
{
    const PlasticParams p = {.diffuse = m->albedo, .specular = m->specular, .eta = m->ior, .fdr = m->fdr,
                             .spec_weight = m->spec_weight, .nonlinear = (m->flags & MATERIAL_FLAG_NONLINEAR) != 0};
    return p;
}

/* plastic's parameters and the rough coating's (its transmittance table lies in the record) */
RT_INLINE RoughPlasticParams roughplastic_params(const MaterialLanes *m)
{
    const RoughPlasticParams p = {.s = plastic_params(m), .alpha = pfmax(m->alpha, PFLOAT(1e-4f)),
                                  .beckmann = (m->flags & MATERIAL_FLAG_BECKMANN) != 0, .records = m->records,
                                  .table = m->rec + FIELD_INDEX(Material, table)};
    return p;
}

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

/* a thin sheet (principledthin) does not bend light: 1 */
RT_INLINE pfloat dielectric_eta(const MaterialLanes *m, pint front)
{
    const pfloat ior = ((m->ior > 0.0f) & (m->type != MATERIAL_PRINCIPLEDTHIN) & ((m->flags & MATERIAL_FLAG_THIN) == 0))
                           ? m->ior : PFLOAT(1.0f);
    return front ? ior : 1.0f / ior;
}

RT_INLINE DielectricParams dielectric_params(const MaterialLanes *m, pint front)
{
    DielectricParams p;
    p.d = microfacet_params(m, &p.smooth);
    p.eta = dielectric_eta(m, front);
    return p;
}

/* A dielectric's sample: it refracts, or (MATERIAL_FLAG_THIN, Mitsuba's thindielectric) a thin sheet
 * lets light through unbent or reflects it. */
RT_INLINE pvec3 dielectric_or_thin_sample(const MaterialLanes *m, const DielectricParams *p, pint active, pvec3 lo,
                                          pfloat u0, pfloat u1, pfloat u2, pvec3 *wl, pfloat *q, pint *d)
{
    pvec3 g = dielectric_sample(&p->d, p->smooth, p->eta, m->specular, active, lo, u0, u1, u2, wl, q, d);
    const pint thin = active & ((m->flags & MATERIAL_FLAG_THIN) != 0);
    if (pany(thin)) {
        pvec3 wt;
        pfloat qt;
        pint dt;
        g = pv3_sel(g, thin_dielectric_sample(m->ior, m->specular, thin, lo, u2, &wt, &qt, &dt), thin);
        *wl = pv3_sel(*wl, wt, thin);
        *q = thin ? qt : *q;
        *d = thin ? dt : *d;
    }
    return g;
}

RT_INLINE pint bsdf_has_nondelta_lobes(const MaterialLanes *m)
{
    pint r = pnot(PINT(0)); /* diffuse, and any type not compiled in */
#if defined(HAS_MATERIAL_CONDUCTOR) || defined(HAS_MATERIAL_DIELECTRIC)
    pint smooth;
    (void)microfacet_params(m, &smooth);
#endif
#ifdef HAS_MATERIAL_CONDUCTOR
    r = m->type == MATERIAL_CONDUCTOR ? pnot(smooth) : r;
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
    r = m->type == MATERIAL_DIELECTRIC ? pnot(dielectric_is_smooth(smooth, m->ior)) : r;
#endif
#ifdef HAS_MATERIAL_GLTF
    r = m->type == MATERIAL_GLTF ? pnot(microfacet_is_smooth(m->alpha)) | (m->metallic < 1.0f) : r;
#endif
    return r;
}

/* The types shaded in the local frame (all but diffuse): X(TYPE, mask, Params, params, eval, sample) with
 * MATERIAL_<TYPE>, its MaterialMasks field, the type and value of its parameters P, and its bsdf_eval /
 * bsdf_sample calls over the lanes K of that type.  Each case is compiled only where
 * HAS_MATERIAL_<TYPE> is defined (RT_WHEN). */
#define FRAMED_MATERIALS(X) \
    X(CONDUCTOR, conductor, ConductorParams, conductor_params(m), conductor_eval(&P, K, lo, li, &q), conductor_sample(&P, K, lo, u0, u1, &wl, &q, &d)) \
    X(DIELECTRIC, dielectric, DielectricParams, dielectric_params(m, front), dielectric_eval(&P.d, P.smooth, P.eta, m->specular, K, lo, li, &q), dielectric_or_thin_sample(m, &P, K, lo, u0, u1, u2, &wl, &q, &d)) \
    X(GLTF, gltf, GltfParams, gltf_params(m), gltf_eval(&P, K, lo, li, &q), gltf_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d)) \
    X(PLASTIC, plastic, PlasticParams, plastic_params(m), plastic_eval(&P, K, lo, li, &q), plastic_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d)) \
    X(ROUGHPLASTIC, roughplastic, RoughPlasticParams, roughplastic_params(m), roughplastic_eval(&P, K, lo, li, &q), roughplastic_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d)) \
    X(PRINCIPLED, principled, PrincipledParams, principled_params(m), principled_eval(&P, K, front, lo, li, &q), principled_sample(&P, K, front, lo, u0, u1, u2, &wl, &q, &d)) \
    X(PRINCIPLEDTHIN, principledthin, PrincipledParams, principled_params(m), principledthin_eval(&P, K, lo, li, &q), principledthin_sample(&P, K, lo, u0, u1, u2, &wl, &q, &d))

/* RT_WHEN(HAS_MATERIAL_X)(code) is code where HAS_MATERIAL_X is defined (empty, as above, or 1, as -D
 * defines it), else nothing: #ifdef inside a macro. */
#define RT_PASTE3_(a, b, c) a##b##c
#define RT_PASTE3(a, b, c) RT_PASTE3_(a, b, c)
#define RT_SECOND_(a, b, ...) b
#define RT_SECOND(...) RT_SECOND_(__VA_ARGS__)
#define RT_PROBE__ ~, 1
#define RT_PROBE_1_ ~, 1
#define RT_WHEN_0(...)
#define RT_WHEN_1(...) __VA_ARGS__
#define RT_WHEN(x) RT_PASTE3(RT_WHEN_, RT_SECOND(RT_PASTE3(RT_PROBE_, x, _), 0, ~), )

/* The active lanes of each type compiled in, those of all of them (framed), and the others (diffuse,
 * and any type not compiled in, which shades as diffuse). */
typedef struct {
    pint conductor, dielectric, gltf, plastic, roughplastic, principled, principledthin, framed, diffuse;
} MaterialMasks;

#define MASK_CASE(T, mask, ...) RT_WHEN(HAS_MATERIAL_##T)(k.mask = active & (m->type == MATERIAL_##T); k.framed |= k.mask;)

RT_INLINE MaterialMasks material_masks(const MaterialLanes *m, pint active)
{
    MaterialMasks k;
    k.conductor = k.dielectric = k.gltf = k.plastic = k.roughplastic = k.principled = k.principledthin = PINT(0);
    k.framed = PINT(0);
    FRAMED_MATERIALS(MASK_CASE)
    k.diffuse = active & pnot(k.framed);
    return k;
}

/* The local frame (t, b, n) of the framed lanes `framed`: make_onb(n), or for anisotropic lanes the
 * tangent made orthogonal to n (Mitsuba's sh_frame.s) and b = n x t. */
RT_INLINE void bsdf_frame(const MaterialLanes *m, pint framed, pvec3 n, pvec3 tangent, pvec3 *t, pvec3 *b)
{
    make_onb(n, t, b);
    const pint aniso = framed & ((m->flags & MATERIAL_FLAG_ANISOTROPIC) != 0);
    if (!pany(aniso)) return;
    const pvec3 s = pv3_sub(tangent, pv3_scale(n, pv3_dot(n, tangent)));
    const pfloat l2 = pv3_dot(s, s);
    const pint use = aniso & (l2 > 0.0f) & pisfinite(l2);
    const pvec3 su = pv3_scale(s, 1.0f / psqrt(use ? l2 : PFLOAT(1.0f)));
    *t = pv3_sel(*t, su, use);
    *b = pv3_sel(*b, pv3_cross(n, su), use);
}

/* bsdf_eval's case of one type: its lanes K take f and the pdf q of its eval */
#define EVAL_CASE(T, mask, Params, params, eval, sample) \
    RT_WHEN(HAS_MATERIAL_##T)(if (pany(k.mask)) { \
        const pint K = k.mask; \
        const Params P = params; \
        const pvec3 g = eval; \
        f = pv3_sel(f, g, K); \
        p = K ? q : p; \
    })

RT_INLINE pvec3 bsdf_eval(const MaterialLanes *m, pint active, pvec3 n, pvec3 tangent, pint front, pvec3 wo, pvec3 wi,
                          pfloat *pdf)
{
    const MaterialMasks k = material_masks(m, active);
    pvec3 f = pv3_zero();
    pfloat p = PFLOAT(0.0f);
    if (pany(k.diffuse)) f = diffuse_eval(m->albedo, k.diffuse, n, wi, &p);
    if (pany(k.framed)) {
        pvec3 t, b;
        bsdf_frame(m, k.framed, n, tangent, &t, &b);
        const pvec3 lo = to_local(wo, t, b, n), li = to_local(wi, t, b, n);
        pfloat q;
        FRAMED_MATERIALS(EVAL_CASE)
    }
    *pdf = p;
    return f;
}

/* bsdf_sample's case of one type: its lanes K take the weight g, local direction li, pdf ql and delta
 * flag dd of its sample */
#define SAMPLE_CASE(T, mask, Params, params, eval, sample) \
    RT_WHEN(HAS_MATERIAL_##T)(if (pany(k.mask)) { \
        const pint K = k.mask; \
        const Params P = params; \
        g = pv3_sel(g, sample, K); \
        li = pv3_sel(li, wl, K); \
        ql = K ? q : ql; \
        dd = K ? d : dd; \
    })

RT_INLINE pvec3 bsdf_sample(const MaterialLanes *m, pint active, pvec3 n, pvec3 tangent, pint front, pvec3 wo,
                            pfloat u0, pfloat u1, pfloat u2, pvec3 *wi, pfloat *pdf, pint *delta)
{
    const MaterialMasks k = material_masks(m, active);
    const pint framed = k.framed;
    pvec3 w = pv3_zero();
    pfloat p = PFLOAT(0.0f);
    pint dl = PINT(0);
    *wi = n;
    if (pany(k.diffuse)) w = diffuse_sample(m->albedo, k.diffuse, n, u0, u1, wi, &p);
    if (pany(framed)) {
        pvec3 t, b;
        bsdf_frame(m, framed, n, tangent, &t, &b);
        const pvec3 lo = to_local(wo, t, b, n);
        pvec3 li = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f)), wl = li, g = pv3_zero();
        pfloat ql = PFLOAT(0.0f), q;
        pint dd = PINT(0), d;
        FRAMED_MATERIALS(SAMPLE_CASE)
        const pvec3 ww = pv3_normalize(to_world(li, t, b, n), framed);
        /* a non-finite weight or direction fails the sample */
        const pint bad = pnot(pisfinite(g.x + g.y + g.z)) | pnot(pisfinite(ww.x + ww.y + ww.z));
        const pint good = framed & pnot(bad);
        *wi = pv3_sel(*wi, ww, framed);
        w = pv3_sel(pv3_sel(w, pv3_zero(), framed), g, good);
        p = good ? ql : (framed ? PFLOAT(0.0f) : p);
        dl = good & dd;
    }
    *pdf = p;
    *delta = dl;
    return w;
}

/* The albedo guide of cl/render/aov.h for the lanes' hits (n on wo's side). */
RT_INLINE pvec3 material_albedo_aov(const MaterialLanes *m, pvec3 n, pvec3 wo)
{
    const pfloat cos_o = pclamp(pv3_dot(n, wo), 0.0f, 1.0f);
    pvec3 a = m->albedo;
#ifdef HAS_MATERIAL_CONDUCTOR
    const pint mc = m->type == MATERIAL_CONDUCTOR;
    if (pany(mc)) {
        const ConductorParams c = conductor_params(m);
        a = pv3_sel(a, conductor_fresnel(&c, cos_o), mc);
    }
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
    a = pv3_sel(a, m->specular, m->type == MATERIAL_DIELECTRIC);
#endif
#ifdef HAS_MATERIAL_GLTF
    const pint mg = m->type == MATERIAL_GLTF;
    if (pany(mg)) {
        const GltfParams g = gltf_params(m);
        const pfloat s = 1.0f - fresnel_schlick1(g.f0d, cos_o);
        const pvec3 d = pv3_scale(pv3_scale(g.base, 1.0f - g.metallic), s); /* (1 - metallic) base (1 - Fd) */
        a = pv3_sel(a, pv3_add(fresnel_schlick(gltf_f0(&g), cos_o), d), mg);
    }
#endif
    return pv3(pclamp(a.x, 0.0f, 1.0f), pclamp(a.y, 0.0f, 1.0f), pclamp(a.z, 0.0f, 1.0f));
}

#endif
