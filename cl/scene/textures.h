/* Image textures (compiled only with HAS_TEXTURES; pyopencl_rt/scene/textures.py loads and packs them).
 *
 * Storage: one float4 texel buffer (linear RGBA: sRGB colour images are decoded at load) and a
 * table of Texture records (offset, width, height; pyopencl_rt/device/abi.py).  Texture coordinates:
 * (0, 0) is the top-left corner of the image, texel (x, y) covers [x, x+1)/W x [y, y+1)/H.
 *
 * Lookup (the record's to_uv, wrap and filter: pyopencl_rt/device/abi.py), as Mitsuba 3's bitmap
 * texture and Dr.Jit's textures do it: the hit's uv goes through the affine to_uv first; bilinear
 * filtering weighs the four texel centres around uv (texel x's centre at (x + 0.5) / W), nearest
 * takes the texel that holds it (floor(u W)); a texel index outside the image wraps (repeat: modulo
 * W; mirror: modulo 2 W, the second copy reversed, so the edge texel repeats once; clamp: to
 * [0, W - 1]).  Repeat and mirror reduce the coordinate to one period first (u - floor(u), or
 * modulo 2 for mirror), so large coordinates keep precision; a non-finite coordinate reads as 0.
 * No mipmapping.  lookup() in pyopencl_rt/scene/textures.py is the same lookup in numpy.  A texture
 * whose mapping is pbrt-v4's planar, spherical or cylindrical one is looked up by the hit point
 * instead of its uv (tex_map_lanes), and a direction mix (pbrt-v4's directionmix) blends two by the
 * geometric normal: both where texture_material() applies textures (TexHit carries the point and
 * the normal); scene/validate.py keeps them from the uv-only lookups (normal and bump maps,
 * emission, masks, a mix's weight).
 *
 * Per-triangle UVs: tri_uv holds 3 float2 per BVH-reordered triangle; a hit's uv is
 * (1 - u - v) uv0 + u uv1 + v uv2 with (u, v) the hit's barycentrics (weights of v1 and v2).
 *
 * Textured materials (Material.tex_base / tex_mr / tex_emission >= 0, triangles only):
 *   tex_base      albedo *= rgb (diffuse, gltf); tint *= rgb (dielectric); coatedconductor: the metal's
 *                 k from the reflectance albedo * rgb (pbrt-v4's "texture reflectance")
 *   tex_mr        glTF metallicRoughness: metallic *= b, roughness *= g (alpha *= g^2)
 *   tex_emission  emission *= rgb
 *   tex_scalar    slot k (used slots first, -1 after them): the parameter TEXP_* named by bits
 *                 4k..4k+3 of tex_params *= r (alpha, alpha_v, roughness, metallic, anisotropic, ...: the
 *                 Mitsuba types' textured parameters; the host stores the value in R)
 *   tex_normal    a normal map (tex_sample) or bump map (tex_gradient_lanes: the derivative of the
 *                 bilinear lookup, as Mitsuba's bump maps take it), read by cl/scene/shading.h
 * texture_material() applies them to the lanes' gathered materials (MaterialLanes) before
 * shading, so the BSDF and emission code is unchanged.  For next-event estimation
 * texture_light_emission() (scene/texture_lights.h) re-derives the sampled point's barycentrics from the same random
 * numbers light_sample_all() used and applies the emission texture there.
 */
#ifndef PYOPENCL_RT_TEXTURES_H
#define PYOPENCL_RT_TEXTURES_H

#include "materials/dispatch.h"

/* tex_wrap1, tex_coord1, TexelQuad1, tex_quad1, tex_channel1: one lookup */
#define TL_LANES 0
#include "scene/texture_lookup.tpl.h"
#undef TL_LANES
/* the same over the lanes: tex_wrap_lanes, ..., tex_channel_lanes */
#define TL_LANES 1
#include "scene/texture_lookup.tpl.h"
#undef TL_LANES

RT_INLINE __global const float *tex_texels(__global const float4 *data, __global const Texture *t)
{
    return (__global const float *)(data + t->offset);
}

