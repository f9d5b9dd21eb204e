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
 * The Mitsuba 3 types (plastic, roughplastic, principled, principledthin) read the Material
 * fields after the texture indices; material_lanes() gathers those only when some lane has such
 * a type.  roughplastic reads its table from the records themselves (MaterialLanes.records/rec).
 */
#ifndef PYOPENCL_RT_BSDF_H
#define PYOPENCL_RT_BSDF_H

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
    pfloat alpha, metallic, ior;
    pint tex_base, tex_mr, tex_emission; /* texture indices, -1 none */
    pfloat fdr, spec_weight, roughness, anisotropic, spec_trans, spec_tint, sheen, sheen_tint, clearcoat,
        clearcoat_gloss, flatness, diff_trans, rate0, rate1, rate2, rate3;
    __global const float *records; /* the Material array as floats, and each lane's record in it */
    pint rec;
} MaterialLanes;

/* materials[index] in each lane (index valid in every lane) */
RT_INLINE MaterialLanes material_lanes(__global const Material *materials, pint index)
{
    __global const float *f = (__global const float *)materials;
    __global const int *n = (__global const int *)materials;
    const pint i = index * STRIDE_INDEX(Material);
    MaterialLanes m;
    m.type = pgather_int(n, i + FIELD_INDEX(Material, type));
    m.flags = pgather_int(n, i + FIELD_INDEX(Material, flags));
    m.albedo = pv3_gather(f, i + FIELD_INDEX(Material, albedo));
    m.emission = pv3_gather(f, i + FIELD_INDEX(Material, emission));
    m.specular = pv3_gather(f, i + FIELD_INDEX(Material, specular));
    m.eta = pv3_gather(f, i + FIELD_INDEX(Material, eta));
    m.k = pv3_gather(f, i + FIELD_INDEX(Material, k));
    m.alpha = pgather(f, i + FIELD_INDEX(Material, alpha));
    m.metallic = pgather(f, i + FIELD_INDEX(Material, metallic));
    m.ior = pgather(f, i + FIELD_INDEX(Material, ior));
    m.tex_base = pgather_int(n, i + FIELD_INDEX(Material, tex_base));
    m.tex_mr = pgather_int(n, i + FIELD_INDEX(Material, tex_mr));
    m.tex_emission = pgather_int(n, i + FIELD_INDEX(Material, tex_emission));
    m.records = f;
    m.rec = i;
    m.fdr = m.spec_weight = m.roughness = m.anisotropic = m.spec_trans = m.spec_tint = m.sheen = m.sheen_tint =
        m.clearcoat = m.clearcoat_gloss = m.flatness = m.diff_trans = m.rate0 = m.rate1 = m.rate2 = m.rate3 =
            PFLOAT(0.0f);
#ifdef HAS_MITSUBA_MATERIALS
    if (pany(m.type >= MATERIAL_PLASTIC)) {
        m.fdr = pgather(f, i + FIELD_INDEX(Material, fdr));
        m.spec_weight = pgather(f, i + FIELD_INDEX(Material, spec_weight));
        m.roughness = pgather(f, i + FIELD_INDEX(Material, roughness));
        m.anisotropic = pgather(f, i + FIELD_INDEX(Material, anisotropic));
        m.spec_trans = pgather(f, i + FIELD_INDEX(Material, spec_trans));
        m.spec_tint = pgather(f, i + FIELD_INDEX(Material, spec_tint));
        m.sheen = pgather(f, i + FIELD_INDEX(Material, sheen));
        m.sheen_tint = pgather(f, i + FIELD_INDEX(Material, sheen_tint));
        m.clearcoat = pgather(f, i + FIELD_INDEX(Material, clearcoat));
        m.clearcoat_gloss = pgather(f, i + FIELD_INDEX(Material, clearcoat_gloss));
        m.flatness = pgather(f, i + FIELD_INDEX(Material, flatness));
        m.diff_trans = pgather(f, i + FIELD_INDEX(Material, diff_trans));
        m.rate0 = pgather(f, i + FIELD_INDEX(Material, rates));
        m.rate1 = pgather(f, i + FIELD_INDEX(Material, rates) + 1);
        m.rate2 = pgather(f, i + FIELD_INDEX(Material, rates) + 2);
        m.rate3 = pgather(f, i + FIELD_INDEX(Material, rates) + 3);
    }
#endif
    return m;
}

