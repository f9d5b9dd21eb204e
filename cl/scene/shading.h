/* The frame the BSDF is evaluated in: shading normals interpolated from the vertex normals
 * (HAS_SHADING_NORMALS), normal and bump maps (HAS_NORMAL_MAPS), and vertex colours
 * (HAS_VERTEX_COLORS).  Without these defines shading_lanes() gives the geometric normal and
 * the geometric `front`, so a scene without them compiles to what it compiled to before.
 *
 * Conventions (those of Mitsuba 3, whose scenes we render as it renders them; pbrt-v4 agrees
 * where noted):
 *
 *   shading normal  the unit barycentric interpolation of the triangle's three vertex normals,
 *                   face_normal: 9 floats per face of the scene (a reordered triangle's is
 *                   its face prim_ids[prim]'s), its corners' unit normals in world space (Mesh::compute_surface_interaction); a face whose corners hold
 *                   0 is shaded flat (the geometric normal).  Analytic shapes keep their exact normal.
 *                   The interpolated normal is not turned to the geometric normal's side
 *                   (Mitsuba turns neither; pbrt-v4 turns the geometric normal to the shading
 *                   normal's side): its orientation decides the BSDF's sides, so a dielectric's
 *                   inside is where the vertex normals point away from (`front` below).
 *   BSDF frame      the BSDF (eval, sample, pdf) sees only the shading frame: as Mitsuba's and
 *                   pbrt-v4's BSDFs it is evaluated with wo and wi relative to the shading
 *                   normal, flipped to wo's side (our materials are two-sided: Mitsuba's
 *                   twosided mirrors the frame the same way), and `front` = wo on the side the
 *                   shading normal points to.  No sample is rejected for lying on the other
 *                   side of the geometric surface than the shading normal says ("light leaks"):
 *                   Mitsuba 3's path integrator and BSDFs do not look at the geometric normal,
 *                   nor does pbrt-v4 (pbrt-v3's BSDF::f did, with the geometric normal); rays
 *                   that cross the surface leave from its other side (path.h picks the offset
 *                   side from the geometric normal).
 *   geometric       the geometric normal stays for ray offsets, emission's sidedness, light
 *                   sampling (the reference point) and the geometric `front` of path.h.
 *   normal map      (Material.tex_normal, cl/scene/textures.h) Mitsuba's normalmap: the
 *                   texel's RGB as n = 2 rgb - 1 (x and y times normal_scale: glTF's
 *                   normalTexture.scale) in the shading frame (S, T, N): N the shading normal,
 *                   S = dp/du made orthogonal to N, T = N x S (dp/du, dp/dv from the triangle's
 *                   vertices and UVs; a degenerate parameterisation gets an arbitrary pair
 *                   around the geometric normal, as Mitsuba does).  T points along -dp/dv with
 *                   our top-down v, which is +y of Mitsuba's, pbrt-v4's and glTF's maps.
 *   bump map        (MATERIAL_FLAG_BUMP_MAP) Mitsuba's bumpmap: g = normal_scale times the
 *                   gradient of the height's luminance in uv (tex_gradient_lanes: the bilinear
 *                   lookup's derivative); dp/du' = dp/du + N (g.u - N.dp/du), likewise dp/dv';
 *                   the normal is dp/du' x dp/dv' turned to the geometric normal's side.
 *                   A constant height map gives N.
 *   Mitsuba's rules (flags, model.py MITSUBA_MAP: Mitsuba's defaults for its wrappers; pbrt-v4's
 *                   normalmap and glTF's normalTexture use none):
 *                   MAP_FLIP        flip_invalid_normals: a perturbed normal n with wo below
 *                                   it gets (-n.x, -n.y, n.z)
 *                   MAP_SIDE        f = 0 where wi lies on opposite sides of the shading normal
 *                                   and the perturbed one
 *                   MAP_TERMINATOR  f and the sample weight times the shadowing term of Estevez
 *                                   et al. 2019: 2 / (1 + sqrt(1 + a2 tan^2 theta_i)), a2 =
 *                                   min(tan^2 theta_n / 8, 1), angles to the shading normal
 *                   A viewer on the shading normal's back side sees the map mirrored through the
 *                   tangent plane (Mitsuba's twosided around the wrapper); with MAP_WHOLE (pbrt-v4's
 *                   normal and bump maps: the map tilts the frame, a two-sided BSDF sees it from
 *                   behind) the tilted normal negated whole.
 *   tangent         (HAS_ANISOTROPY: the lanes of MATERIAL_FLAG_ANISOTROPIC) the direction of the
 *                   BSDF frame's x axis, as Mitsuba's sh_frame.s: dp/du of the triangle from its
 *                   vertices and UVs (a triangle without a UV parameterisation: its edge v1 - v0,
 *                   Mitsuba's barycentric dp/du), of an analytic shape (-n.y, n.x, 0) (Mitsuba's
 *                   sphere in its own unrotated frame; the loaders give a shape whose material
 *                   reads dp/du as triangles); under a normal or bump map, dp/du made
 *                   orthogonal to the shading normal, which the BSDF's frame then makes
 *                   orthogonal to the mapped normal (Mitsuba's normalmap frame).  dispatch.h's
 *                   bsdf_frame() makes it orthogonal to the BSDF's normal.
 *   vertex colours  (MATERIAL_FLAG_VERTEX_COLOR) tri_color: 9 floats per reordered triangle,
 *                   linear RGB per corner, interpolated as the UVs; they multiply the albedo (a
 *                   dielectric's tint), as the base texture does (Mitsuba's mesh_attribute
 *                   texture as a reflectance, glTF's COLOR_0 times baseColor).
 *
 * Over the lanes: the vertex normals and colours are gathered per lane; a normal or bump map is
 * computed lane by lane (a texture lookup is a gather of its own) by the same scalar code at
 * every width.
 */