/* Texture `index` at uv, filtered and wrapped as its record says (RGBA). */
RT_INLINE float4 tex_sample(__global const Texture *textures, __global const float4 *data, int index, float2 uv)
{
    __global const Texture *t = textures + index;
    const TexelQuad1 q = tex_quad1(t, uv.x, uv.y);
    __global const float *texels = tex_texels(data, t);
    return (float4)(tex_channel1(texels, &q, 0), tex_channel1(texels, &q, 1), tex_channel1(texels, &q, 2),
                    tex_channel1(texels, &q, 3));
}

/* Where the lanes look their textures up: the hit's uv and, for the textures that map the hit
 * point (Texture.mapping) or mix by the normal (TEXTURE_MAP_DIRECTION_MIX), its world position p
 * and geometric normal ng (any sign). */
typedef struct {
    pfloat u, v;
    pvec3 p, ng;
} TexHit;

/* pbrt-v4's mappings of the hit point (pyopencl_rt/scene/textures.py map_points is the same in
 * numpy): x = frame (p, 1) (3 x 4 rows), then planar (s, t) = (x.x, x.y) (pbrt's ds + vs . p,
 * folded into the frame), spherical (theta / pi, phi / 2 pi) of x / |x| (theta from +z, phi from
 * +x toward +y in [0, 2 pi)), cylindrical ((pi + atan2(x.y, x.x)) / 2 pi, x.z). */
RT_INLINE void tex_map_lanes(__global const Texture *t, pvec3 p, pfloat *s, pfloat *tt)
{
    __global const float *f = t->frame;
    const pfloat x = f[0] * p.x + f[1] * p.y + f[2] * p.z + f[3];
    const pfloat y = f[4] * p.x + f[5] * p.y + f[6] * p.z + f[7];
    const pfloat z = f[8] * p.x + f[9] * p.y + f[10] * p.z + f[11];
    if (t->mapping == TEXTURE_MAP_PLANAR) {
        *s = x;
        *tt = y;
    } else if (t->mapping == TEXTURE_MAP_CYLINDRICAL) {
        *s = (PI_F + patan2(y, x)) * (0.5f * INV_PI_F);
        *tt = z;
    } else { /* spherical */
        pfloat phi = patan2(y, x);
        phi = phi < 0.0f ? phi + 2.0f * PI_F : phi;
        *s = pacos(pclamp(z / psqrt(x * x + y * y + z * z), -1.0f, 1.0f)) * INV_PI_F;
        *tt = phi * (0.5f * INV_PI_F);
    }
}

/* The RGB of image texture t at the lanes' hits (its mapping applied), every lane computed. */
RT_INLINE pvec3 tex_image_lanes(__global const Texture *t, __global const float4 *data, const TexHit *h)
{
    pfloat s = h->u, tt = h->v;
    if (t->mapping != TEXTURE_MAP_UV) tex_map_lanes(t, h->p, &s, &tt);
    const TexelQuad_lanes q = tex_quad_lanes(t, s, tt);
    __global const float *texels = tex_texels(data, t);
    return pv3(tex_channel_lanes(texels, &q, 0), tex_channel_lanes(texels, &q, 1), tex_channel_lanes(texels, &q, 2));
}

/* The RGB of texture index[k] at hit k in the lanes k of `on` (0 in the others): the lanes are
 * taken a texture at a time (usually all of them at once), each group in vectors with its
 * record's fields shared; tex_sample's texels, bit for bit, for a uv lookup.  A direction mix
 * (pbrt-v4's directionmix) weighs its first texture by |ng . dir| (frame[0..2], a unit vector)
 * and its second by the rest; its textures are images. */
RT_INLINE pvec3 tex_sample_lanes(__global const Texture *textures, __global const float4 *data, pint index,
                                 const TexHit *h, pint on)
{
    pvec3 out = pv3_zero();
    for (int todo = pbits(on); todo;) {
        const int ti = PLANE_I(index, lowest_bit(todo));
        const pint group = on & (index == ti);
        __global const Texture *t = textures + ti;
        pvec3 c;
        if (t->mapping == TEXTURE_MAP_DIRECTION_MIX) {
            const pfloat amt = pabs(pv3_dot(h->ng, pv3(PFLOAT(t->frame[0]), PFLOAT(t->frame[1]), PFLOAT(t->frame[2]))));
            c = pv3_add(pv3_scale(tex_image_lanes(textures + t->children[0], data, h), amt),
                        pv3_scale(tex_image_lanes(textures + t->children[1], data, h), 1.0f - amt));
        } else {
            c = tex_image_lanes(t, data, h);
        }
        out = pv3_sel(out, c, group);
        todo &= ~pbits(group);
    }
    return out;
}