RT_INLINE ConductorParams conductor_params(const MaterialLanes *m)
{
    ConductorParams c;
    c.f0 = m->specular;
    c.eta = m->eta;
    c.k = m->k;
    c.alpha = m->alpha;
    c.schlick = (m->flags & MATERIAL_FLAG_CONDUCTOR_F0) != 0;
    return c;
}

RT_INLINE GltfParams gltf_params(const MaterialLanes *m)
{
    GltfParams g;
    g.base = m->albedo;
    g.metallic = pclamp(m->metallic, 0.0f, 1.0f);
    g.alpha = m->alpha;
    const pfloat r = (m->ior - 1.0f) / (m->ior + 1.0f);
    g.f0d = pisfinite(r) ? r * r : PFLOAT(0.0f);
    return g;
}

RT_INLINE PlasticParams plastic_params(const MaterialLanes *m)
{
    PlasticParams p;
    p.diffuse = m->albedo;
    p.specular = m->specular;
    p.eta = m->ior;
    p.fdr = m->fdr;
    p.spec_weight = m->spec_weight;
    p.nonlinear = (m->flags & MATERIAL_FLAG_NONLINEAR) != 0;
    return p;
}

RT_INLINE RoughPlasticParams roughplastic_params(const MaterialLanes *m)
{
    RoughPlasticParams p;
    p.diffuse = m->albedo;
    p.specular = m->specular;
    p.eta = m->ior;
    p.alpha = pfmax(m->alpha, PFLOAT(1e-4f));
    p.fdr = m->fdr;
    p.spec_weight = m->spec_weight;
    p.nonlinear = (m->flags & MATERIAL_FLAG_NONLINEAR) != 0;
    p.beckmann = (m->flags & MATERIAL_FLAG_BECKMANN) != 0;
    p.records = m->records;
    p.table = m->rec + FIELD_INDEX(Material, table);
    return p;
}

RT_INLINE PrincipledParams principled_params(const MaterialLanes *m)
{
    PrincipledParams p;
    p.base = m->albedo;
    p.roughness = m->roughness;
    p.anisotropic = m->anisotropic;
    p.metallic = m->metallic;
    p.spec_trans = m->spec_trans;
    p.spec_tint = m->spec_tint;
    p.sheen = m->sheen;
    p.sheen_tint = m->sheen_tint;
    p.clearcoat = m->clearcoat;
    p.clearcoat_gloss = m->clearcoat_gloss;
    p.flatness = m->flatness;
    p.diff_trans = m->diff_trans;
    p.eta = m->ior;
    p.rate0 = m->rate0;
    p.rate1 = m->rate1;
    p.rate2 = m->rate2;
    p.rate3 = m->rate3;
    return p;
}

/* a thin sheet (principledthin) does not bend light: 1 */
RT_INLINE pfloat dielectric_eta(const MaterialLanes *m, pint front)
{
    const pfloat ior = ((m->ior > 0.0f) & (m->type != MATERIAL_PRINCIPLEDTHIN) & ((m->flags & MATERIAL_FLAG_THIN) == 0))
                           ? m->ior : PFLOAT(1.0f);
    return front ? ior : 1.0f / ior;
}

RT_INLINE pint bsdf_has_nondelta_lobes(const MaterialLanes *m)
{
    pint r = pnot(PINT(0)); /* diffuse, and any type not compiled in */
#ifdef HAS_MATERIAL_CONDUCTOR
    r = m->type == MATERIAL_CONDUCTOR ? pnot(microfacet_is_smooth(m->alpha)) : r;
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
    r = m->type == MATERIAL_DIELECTRIC ? pnot(dielectric_is_smooth(m->alpha, m->ior)) : r;
#endif
#ifdef HAS_MATERIAL_GLTF
    r = m->type == MATERIAL_GLTF ? pnot(microfacet_is_smooth(m->alpha)) | (m->metallic < 1.0f) : r;
#endif
    return r;
}

/* The active lanes of each type compiled in, and the others (diffuse, and any type not compiled
 * in, which shades as diffuse). */
typedef struct {
    pint conductor, dielectric, gltf, plastic, roughplastic, principled, principledthin, diffuse;
} MaterialMasks;