#ifndef PYOPENCL_RT_SHADING_H
#define PYOPENCL_RT_SHADING_H

#include "materials/dispatch.h"
#include "scene/scene.h"

#if defined(HAS_NORMAL_MAPS) && !defined(HAS_TEXTURES)
#error "normal and bump maps are textures: HAS_NORMAL_MAPS needs HAS_TEXTURES (cl/scene/textures.h)"
#endif

/* The BSDF's frame at the lanes' hits. */
typedef struct {
    pvec3 n;      /* the BSDF's normal, on wo's side */
    pvec3 t;      /* the frame's tangent direction of anisotropic lanes (bsdf_frame), else 0 */
    pint front;   /* wo on the side the shading normal points to (dielectrics: the outside) */
#ifdef HAS_NORMAL_MAPS
    pint mapped;  /* lanes whose normal a map tilted, with Mitsuba's side test or shadowing term */
    pint side;    /* MAP_SIDE lanes */
    pvec3 tilt;   /* the tilted normal (not flipped to wo's side) */
    pvec3 base;   /* the shading normal before the map, on wo's side */
    pfloat a2;    /* the shadowing term's alpha^2 (0: no shadowing term) */
#endif
} ShadingLanes;

RT_INLINE pvec3 gather9_corner(__global const float *f, pint i, int corner)
{
    return pv3_gather(f, i + 3 * corner);
}

/* (1 - u - v) a + u b + v c per lane, as triangle_uv interpolates */
RT_INLINE pvec3 barycentric3(pvec3 a, pvec3 b, pvec3 c, pfloat u, pfloat v)
{
    const pfloat w = 1.0f - u - v;
    return pv3_add(pv3_add(pv3_scale(a, w), pv3_scale(b, u)), pv3_scale(c, v));
}

#ifdef HAS_VERTEX_COLORS
/* The vertex colours of the lanes' triangles multiply the reflectance of the materials that
 * ask for them. */