/* The gradient (tex_gradient_lanes: d/du, d/dv of its luminance) of texture index[k] at (u[k],
 * v[k]) in the lanes k of `on` (0 in the others and for nearest lookups), a texture at a time as
 * tex_sample_lanes. */
RT_INLINE void tex_gradient_lanes(__global const Texture *textures, __global const float4 *data, pint index,
                                  pfloat u, pfloat v, pint on, pfloat *gu, pfloat *gv)
{
    *gu = *gv = PFLOAT(0.0f);
    for (int todo = pbits(on); todo;) {
        const int ti = PLANE_I(index, lowest_bit(todo));
        const pint group = on & (index == ti);
        todo &= ~pbits(group);
        __global const Texture *t = textures + ti;
        if (t->filter == TEXTURE_FILTER_NEAREST) continue;
        const TexelQuad_lanes q = tex_quad_lanes(t, u, v);
        pfloat x, y;
        tex_gradient_of_lanes(t, tex_texels(data, t), &q, &x, &y);
        *gu = group ? x : *gu;
        *gv = group ? y : *gv;
    }
}

RT_INLINE float2 triangle_uv(__global const float2 *tri_uv, int prim, float u, float v)
{
    return (1.0f - u - v) * tri_uv[3 * prim] + u * tri_uv[3 * prim + 1] + v * tri_uv[3 * prim + 2];
}

/* x times the R of each scalar texture of kind `kind` (TEXP_*) of the Material record `rec` (as ints),
 * in slot order, at the triangle hit (prim, u, v) */
RT_INLINE float tex_scalar_times(float x, __global const int *rec, int kind, __global const float2 *tri_uv,
                                 __global const Texture *textures, __global const float4 *tex_data, int prim,
                                 float u, float v)
{
    const int params = rec[FIELD_INDEX(Material, tex_params)];
    for (int slot = 0; slot < TEX_SLOTS; ++slot) {
        const int t = rec[FIELD_INDEX(Material, tex_scalar) + slot];
        if (t < 0) break;
        if (((params >> (4 * slot)) & 15) != kind) continue;
        x *= tex_sample(textures, tex_data, t, triangle_uv(tri_uv, prim, u, v)).x;
    }
    return x;
}

/* The uv of the lanes' triangle hits (prim valid in every lane), as triangle_uv interpolates. */
RT_INLINE void triangle_uv_lanes(__global const float2 *tri_uv, pint prim, pfloat u, pfloat v, pfloat *tu, pfloat *tv)
{
    __global const float *f = (__global const float *)tri_uv;
    const pint i = 6 * prim;
    const pfloat w = 1.0f - u - v;
    *tu = w * pgather(f, i) + u * pgather(f, i + 2) + v * pgather(f, i + 4);
    *tv = w * pgather(f, i + 1) + u * pgather(f, i + 3) + v * pgather(f, i + 5);
}

/* The textures of the lanes' materials applied at their hits (lanes of `tri_hit`: hits on
 * triangles, prim a triangle there; p the hit point, ng its geometric normal, both in the world),
 * in vectors over the lanes that read each texture. */
