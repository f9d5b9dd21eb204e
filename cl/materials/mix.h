/* "mix": a blend (1 - w) f_a + w f_b of two materials (Mitsuba 3's blendbsdf, pbrt-v4's MixMaterial;
 * pyopencl_rt/scene/materials/mix.py).  It has no BSDF of its own: at a hit, mix_sample() picks one
 * of the two records, b with probability w, whose BSDF sample continues the path (and whose record
 * is the AOVs' and the shading frame's).  Nested mixes resolve in turn, each from the same uniform
 * number rescaled into the part it fell in, up to MIX_MAX_DEPTH levels (a deeper record shades as a
 * black diffuse); the record picked is then shaded alone (its light sample, its BSDF sample and their
 * MIS weights), as pbrt-v4 resolves a MixMaterial: conditional on the pick the estimate is unbiased
 * for that material, so in expectation it is the blend.
 *
 * Where the mix blends two materials that are not mixes, the caller (cl/render/path.h) evaluates
 * both as Mitsuba's blendbsdf does, for the same variance as Mitsuba's: the light sample sees
 * (1 - w) f_a + w f_b with the pdf (1 - w) p_a + w p_b, and the picked material's BSDF sample
 * (continuous) is weighed by that f over that pdf (one-sample MIS over the two); a delta sample
 * of the picked one keeps its own weight (its selection probability w_c cancels the blend's w_c).
 * There Mitsuba differs: its blendbsdf weighs a delta sample as if its density were 1 against the
 * other BSDF's density, which is not the blend's expectation (a mirror blended with a diffuse comes
 * out up to 10% darker than picking alone gives; tests/render/test_mix.py checks ours against picks).
 * Nested mixes are resolved by picks alone (pbrt-v4's way), which is unbiased too.
 *
 * Record (abi.MATERIAL): its block in `table` (pyopencl_rt/scene/materials/mix.py), MIX_WEIGHT the
 * weight w, MIX_FIRST / MIX_SECOND the indices of a and b (floats);
 * tex_scalar's TEXP_MIX_WEIGHT slot a texture whose R multiplies w (triangles: its luminance, as
 * Mitsuba's eval_1); with MATERIAL_FLAG_VERTEX_COLOR the luminance of the triangle's interpolated
 * colours multiplies it (Mitsuba's mesh_attribute as the weight).  w is clamped to [0, 1].
 *
 * The uniform number: sample dimension DIM_MIX of the bounce (cl/render/sampler.h), so every width
 * and schedule picks the same record for a path.  The emission and an alpha mask stay the mix
 * record's own (mix_keep_top). */
#ifndef PYOPENCL_RT_MIX_H
#define PYOPENCL_RT_MIX_H

#include "scene/textures.h"
#include "scene/shading.h"

#ifdef HAS_MATERIAL_MIX

#define MIX_MAX_DEPTH 8
#define MIX_WEIGHT 0 /* Material.table entries */
#define MIX_FIRST 1
#define MIX_SECOND 2

/* w of the lanes' mix records (float index i of each record) at their hits (lanes of `active`) */
RT_INLINE pfloat mix_eval(__global const Material *materials, __global const float2 *tri_uv,
                          __global const Texture *textures, __global const float4 *tex_data,
                          __global const float *tri_color, pint active, pint prim, pfloat u, pfloat v, pint i)
{
    __global const float *f = (__global const float *)materials;
    __global const int *ints = (__global const int *)materials;
    pfloat w = pgather(f, i + FIELD_INDEX(Material, table) + MIX_WEIGHT);
#ifdef HAS_TEXTURES
    const pint tri = active & pnot(IS_SHAPE(prim));
    const pint textured = tri & (pgather_int(ints, i + FIELD_INDEX(Material, tex_scalar)) >= 0);
    if (pany(textured)) {
        for (int k = 0; k < PACKET_WIDTH; ++k) {
            if (PLANE_I(textured, k))
                PLANE(w, k) = tex_scalar_times(PLANE(w, k), ints + PLANE_I(i, k), TEXP_MIX_WEIGHT, tri_uv, textures,
                                               tex_data, PLANE_I(prim, k), PLANE(u, k), PLANE(v, k));
        }
    }
#endif
#ifdef HAS_VERTEX_COLORS
    const pint colored = active & (prim >= 0) &
                         ((pgather_int(ints, i + FIELD_INDEX(Material, flags)) & MATERIAL_FLAG_VERTEX_COLOR) != 0);
    if (pany(colored)) {
        const pint c9 = colored ? prim * 9 : PINT(0);
        const pvec3 c = barycentric3(gather9_corner(tri_color, c9, 0), gather9_corner(tri_color, c9, 1),
                                     gather9_corner(tri_color, c9, 2), u, v);
        w = colored ? w * (0.212671f * c.x + 0.715160f * c.y + 0.072169f * c.z) : w;
    }
#endif
    return pclamp(w, 0.0f, 1.0f);
}