RT_INLINE void vertex_color_material(__global const float *tri_color, pint hit, pint prim, pfloat u, pfloat v,
                                     MaterialLanes *m)
{
    const pint colored = hit & (prim >= 0) & ((m->flags & MATERIAL_FLAG_VERTEX_COLOR) != 0);
    if (!pany(colored)) return;
    const pint i = colored ? prim * 9 : PINT(0);
    const pvec3 c = barycentric3(gather9_corner(tri_color, i, 0), gather9_corner(tri_color, i, 1),
                                 gather9_corner(tri_color, i, 2), u, v);
    const pint tint = colored & (m->type == MATERIAL_DIELECTRIC);
    m->specular = pv3_sel(m->specular, pv3_mul(m->specular, c), tint);
    m->albedo = pv3_sel(m->albedo, pv3_mul(m->albedo, c), colored & pnot(tint));
}
#endif

#if defined(HAS_NORMAL_MAPS) || defined(HAS_ANISOTROPY)
/* dp/du and dp/dv of the lanes' triangles (prim valid in every lane) from their vertices and UVs
 * (Mitsuba's Mesh::compute_surface_interaction), with the edge v1 - v0 (*dp0) and the UVs'
 * determinant (*det) for the callers' fallbacks where the parameterisation is degenerate. */
RT_INLINE void triangle_uv_derivatives(MESH_PARAMS, __global const float2 *tri_uv, pint prim,
                                       pvec3 *dpdu, pvec3 *dpdv, pvec3 *dp0, pfloat *det)
{
    __global const float *T = (__global const float *)tri_uv;
    const pint j = prim * 6;
    const pvec3 p0 = tri_vertex(MESH_ARGS, prim, 0);
    const pvec3 dp1 = pv3_sub(tri_vertex(MESH_ARGS, prim, 2), p0);
    *dp0 = pv3_sub(tri_vertex(MESH_ARGS, prim, 1), p0);
    const pfloat u0 = pgather(T, j), v0 = pgather(T, j + 1);
    const pfloat du0 = pgather(T, j + 2) - u0, dv0 = pgather(T, j + 3) - v0;
    const pfloat du1 = pgather(T, j + 4) - u0, dv1 = pgather(T, j + 5) - v0;
    *det = du0 * dv1 - dv0 * du1;
    const pfloat inv = 1.0f / *det;
    *dpdu = pv3_scale(pv3_sub(pv3_scale(*dp0, dv1), pv3_scale(dp1, dv0)), inv);
    *dpdv = pv3_scale(pv3_sub(pv3_scale(dp1, du0), pv3_scale(*dp0, du1)), inv);
}
#endif

#ifdef HAS_NORMAL_MAPS
RT_INLINE pint pv3_isfinite(pvec3 a) { return pisfinite(a.x) & pisfinite(a.y) & pisfinite(a.z); }

/* dp/du and dp/dv for the maps; a degenerate parameterisation: the basis around ng (make_onb,
 * Mitsuba's coordinate_system). */
RT_INLINE void triangle_dpduv(MESH_PARAMS, __global const float2 *tri_uv, pint prim, pvec3 ng,
                              pvec3 *dpdu, pvec3 *dpdv)
{
    pvec3 du, dv, dp0;
    pfloat det;
    triangle_uv_derivatives(MESH_ARGS, tri_uv, prim, &du, &dv, &dp0, &det);
    make_onb(ng, dpdu, dpdv);
    const pint ok = (det != 0.0f) & pisfinite(1.0f / det) & pv3_isfinite(du) & pv3_isfinite(dv);
    *dpdu = pv3_sel(*dpdu, du, ok);
    *dpdv = pv3_sel(*dpdv, dv, ok);
}

/* The lanes of `mapped` (triangle hits whose material, mat_index, has a map tex_normal and the
 * flags `flags`): the normal the map tilts N (the shading normal, its own orientation) to, for the
 * viewer at wo; *a2: the shadowing term's alpha^2 (0 without it); each texture looked up over the
 * lanes that read it.  Returns the lanes with a direction (a zero texel gives none: the lane
 * keeps N). */
