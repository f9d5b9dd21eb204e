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
 * No mipmapping.  texlookup_ref() in pyopencl_rt/scene/textures.py is the same lookup in numpy.
 *
 * Per-triangle UVs: tri_uv holds 3 float2 per BVH-reordered triangle; a hit's uv is
 * (1 - u - v) uv0 + u uv1 + v uv2 with (u, v) the hit's barycentrics (weights of v1 and v2).
 *
 * Textured materials (Material.tex_base / tex_mr / tex_emission >= 0, triangles only):
 *   tex_base      albedo *= rgb (diffuse, gltf); tint *= rgb (dielectric)
 *   tex_mr        glTF metallicRoughness: metallic *= b, roughness *= g (alpha *= g^2)
 *   tex_emission  emission *= rgb
 *   tex_scalar    slot k (used slots first, -1 after them): the parameter TEXP_* named by bits
 *                 4k..4k+3 of tex_params *= r (alpha, alpha_v, roughness, metallic, anisotropic, ...: the
 *                 Mitsuba types' textured parameters; the host stores the value in R)
 *   tex_normal    a normal map (tex_sample) or bump map (tex_gradient: the derivative of the
 *                 bilinear lookup, as Mitsuba's bump maps take it), read by cl/scene/shading.h
 * texture_material() applies them to the lanes' gathered materials (MaterialLanes) before
 * shading, so the BSDF and emission code is unchanged.  For next-event estimation
 * texture_light_emission() (scene/texture_lights.h) re-derives the sampled point's barycentrics from the same random
 * numbers light_sample_all() used and applies the emission texture there.
 */
#ifndef PYOPENCL_RT_TEXTURES_H
#define PYOPENCL_RT_TEXTURES_H

#include "materials/dispatch.h"

RT_INLINE float4 tex_fetch(__global const float4 *data, __global const Texture *t, int x, int y)
{
    return data[t->offset + y * t->width + x];
}

/* A texel index wrapped into [0, n) by the record's mode; i lies in [-1, 2n] for repeat and
 * mirror (the coordinate was reduced to one period), anywhere for clamp. */
RT_INLINE int tex_wrap(int i, int n, int wrap)
{
    if (wrap == TEXTURE_WRAP_CLAMP) return clamp(i, 0, n - 1);
    if (wrap == TEXTURE_WRAP_MIRROR) {
        const int m = i < 0 ? i + 2 * n : (i >= 2 * n ? i - 2 * n : i);
        return m >= n ? 2 * n - 1 - m : m;
    }
    return i < 0 ? i + n : (i >= n ? i - n : i);
}

/* One coordinate in texels of a lookup (before the half-texel shift): c reduced to one period
 * (repeat: [0, 1), mirror: [0, 2)) or, for clamp, to [-1, 2] (beyond that every texel index clamps
 * the same way), times n. */
RT_INLINE float tex_coord(float c, int n, int wrap)
{
    c = isfinite(c) ? c : 0.0f;
    if (wrap == TEXTURE_WRAP_CLAMP) c = clamp(c, -1.0f, 2.0f);
    else if (wrap == TEXTURE_WRAP_MIRROR) c -= 2.0f * floor(0.5f * c);
    else c -= floor(c);
    return c * (float)n;
}

/* The lookup's coordinates: uv through the record's affine to_uv (non-finite parts read as 0). */
RT_INLINE float2 tex_transform(__global const Texture *t, float2 uv)
{
    uv = (float2)(isfinite(uv.x) ? uv.x : 0.0f, isfinite(uv.y) ? uv.y : 0.0f);
    return (float2)(t->to_uv[0] * uv.x + t->to_uv[1] * uv.y + t->to_uv[2],
                    t->to_uv[3] * uv.x + t->to_uv[4] * uv.y + t->to_uv[5]);
}

/* The four texels around uv (wrapped) and the bilinear weights ax, ay of the right and bottom
 * ones. */
typedef struct { int x0, y0, x1, y1; float ax, ay; } TexelQuad;

RT_INLINE TexelQuad tex_quad(__global const Texture *t, float2 uv)
{
    const int w = t->width, h = t->height, wrap = t->wrap;
    const float2 c = tex_transform(t, uv);
    const float fx = tex_coord(c.x, w, wrap) - 0.5f, fy = tex_coord(c.y, h, wrap) - 0.5f;
    const float x0f = floor(fx), y0f = floor(fy);
    TexelQuad q;
    q.ax = fx - x0f;
    q.ay = fy - y0f;
    const int x0 = (int)x0f, y0 = (int)y0f;
    q.x0 = tex_wrap(x0, w, wrap);
    q.y0 = tex_wrap(y0, h, wrap);
    q.x1 = tex_wrap(x0 + 1, w, wrap);
    q.y1 = tex_wrap(y0 + 1, h, wrap);
    return q;
}

/* Texture `index` at uv, filtered and wrapped as its record says. */
RT_INLINE float4 tex_sample(__global const Texture *textures, __global const float4 *data, int index, float2 uv)
{
    __global const Texture *t = textures + index;
    if (t->filter == TEXTURE_FILTER_NEAREST) {
        const float2 c = tex_transform(t, uv);
        const int x = (int)floor(tex_coord(c.x, t->width, t->wrap)), y = (int)floor(tex_coord(c.y, t->height, t->wrap));
        return tex_fetch(data, t, tex_wrap(x, t->width, t->wrap), tex_wrap(y, t->height, t->wrap));
    }
    const TexelQuad q = tex_quad(t, uv);
    const float4 top = mix(tex_fetch(data, t, q.x0, q.y0), tex_fetch(data, t, q.x1, q.y0), q.ax);
    const float4 bot = mix(tex_fetch(data, t, q.x0, q.y1), tex_fetch(data, t, q.x1, q.y1), q.ax);
    return mix(top, bot, q.ay);
}

/* The gradient (d/du, d/dv) of the bilinear lookup's luminance (Rec. 709 weights) at uv, as
 * Mitsuba 3's bitmap texture computes it for bump maps (eval_1_grad): the derivative of the
 * bilinear interpolation within the four texels around uv, times the resolution, taken back
 * through to_uv (its transpose, then the resolution, in Mitsuba's order); 0 for a nearest lookup. */
RT_INLINE float2 tex_gradient(__global const Texture *textures, __global const float4 *data, int index, float2 uv)
{
    __global const Texture *t = textures + index;
    if (t->filter == TEXTURE_FILTER_NEAREST) return (float2)(0.0f, 0.0f);
    const TexelQuad q = tex_quad(t, uv);
    const float3 lum = (float3)(0.212671f, 0.715160f, 0.072169f);
    const float f00 = dot(tex_fetch(data, t, q.x0, q.y0).xyz, lum), f10 = dot(tex_fetch(data, t, q.x1, q.y0).xyz, lum);
    const float f01 = dot(tex_fetch(data, t, q.x0, q.y1).xyz, lum), f11 = dot(tex_fetch(data, t, q.x1, q.y1).xyz, lum);
    const float dx = (1.0f - q.ay) * (f10 - f00) + q.ay * (f11 - f01);
    const float dy = (1.0f - q.ax) * (f01 - f00) + q.ax * (f11 - f10);
    /* Mitsuba's order: the transpose first, then the resolution (the same for an axis-aligned to_uv) */
    return (float2)((float)t->width * (t->to_uv[0] * dx + t->to_uv[3] * dy),
                    (float)t->height * (t->to_uv[1] * dx + t->to_uv[4] * dy));
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

/* The textures of the lanes' materials applied at their hits (lanes of `tri_hit`: hits on
 * triangles, prim a triangle there), lane by lane: a texture lookup is a gather of its own. */
RT_INLINE void texture_material(__global const float2 *tri_uv, __global const Texture *textures,
                                __global const float4 *data, pint tri_hit, pint prim, pfloat u, pfloat v,
                                MaterialLanes *m)
{
    __global const int *recs = (__global const int *)m->records;
    const pint scalar = pgather_int(recs, m->rec + FIELD_INDEX(Material, tex_scalar)) >= 0;
    const pint textured = tri_hit & ((m->tex_base >= 0) | (m->tex_mr >= 0) | (m->tex_emission >= 0) | scalar);
    if (!pany(textured)) return;
    for (int k = 0; k < PACKET_WIDTH; ++k) {
        if (!PLANE_I(textured, k)) continue;
        const float2 uv = triangle_uv(tri_uv, PLANE_I(prim, k), PLANE(u, k), PLANE(v, k));
        const int base = PLANE_I(m->tex_base, k), mr = PLANE_I(m->tex_mr, k), emission = PLANE_I(m->tex_emission, k);
        if (base >= 0) {
            const float3 c = tex_sample(textures, data, base, uv).xyz;
            pvec3 *tinted = PLANE_I(m->type, k) == MATERIAL_DIELECTRIC ? &m->specular : &m->albedo;
            pv3_set_lane(tinted, k, pv3_lane(*tinted, k) * c);
        }
        if (mr >= 0) {
            const float4 c = tex_sample(textures, data, mr, uv);
            PLANE(m->metallic, k) *= c.z;
            PLANE(m->alpha, k) *= c.y * c.y;
        }
        if (emission >= 0) {
            const float3 c = tex_sample(textures, data, emission, uv).xyz;
            pv3_set_lane(&m->emission, k, pv3_lane(m->emission, k) * c);
        }
        __global const int *rec = recs + PLANE_I(m->rec, k);
        const int params = rec[FIELD_INDEX(Material, tex_params)];
        for (int slot = 0; slot < TEX_SLOTS; ++slot) {
            const int t = rec[FIELD_INDEX(Material, tex_scalar) + slot];
            if (t < 0) break;
            const float c = tex_sample(textures, data, t, uv).x;
            switch ((params >> (4 * slot)) & 15) {
            case TEXP_ALPHA: PLANE(m->alpha, k) *= c; break;
            case TEXP_ROUGHNESS: PLANE(m->roughness, k) *= c; break;
            case TEXP_METALLIC: PLANE(m->metallic, k) *= c; break;
            case TEXP_ANISOTROPIC: PLANE(m->anisotropic, k) *= c; break;
            case TEXP_SPEC_TRANS: PLANE(m->spec_trans, k) *= c; break;
            case TEXP_SPEC_TINT: PLANE(m->spec_tint, k) *= c; break;
            case TEXP_SHEEN: PLANE(m->sheen, k) *= c; break;
            case TEXP_SHEEN_TINT: PLANE(m->sheen_tint, k) *= c; break;
            case TEXP_CLEARCOAT: PLANE(m->clearcoat, k) *= c; break;
            case TEXP_CLEARCOAT_GLOSS: PLANE(m->clearcoat_gloss, k) *= c; break;
            case TEXP_FLATNESS: PLANE(m->flatness, k) *= c; break;
            case TEXP_DIFF_TRANS: PLANE(m->diff_trans, k) *= c; break;
            case TEXP_ETA: PLANE(m->ior, k) *= c; break;
            case TEXP_OPACITY: PLANE(m->opacity, k) *= c; break;
            case TEXP_ALPHA_V: PLANE(m->alpha_v, k) *= c; break;
            default: break;
            }
        }
    }
}

#endif /* PYOPENCL_RT_TEXTURES_H */