/* The record each lane of `hit` is shaded with: index itself unless it is a mix, else one of the
 * records it blends, picked with uniform number um (and so on for nested mixes).  Where the hit's
 * mix blends two records that are not mixes, *other is the record not picked and *w_other its
 * weight (the caller evaluates both, as Mitsuba's blendbsdf); elsewhere *other is -1, *w_other 0. */
RT_INLINE pint mix_sample(__global const Material *materials, __global const float2 *tri_uv,
                          __global const Texture *textures, __global const float4 *tex_data,
                          __global const float *tri_color, pint hit, pint prim, pfloat u, pfloat v, pfloat um,
                          pint index, pint *other, pfloat *w_other)
{
    __global const float *f = (__global const float *)materials;
    __global const int *ints = (__global const int *)materials;
    *other = PINT(-1);
    *w_other = PFLOAT(0.0f);
    for (int level = 0; level < MIX_MAX_DEPTH; ++level) {
        const pint i = index * STRIDE_INDEX(Material);
        const pint mixed = hit & (pgather_int(ints, i + FIELD_INDEX(Material, type)) == MATERIAL_MIX);
        if (!pany(mixed)) break;
        const pfloat w = mix_eval(materials, tri_uv, textures, tex_data, tri_color, mixed, prim, u, v, i);
        const pint second = um < w;
        /* the part um fell in, stretched back to [0, 1) */
        const pfloat rest = second ? um / w : (um - w) / (1.0f - w);
        um = mixed ? pfmin(rest, PFLOAT(0x1.fffffep-1f)) : um;
        const pint ia = convert_pint(pgather(f, i + FIELD_INDEX(Material, table) + MIX_FIRST));
        const pint ib = convert_pint(pgather(f, i + FIELD_INDEX(Material, table) + MIX_SECOND));
        const pint child = second ? ib : ia;
        if (level == 0) {
            const pint ok = mixed & (ia >= 0) & (ib >= 0);
            const pint ta = pgather_int(ints, (ok ? ia : PINT(0)) * STRIDE_INDEX(Material) + FIELD_INDEX(Material, type));
            const pint tb = pgather_int(ints, (ok ? ib : PINT(0)) * STRIDE_INDEX(Material) + FIELD_INDEX(Material, type));
            const pint leaves = ok & (ta != MATERIAL_MIX) & (tb != MATERIAL_MIX);
            *other = leaves ? (second ? ia : ib) : *other;
            *w_other = leaves ? (second ? 1.0f - w : w) : *w_other;
        }
        index = (mixed & (child >= 0)) ? child : index;
    }
    return index;
}

/* The other material of the lanes whose mix blends two leaves (mix_sample's *other >= 0): its
 * gathered record (textures and vertex colours applied), its shading frame, the lanes where it
 * reflects (`surface`: not one-sided seen from behind) and the weights of the picked material (wc)
 * and of it (wo); wc is 1 and wo 0 in the other lanes. */
typedef struct {
    MaterialLanes m;
    ShadingLanes sh;
    pint blended, surface;
    pfloat wc, wo;
} MixOther;

RT_INLINE MixOther mix_other(MESH_PARAMS, __global const float *face_normal,
                             __global const Material *materials, __global const float2 *tri_uv,
                             __global const Texture *textures, __global const float4 *tex_data,
                             __global const float *tri_color, pint hit, pint prim, pfloat u, pfloat v, pvec3 p,
                             pvec3 ng, pvec3 n, pint front, pvec3 wo, pint other, pfloat w_other)
{
    MixOther x;
    x.blended = hit & (other >= 0);
    x.wo = x.blended ? w_other : PFLOAT(0.0f);
    x.wc = x.blended ? 1.0f - w_other : PFLOAT(1.0f);
    const pint index = x.blended ? other : PINT(0);
    x.m = material_lanes(materials, index);
    x.surface = PINT(0);
    if (!pany(x.blended)) {
        x.sh.n = n; /* unused */
        return x;
    }
#ifdef HAS_TEXTURES
    texture_material(tri_uv, textures, tex_data, x.blended & pnot(IS_SHAPE(prim)), prim, u, v, p, ng, &x.m);
#endif
#ifdef HAS_VERTEX_COLORS
    vertex_color_material(tri_color, x.blended, prim, u, v, &x.m);
#endif
    x.sh = shading_lanes(MESH_ARGS, face_normal, tri_uv, textures, tex_data, materials, index, x.blended, prim, u, v, ng, n,
                         front, wo, x.blended & ((x.m.flags & MATERIAL_FLAG_ANISOTROPIC) != 0));
    x.surface = x.blended & pnot(((x.m.flags & MATERIAL_FLAG_ONE_SIDED) != 0) & pnot(x.sh.front));
    return x;
}