RT_INLINE pint map_normal_lanes(MESH_PARAMS, __global const float2 *tri_uv,
                                __global const Texture *textures, __global const float4 *tex_data,
                                __global const Material *materials, pint mat_index, pint tex_normal, pint flags,
                                pint mapped, pint prim, pfloat u, pfloat v, pvec3 N, pvec3 ng, pvec3 wo, pvec3 *tilt,
                                pfloat *a2)
{
    const pfloat scale = pgather((__global const float *)materials,
                                 mat_index * STRIDE_INDEX(Material) + FIELD_INDEX(Material, normal_scale));
    const pint safe_prim = mapped ? prim : PINT(0);
    pvec3 dpdu, dpdv, S, S0, B;
    triangle_dpduv(MESH_ARGS, tri_uv, safe_prim, ng, &dpdu, &dpdv);
    S = pv3_normalize(pv3_sub(dpdu, pv3_scale(N, pv3_dot(N, dpdu))), mapped);
    make_onb(N, &S0, &B); /* where dp/du lies along N */
    S = pv3_sel(S0, S, pv3_isfinite(S));
    const pvec3 T = pv3_cross(N, S);
    pfloat tu, tv;
    triangle_uv_lanes(tri_uv, safe_prim, u, v, &tu, &tv);
    const pint bump = mapped & ((flags & MATERIAL_FLAG_BUMP_MAP) != 0), normal_map = mapped & pnot(bump);
    pvec3 tn = pv3_zero();
    if (pany(bump)) {
        pfloat gu, gv;
        tex_gradient_lanes(textures, tex_data, tex_normal, tu, tv, bump, &gu, &gv);
        gu = scale * gu;
        gv = scale * gv;
        const pvec3 du = pv3_add(dpdu, pv3_scale(N, gu - pv3_dot(N, dpdu)));
        const pvec3 dv = pv3_add(dpdv, pv3_scale(N, gv - pv3_dot(N, dpdv)));
        pvec3 nb = pv3_normalize(pv3_cross(du, dv), bump);
        nb = pv3_sel(nb, pv3_neg(nb), pv3_dot(ng, nb) < 0.0f);
        tn = pv3_sel(tn, pv3(pv3_dot(nb, S), pv3_dot(nb, T), pv3_dot(nb, N)), bump);
    }
    if (pany(normal_map)) {
        const TexHit at = {tu, tv, pv3_zero(), ng}; /* a normal map is looked up by uv (scene/validate.py) */
        const pvec3 c = tex_sample_lanes(textures, tex_data, tex_normal, &at, normal_map);
        tn = pv3_sel(tn, pv3((2.0f * c.x - 1.0f) * scale, (2.0f * c.y - 1.0f) * scale, 2.0f * c.z - 1.0f), normal_map);
    }
    /* a viewer behind N sees the map mirrored through the tangent plane (Mitsuba's twosided) */
    const pfloat cos_o = pv3_dot(wo, N);
    const pvec3 Nv = pv3_sel(pv3_neg(N), N, cos_o >= 0.0f);
    const pvec3 tangential = pv3_add(pv3_scale(S, tn.x), pv3_scale(T, tn.y));
    pvec3 n = pv3_add(tangential, pv3_scale(Nv, tn.z));
    const pint whole = (cos_o < 0.0f) & ((flags & MATERIAL_FLAG_MAP_WHOLE) != 0);
    n = pv3_sel(n, pv3_neg(pv3_add(tangential, pv3_scale(N, tn.z))), whole);
    const pint flip = ((flags & MATERIAL_FLAG_MAP_FLIP) != 0) & (pabs(cos_o) * pv3_dot(wo, n) <= 0.0f);
    n = pv3_sel(n, pv3_sub(pv3_sub(pv3_scale(Nv, tn.z), pv3_scale(S, tn.x)), pv3_scale(T, tn.y)), flip);
    n = pv3_normalize(n, mapped);
    const pint ok = mapped & pv3_isfinite(n);
    const pfloat c = pv3_dot(n, Nv), c2 = c * c;
    *a2 = ((flags & MATERIAL_FLAG_MAP_TERMINATOR) != 0) ? pfmin(0.125f * (pfmax(1.0f - c2, PFLOAT(0.0f)) / c2),
                                                                 PFLOAT(1.0f))
                                                          : PFLOAT(0.0f);
    *tilt = n;
    return ok;
}
#endif