RT_INLINE MaterialMasks material_masks(const MaterialLanes *m, pint active)
{
    MaterialMasks k;
    k.conductor = k.dielectric = k.gltf = k.plastic = k.roughplastic = k.principled = k.principledthin = PINT(0);
    pint other = PINT(0);
#ifdef HAS_MATERIAL_CONDUCTOR
    k.conductor = active & (m->type == MATERIAL_CONDUCTOR);
    other |= k.conductor;
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
    k.dielectric = active & (m->type == MATERIAL_DIELECTRIC);
    other |= k.dielectric;
#endif
#ifdef HAS_MATERIAL_GLTF
    k.gltf = active & (m->type == MATERIAL_GLTF);
    other |= k.gltf;
#endif
#ifdef HAS_MATERIAL_PLASTIC
    k.plastic = active & (m->type == MATERIAL_PLASTIC);
    other |= k.plastic;
#endif
#ifdef HAS_MATERIAL_ROUGHPLASTIC
    k.roughplastic = active & (m->type == MATERIAL_ROUGHPLASTIC);
    other |= k.roughplastic;
#endif
#ifdef HAS_MATERIAL_PRINCIPLED
    k.principled = active & (m->type == MATERIAL_PRINCIPLED);
    other |= k.principled;
#endif
#ifdef HAS_MATERIAL_PRINCIPLEDTHIN
    k.principledthin = active & (m->type == MATERIAL_PRINCIPLEDTHIN);
    other |= k.principledthin;
#endif
    k.diffuse = active & pnot(other);
    return k;
}

RT_INLINE pvec3 bsdf_eval(const MaterialLanes *m, pint active, pvec3 n, pint front, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    const MaterialMasks k = material_masks(m, active);
    pvec3 f = pv3_zero();
    pfloat p = PFLOAT(0.0f);
    if (pany(k.diffuse)) f = diffuse_eval(m->albedo, k.diffuse, n, wi, &p);
    const pint framed =
        k.conductor | k.dielectric | k.gltf | k.plastic | k.roughplastic | k.principled | k.principledthin;
    if (pany(framed)) {
        pvec3 t, b;
        make_onb(n, &t, &b);
        const pvec3 lo = to_local(wo, t, b, n), li = to_local(wi, t, b, n);
        pfloat q;
        pvec3 g;
#ifdef HAS_MATERIAL_CONDUCTOR
        if (pany(k.conductor)) {
            const ConductorParams c = conductor_params(m);
            g = conductor_eval(&c, k.conductor, lo, li, &q);
            f = pv3_sel(f, g, k.conductor);
            p = k.conductor ? q : p;
        }
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
        if (pany(k.dielectric)) {
            g = dielectric_eval(m->alpha, dielectric_eta(m, front), m->specular, k.dielectric, lo, li, &q);
            f = pv3_sel(f, g, k.dielectric);
            p = k.dielectric ? q : p;
        }
#endif
#ifdef HAS_MATERIAL_GLTF
        if (pany(k.gltf)) {
            const GltfParams gp = gltf_params(m);
            g = gltf_eval(&gp, k.gltf, lo, li, &q);
            f = pv3_sel(f, g, k.gltf);
            p = k.gltf ? q : p;
        }
#endif
#ifdef HAS_MATERIAL_PLASTIC
        if (pany(k.plastic)) {
            const PlasticParams pp = plastic_params(m);
            g = plastic_eval(&pp, k.plastic, lo, li, &q);
            f = pv3_sel(f, g, k.plastic);
            p = k.plastic ? q : p;
        }
#endif
#ifdef HAS_MATERIAL_ROUGHPLASTIC
        if (pany(k.roughplastic)) {
            const RoughPlasticParams rp = roughplastic_params(m);
            g = roughplastic_eval(&rp, k.roughplastic, lo, li, &q);
            f = pv3_sel(f, g, k.roughplastic);
            p = k.roughplastic ? q : p;
        }
#endif
#ifdef HAS_MATERIAL_PRINCIPLED
        if (pany(k.principled)) {
            const PrincipledParams pr = principled_params(m);
            g = principled_eval(&pr, k.principled, front, lo, li, &q);
            f = pv3_sel(f, g, k.principled);
            p = k.principled ? q : p;
        }
#endif
#ifdef HAS_MATERIAL_PRINCIPLEDTHIN
        if (pany(k.principledthin)) {
            const PrincipledParams pr = principled_params(m);
            g = principledthin_eval(&pr, k.principledthin, lo, li, &q);
            f = pv3_sel(f, g, k.principledthin);
            p = k.principledthin ? q : p;
        }
#endif
    }
    *pdf = p;
    return f;
}