/* The picked material's f and pdf (fc, *pdf: its bsdf_eval after shading_eval) blended with the
 * other's at wi in the lanes of x->blended: wc fc + wo fo, wc pc + wo po; unchanged elsewhere. */
RT_INLINE pvec3 mix_blend_eval(const MixOther *x, pint active, pvec3 fc, pvec3 wo, pvec3 wi, pfloat *pdf)
{
    const pint both = active & x->blended;
    if (!pany(both)) return fc;
    pfloat po;
    pvec3 fo = bsdf_eval(&x->m, both & x->surface, x->sh.n, x->sh.t, x->sh.front, wo, wi, &po);
    fo = shading_eval(&x->sh, wi, fo, &po);
    const pvec3 f = pv3_add(pv3_scale(fc, x->wc), pv3_scale(fo, x->wo));
    *pdf = both ? x->wc * *pdf + x->wo * po : *pdf;
    return pv3_sel(fc, f, both);
}

/* A BSDF sample (weight, *pdf, delta) of the picked material m (frame sh) in the lanes of x->blended
 * made a sample of the blend: a continuous sample's weight becomes f / pdf and its pdf the blend's
 * (Mitsuba's blendbsdf::sample); a delta sample keeps its weight.  Unchanged elsewhere. */
RT_INLINE pvec3 mix_blend_sample(const MixOther *x, const MaterialLanes *m, const ShadingLanes *sh, pint active,
                                 pvec3 wo, pvec3 wi, pint delta, pvec3 weight, pfloat *pdf)
{
    const pint both = active & x->blended & pnot(delta) & (*pdf > 0.0f);
    if (!pany(both)) return weight;
    pfloat pc;
    pvec3 fc = bsdf_eval(m, both, sh->n, sh->t, sh->front, wo, wi, &pc);
    fc = shading_eval(sh, wi, fc, &pc);
    const pvec3 f = mix_blend_eval(x, both, fc, wo, wi, &pc);
    const pint ok = both & (pc > 0.0f);
    *pdf = both ? (ok ? pc : PFLOAT(0.0f)) : *pdf;
    return pv3_sel(weight, pv3_sel(pv3_zero(), pv3_div(f, ok ? pc : PFLOAT(1.0f)), ok), both);
}

/* What stays the hit's own record's (`top`, where mix_sample moved to `index`): its emission, emission
 * texture and two-sidedness, and its alpha mask (MATERIAL_FLAG_MASK: Mitsuba's mask around a
 * blendbsdf) with its opacity, times its opacity texture at the hit (triangles). */
RT_INLINE void mix_keep_top(__global const Material *materials, __global const float2 *tri_uv,
                            __global const Texture *textures, __global const float4 *tex_data, pint top, pint index,
                            pint prim, pfloat u, pfloat v, MaterialLanes *m)
{
    const pint moved = top != index;
    if (!pany(moved)) return;
    const MaterialLanes t = material_lanes(materials, moved ? top : index);
    const int kept = MATERIAL_FLAG_TWO_SIDED | MATERIAL_FLAG_MASK;
    m->emission = pv3_sel(m->emission, t.emission, moved);
    m->tex_emission = moved ? t.tex_emission : m->tex_emission;
    m->flags = moved ? ((m->flags & ~kept) | (t.flags & kept)) : m->flags;
    m->opacity = moved ? t.opacity : m->opacity;
#ifdef HAS_TEXTURES
    const pint masked = moved & pnot(IS_SHAPE(prim)) & ((t.flags & MATERIAL_FLAG_MASK) != 0);
    if (!pany(masked)) return;
    __global const int *ints = (__global const int *)materials;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        if (PLANE_I(masked, k))
            PLANE(m->opacity, k) = tex_scalar_times(PLANE(m->opacity, k), ints + PLANE_I(t.rec, k), TEXP_OPACITY, tri_uv,
                                                    textures, tex_data, PLANE_I(prim, k), PLANE(u, k), PLANE(v, k));
    }
#endif
}

#endif /* HAS_MATERIAL_MIX */

#endif