#ifdef HAS_ANISOTROPY
/* dp/du of the lanes' triangles (prim valid in every lane) from their vertices and UVs; the edge
 * v1 - v0 where the UVs give none (all UVs equal: a mesh without them) */
RT_INLINE pvec3 triangle_dpdu(MESH_PARAMS, __global const float2 *tri_uv, pint prim)
{
    pvec3 dpdu, dpdv, dp0;
    pfloat det;
    triangle_uv_derivatives(MESH_ARGS, tri_uv, prim, &dpdu, &dpdv, &dp0, &det);
    const pint ok = (det != 0.0f) & pisfinite(dpdu.x + dpdu.y + dpdu.z);
    return pv3_sel(dp0, dpdu, ok);
}
#endif

/* The BSDF's frame at the lanes' hits: ng the unit geometric normal, n it on wo's side, front
 * the geometric side of wo; mat_index the lanes' materials, aniso those with
 * MATERIAL_FLAG_ANISOTROPIC (their tangent is computed with HAS_ANISOTROPY). */
#ifdef HAS_SHADING_NORMALS
/* The unit barycentric interpolation of the vertex normals of the lanes of `tri` (triangle hits):
 * *has where the face has normals (its corners not 0) and their sum is finite, else ng. */
RT_INLINE pvec3 interpolated_normal(__global const float *face_normal, __global const int *prim_ids, pint tri,
                                    pint prim, pfloat u, pfloat v, pvec3 ng, pint *has)
{
    const pint i = tri ? pgather_int(prim_ids, prim) * 9 : PINT(0);
    const pvec3 s = barycentric3(gather9_corner(face_normal, i, 0), gather9_corner(face_normal, i, 1),
                                 gather9_corner(face_normal, i, 2), u, v);
    const pfloat d = pv3_dot(s, s);
    *has = tri & (d > 0.0f) & pisfinite(d);
    return pv3_sel(ng, pv3_normalize(s, *has), *has);
}
#endif