RT_INLINE pvec3 bsdf_sample(const MaterialLanes *m, pint active, pvec3 n, pint front, pvec3 wo, pfloat u0, pfloat u1,
                            pfloat u2, pvec3 *wi, pfloat *pdf, pint *delta)
{
    const MaterialMasks k = material_masks(m, active);
    pvec3 w = pv3_zero();
    pfloat p = PFLOAT(0.0f);
    pint dl = PINT(0);
    *wi = n;
    if (pany(k.diffuse)) w = diffuse_sample(m->albedo, k.diffuse, n, u0, u1, wi, &p);
    const pint framed =
        k.conductor | k.dielectric | k.gltf | k.plastic | k.roughplastic | k.principled | k.principledthin;
    if (pany(framed)) {
        pvec3 t, b;
        make_onb(n, &t, &b);
        const pvec3 lo = to_local(wo, t, b, n);
        pvec3 li = pv3(PFLOAT(0.0f), PFLOAT(0.0f), PFLOAT(1.0f)), wl = li, g = pv3_zero();
        pfloat ql = PFLOAT(0.0f), q;
        pint dd = PINT(0), d;
#ifdef HAS_MATERIAL_CONDUCTOR
        if (pany(k.conductor)) {
            const ConductorParams c = conductor_params(m);
            g = pv3_sel(g, conductor_sample(&c, k.conductor, lo, u0, u1, &wl, &q, &d), k.conductor);
            li = pv3_sel(li, wl, k.conductor);
            ql = k.conductor ? q : ql;
            dd = k.conductor ? d : dd;
        }
#endif
#ifdef HAS_MATERIAL_DIELECTRIC
        if (pany(k.dielectric)) {
            g = pv3_sel(g, dielectric_sample(m->alpha, dielectric_eta(m, front), m->specular, k.dielectric, lo, u0, u1,
                                             u2, &wl, &q, &d),
                        k.dielectric);
            const pint thin = k.dielectric & ((m->flags & MATERIAL_FLAG_THIN) != 0);
            if (pany(thin)) {
                pvec3 wt;
                pfloat qt;
                pint dt;
                g = pv3_sel(g, thin_dielectric_sample(m->ior, m->specular, thin, lo, u2, &wt, &qt, &dt), thin);
                wl = pv3_sel(wl, wt, thin);
                q = thin ? qt : q;
                d = thin ? dt : d;
            }
            li = pv3_sel(li, wl, k.dielectric);
            ql = k.dielectric ? q : ql;
            dd = k.dielectric ? d : dd;
        }
#endif
#ifdef HAS_MATERIAL_GLTF
        if (pany(k.gltf)) {
            const GltfParams gp = gltf_params(m);
            g = pv3_sel(g, gltf_sample(&gp, k.gltf, lo, u0, u1, u2, &wl, &q, &d), k.gltf);
            li = pv3_sel(li, wl, k.gltf);
            ql = k.gltf ? q : ql;
            dd = k.gltf ? d : dd;
        }
#endif
#ifdef HAS_MATERIAL_PLASTIC
        if (pany(k.plastic)) {
            const PlasticParams pp = plastic_params(m);
            g = pv3_sel(g, plastic_sample(&pp, k.plastic, lo, u0, u1, u2, &wl, &q, &d), k.plastic);
            li = pv3_sel(li, wl, k.plastic);
            ql = k.plastic ? q : ql;
            dd = k.plastic ? d : dd;
        }
#endif
#ifdef HAS_MATERIAL_ROUGHPLASTIC
        if (pany(k.roughplastic)) {
            const RoughPlasticParams rp = roughplastic_params(m);
            g = pv3_sel(g, roughplastic_sample(&rp, k.roughplastic, lo, u0, u1, u2, &wl, &q, &d), k.roughplastic);
            li = pv3_sel(li, wl, k.roughplastic);
            ql = k.roughplastic ? q : ql;
            dd = k.roughplastic ? d : dd;
        }
#endif
#ifdef HAS_MATERIAL_PRINCIPLED
        if (pany(k.principled)) {
            const PrincipledParams pr = principled_params(m);
            g = pv3_sel(g, principled_sample(&pr, k.principled, front, lo, u0, u1, u2, &wl, &q, &d), k.principled);
            li = pv3_sel(li, wl, k.principled);
            ql = k.principled ? q : ql;
            dd = k.principled ? d : dd;
        }
#endif
#ifdef HAS_MATERIAL_PRINCIPLEDTHIN
        if (pany(k.principledthin)) {
            const PrincipledParams pr = principled_params(m);
            g = pv3_sel(g, principledthin_sample(&pr, k.principledthin, lo, u0, u1, u2, &wl, &q, &d), k.principledthin);
            li = pv3_sel(li, wl, k.principledthin);
            ql = k.principledthin ? q : ql;
            dd = k.principledthin ? d : dd;
        }
#endif
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