RT_INLINE void texture_material(__global const float2 *tri_uv, __global const Texture *textures,
                                __global const float4 *data, pint tri_hit, pint prim, pfloat u, pfloat v, pvec3 p,
                                pvec3 ng, MaterialLanes *m)
{
    __global const int *recs = (__global const int *)m->records;
    const pint scalar = pgather_int(recs, m->rec + FIELD_INDEX(Material, tex_scalar)) >= 0;
    const pint textured = tri_hit & ((m->tex_base >= 0) | (m->tex_mr >= 0) | (m->tex_emission >= 0) | scalar);
    if (!pany(textured)) return;
    TexHit h;
    triangle_uv_lanes(tri_uv, textured ? prim : PINT(0), u, v, &h.u, &h.v);
    h.p = p;
    h.ng = ng;
    const pint base = textured & (m->tex_base >= 0);
    if (pany(base)) {
        const pvec3 c = tex_sample_lanes(textures, data, m->tex_base, &h, base);
        const pint tint = base & (m->type == MATERIAL_DIELECTRIC);
        /* a coated conductor's reflectance r = albedo c: pbrt-v4's metal of eta 1 and k = 2 sqrt(r) /
         * sqrt(1 - r), r clamped to [0, 0.9999] (coatedconductor.py reflectance_to_index), under the coat
         * (divided by its index, as the record's eta is) */
        const pint metal = base & (m->type == MATERIAL_COATEDCONDUCTOR);
        if (pany(metal)) {
            const pvec3 r = pv3_mul(m->albedo, c);
            const pvec3 rc = pv3(pclamp(r.x, 0.0f, 0.9999f), pclamp(r.y, 0.0f, 0.9999f), pclamp(r.z, 0.0f, 0.9999f));
            const pfloat s = 2.0f / (metal ? m->ior : PFLOAT(1.0f));
            const pvec3 k = pv3(s * psqrt(rc.x) / psqrt(1.0f - rc.x), s * psqrt(rc.y) / psqrt(1.0f - rc.y),
                                s * psqrt(rc.z) / psqrt(1.0f - rc.z));
            m->k = pv3_sel(m->k, k, metal);
        }
        m->specular = pv3_sel(m->specular, pv3_mul(m->specular, c), tint);
        m->albedo = pv3_sel(m->albedo, pv3_mul(m->albedo, c), base & pnot(tint) & pnot(metal));
    }
    const pint mr = textured & (m->tex_mr >= 0);
    if (pany(mr)) {
        const pvec3 c = tex_sample_lanes(textures, data, m->tex_mr, &h, mr);
        m->metallic = mr ? m->metallic * c.z : m->metallic;
        m->alpha = mr ? m->alpha * (c.y * c.y) : m->alpha;
    }
    const pint emission = textured & (m->tex_emission >= 0);
    if (pany(emission)) {
        const pvec3 c = tex_sample_lanes(textures, data, m->tex_emission, &h, emission);
        m->emission = pv3_sel(m->emission, pv3_mul(m->emission, c), emission);
    }
    pint on = textured & scalar;
    const pint params = on ? pgather_int(recs, m->rec + FIELD_INDEX(Material, tex_params)) : PINT(0);
    for (int slot = 0; slot < TEX_SLOTS && pany(on); ++slot) {
        const pint t = on ? pgather_int(recs, m->rec + (FIELD_INDEX(Material, tex_scalar) + slot)) : PINT(-1);
        on &= t >= 0;
        if (!pany(on)) break;
        const pfloat c = tex_sample_lanes(textures, data, t, &h, on).x;
        const pint kind = on ? (params >> (4 * slot)) & 15 : PINT(-1);
#define TEXP_TIMES(K, field) m->field = kind == K ? m->field * c : m->field
        TEXP_TIMES(TEXP_ALPHA, alpha);
        TEXP_TIMES(TEXP_ROUGHNESS, roughness);
        TEXP_TIMES(TEXP_METALLIC, metallic);
        TEXP_TIMES(TEXP_ANISOTROPIC, anisotropic);
        TEXP_TIMES(TEXP_SPEC_TRANS, spec_trans);
        TEXP_TIMES(TEXP_SPEC_TINT, spec_tint);
        TEXP_TIMES(TEXP_SHEEN, sheen);
        TEXP_TIMES(TEXP_SHEEN_TINT, sheen_tint);
        TEXP_TIMES(TEXP_CLEARCOAT, clearcoat);
        TEXP_TIMES(TEXP_CLEARCOAT_GLOSS, clearcoat_gloss);
        TEXP_TIMES(TEXP_FLATNESS, flatness);
        TEXP_TIMES(TEXP_DIFF_TRANS, diff_trans);
        TEXP_TIMES(TEXP_ETA, ior);
        TEXP_TIMES(TEXP_OPACITY, opacity);
        TEXP_TIMES(TEXP_ALPHA_V, alpha_v);
#undef TEXP_TIMES
    }
}

#endif /* PYOPENCL_RT_TEXTURES_H */