RT_INLINE ShadingLanes shading_lanes(MESH_PARAMS, __global const float *face_normal,
                                     __global const float2 *tri_uv, __global const Texture *textures,
                                     __global const float4 *tex_data, __global const Material *materials,
                                     pint mat_index, pint hit, pint prim, pfloat u, pfloat v, pvec3 ng, pvec3 n,
                                     pint front, pvec3 wo, pint aniso)
{
    ShadingLanes sh;
    sh.n = n;
    sh.t = pv3_zero();
    sh.front = front;
#if defined(HAS_SHADING_NORMALS) || defined(HAS_NORMAL_MAPS)
    pvec3 ns = ng; /* the shading normal, in its own orientation */
#endif
#ifdef HAS_SHADING_NORMALS
    const pint tri = hit & (prim >= 0);
    if (pany(tri)) {
        pint has;
        ns = interpolated_normal(face_normal, prim_ids, tri, prim, u, v, ns, &has);
        const pint sfront = pv3_dot(ns, wo) >= 0.0f;
        sh.front = has ? sfront : front;
        sh.n = pv3_sel(n, pv3_sel(pv3_neg(ns), ns, sfront), has);
    }
#endif
#ifdef HAS_NORMAL_MAPS
    sh.mapped = sh.side = PINT(0);
    sh.base = sh.n; /* the shading normal on wo's side */
    sh.tilt = sh.n;
    sh.a2 = PFLOAT(0.0f);
    const pint tex_normal = pgather_int((__global const int *)materials,
                                        mat_index * STRIDE_INDEX(Material) + FIELD_INDEX(Material, tex_normal));
    const pint mapped = hit & (prim >= 0) & (tex_normal >= 0);
    if (pany(mapped)) {
        pvec3 tilt;
        pfloat a2;
        const pint flags = pgather_int((__global const int *)materials,
                                       mat_index * STRIDE_INDEX(Material) + FIELD_INDEX(Material, flags));
        const pint ok = map_normal_lanes(MESH_ARGS, tri_uv, textures, tex_data, materials, mat_index, tex_normal, flags,
                                         mapped, prim, u, v, ns, ng, wo, &tilt, &a2);
        sh.tilt = pv3_sel(sh.tilt, tilt, ok);
        sh.n = pv3_sel(sh.n, pv3_sel(pv3_neg(tilt), tilt, pv3_dot(wo, tilt) >= 0.0f), ok);
        sh.a2 = ok ? a2 : sh.a2;
        sh.mapped = ok;
        sh.side = ok & ((flags & MATERIAL_FLAG_MAP_SIDE) != 0);
    }
#endif
#ifdef HAS_ANISOTROPY
    aniso &= hit;
    if (pany(aniso)) {
        const pint tri = aniso & pnot(IS_SHAPE(prim));
        pvec3 t = pv3(-ng.y, ng.x, PFLOAT(0.0f)); /* a sphere's dp/du (above) */
        if (pany(tri)) t = pv3_sel(t, triangle_dpdu(MESH_ARGS, tri_uv, tri ? prim : PINT(0)), tri);
#ifdef HAS_NORMAL_MAPS
        /* under a map: the shading frame's tangent (dp/du orthogonal to the shading normal) */
        t = pv3_sel(t, pv3_sub(t, pv3_scale(sh.base, pv3_dot(sh.base, t))), sh.mapped);
#endif
        sh.t = pv3_sel(pv3_zero(), t, aniso);
    }
#else
    (void)aniso;
#endif
    return sh;
}

#ifdef HAS_NORMAL_MAPS
/* The shadowing term of the lanes' maps for direction wi (1 without one). */
RT_INLINE pfloat map_shadowing(const ShadingLanes *sh, pvec3 wi)
{
    const pfloat c = pv3_dot(wi, sh->base), c2 = c * c;
    const pfloat t2 = pfmax(1.0f - c2, PFLOAT(0.0f)) / c2;
    const pfloat g = 2.0f / (1.0f + psqrt(1.0f + sh->a2 * t2));
    return sh->a2 > 0.0f ? g : PFLOAT(1.0f);
}

/* The lanes of `m` where Mitsuba's side test rejects wi. */
RT_INLINE pint map_wrong_side(const ShadingLanes *sh, pvec3 wi)
{
    return sh->side & ((pv3_dot(wi, sh->base) * pv3_dot(wi, sh->tilt)) <= 0.0f);
}
#endif

/* bsdf_eval's f and *pdf with the lanes' map rules applied (nothing without maps). */
RT_INLINE pvec3 shading_eval(const ShadingLanes *sh, pvec3 wi, pvec3 f, pfloat *pdf)
{
#ifdef HAS_NORMAL_MAPS
    if (pany(sh->mapped)) {
        const pint wrong = sh->mapped & map_wrong_side(sh, wi);
        f = pv3_sel(f, pv3_scale(f, map_shadowing(sh, wi)), sh->mapped);
        f = pv3_sel(f, pv3_zero(), wrong);
        *pdf = wrong ? PFLOAT(0.0f) : *pdf;
    }
#endif
    return f;
}

/* bsdf_sample's weight with the lanes' map rules applied (nothing without maps). */
RT_INLINE pvec3 shading_sample(const ShadingLanes *sh, pvec3 wi, pvec3 weight, pfloat *pdf)
{
    return shading_eval(sh, wi, weight, pdf);
}

#endif
