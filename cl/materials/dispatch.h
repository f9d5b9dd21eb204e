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
 * A type plugs in from its own header: cl/materials/<name>.h, included here for every name of the
 * enum abi.MATERIAL_TYPES (the generated include "materials/bsdfs.h"; "mix" aside: cl/render/path.h
 * resolves it), makes its parameters from the lanes' record (cl/materials/record.h) and defines its
 * case, MATERIAL_CASE_<NAME>(X), one row of the columns
 *   X(TYPE, mask, Params, params, eval, sample, nondelta, albedo)
 * MATERIAL_<TYPE>, its MaterialMasks field, the type and value of its parameters P, its bsdf_eval and
 * bsdf_sample calls over the lanes K of that type (in the local frame: lo, li, wl; u0..u2; front),
 * bsdf_has_nondelta_lobes's mask and material_albedo_aov's value for its lanes (of m, cos_o).  The
 * generated MATERIAL_CASES(X) lists every case in the enum's order; diffuse's is empty (it is shaded
 * before the frame, as is any type not compiled in).
 */
#ifndef PYOPENCL_RT_DISPATCH_H
#define PYOPENCL_RT_DISPATCH_H

/* MATERIAL_<TYPE>, MATERIAL_FLAG_*, MATERIAL_CASES and, unless MATERIALS_SELECTED, every
 * HAS_MATERIAL_<TYPE> come from the generated header (pyopencl_rt/device/abi.py). */
#include "materials/record.h"
#include "materials/bsdfs.h"

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
#define MASK_FIELD(T, mask, ...) pint mask;
typedef struct {
    MATERIAL_CASES(MASK_FIELD)
    pint framed, diffuse;
} MaterialMasks;

#define MASK_CASE(T, mask, ...) \
    k.mask = PINT(0); \
    RT_WHEN(HAS_MATERIAL_##T)(k.mask = active & (m->type == MATERIAL_##T); k.framed |= k.mask;)

RT_INLINE MaterialMasks material_masks(const MaterialLanes *m, pint active)
{
    MaterialMasks k;
    k.framed = PINT(0);
    MATERIAL_CASES(MASK_CASE)
    k.diffuse = active & pnot(k.framed);
    return k;
}

/* bsdf_has_nondelta_lobes's case of one type: its lanes' mask */
#define NONDELTA_CASE(T, mask, Params, params, eval, sample, nondelta, albedo) \
    RT_WHEN(HAS_MATERIAL_##T)(r = m->type == MATERIAL_##T ? (nondelta) : r;)

RT_INLINE pint bsdf_has_nondelta_lobes(const MaterialLanes *m)
{
    pint r = pnot(PINT(0)); /* diffuse, and any type not compiled in */
    MATERIAL_CASES(NONDELTA_CASE)
    return r;
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
#define EVAL_CASE(T, mask, Params, params, eval, sample, ...) \
    RT_WHEN(HAS_MATERIAL_##T)(if (pany(k.mask)) { \
        const pint K = k.mask; \
        const Params P = params; \
        const pvec3 g = eval; \
        f = pv3_sel(f, g, K); \
        p = K ? q : p; \
    })

/* RT_BSDF_NOINLINE (render/settings.py: programs of many material types): bsdf_eval and bsdf_sample out
 * of line, one copy each instead of one per call site (next-event estimation, a mix's two lobes, the
 * BSDF sample): the every-type program's cold build 35 -> 20 CPU s, the same bits, samples/s within
 * 1% there but 3-6% less on scenes of one or two types, which keep them inline. */
#ifdef RT_BSDF_NOINLINE
#define BSDF_ENTRY __attribute__((noinline))
#else
#define BSDF_ENTRY RT_INLINE
#endif
BSDF_ENTRY pvec3 bsdf_eval(const MaterialLanes *m, pint active, pvec3 n, pvec3 tangent, pint front, pvec3 wo, pvec3 wi,
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
        MATERIAL_CASES(EVAL_CASE)
    }
    *pdf = p;
    return f;
}

/* bsdf_sample's case of one type: its lanes K take the weight g, local direction li, pdf ql and delta
 * flag dd of its sample */
#define SAMPLE_CASE(T, mask, Params, params, eval, sample, ...) \
    RT_WHEN(HAS_MATERIAL_##T)(if (pany(k.mask)) { \
        const pint K = k.mask; \
        const Params P = params; \
        g = pv3_sel(g, sample, K); \
        li = pv3_sel(li, wl, K); \
        ql = K ? q : ql; \
        dd = K ? d : dd; \
    })

BSDF_ENTRY pvec3 bsdf_sample(const MaterialLanes *m, pint active, pvec3 n, pvec3 tangent, pint front, pvec3 wo,
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
        MATERIAL_CASES(SAMPLE_CASE)
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

/* material_albedo_aov's case of one type: its lanes' albedo */
#define ALBEDO_CASE(T, mask, Params, params, eval, sample, nondelta, albedo) \
    RT_WHEN(HAS_MATERIAL_##T)({ \
        const pint K = m->type == MATERIAL_##T; \
        if (pany(K)) a = pv3_sel(a, albedo, K); \
    })

/* The albedo guide of cl/render/aov.h for the lanes' hits (n on wo's side). */
RT_INLINE pvec3 material_albedo_aov(const MaterialLanes *m, pvec3 n, pvec3 wo)
{
    const pfloat cos_o = pclamp(pv3_dot(n, wo), 0.0f, 1.0f);
    pvec3 a = m->albedo;
    MATERIAL_CASES(ALBEDO_CASE)
    return pv3(pclamp(a.x, 0.0f, 1.0f), pclamp(a.y, 0.0f, 1.0f), pclamp(a.z, 0.0f, 1.0f));
}

#endif
