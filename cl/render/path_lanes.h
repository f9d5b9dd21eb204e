/* The path integrator of cl/render/path.h with PACKET_WIDTH paths in the lanes of vectors, for
 * the scenes it covers: triangles with the diffuse material, lit by emissive triangles, the MIS
 * integrator (INTEGRATOR 0), no textures (pyopencl_rt/render/megakernel.py: lanes_supported).
 *
 * Why: on a CPU, a path in one work-item is scalar code, and Mitsuba 3's LLVM backend, which runs
 * 8 or 16 paths per instruction, was 2x faster per sample on the Cornell box (docs/BENCHMARKS.md).
 * Here each step of path_shade_hit is done for all lanes at once; what differs per lane (the hit
 * triangle, its material, the light picked) is gathered into the lanes first.
 *
 * Every lane computes exactly what path_shade_hit computes for its path, in the same order, with
 * the same random numbers (sampler_lanes.h) and the same arithmetic (lanes.h): the image equals
 * the one-path megakernel's bit for bit, except where the packet traversal reports the other of
 * two triangles at exactly the same distance (tests/render/test_path_lanes.py).  The per-lane
 * fallbacks of path.h's helpers (double precision near a light's plane, the rescaling
 * normalize) run in scalar code for the lanes that need them. */
#ifndef PYOPENCL_RT_PATH_LANES_H
#define PYOPENCL_RT_PATH_LANES_H

#include "render/path.h"
#include "accel/bvh_packet.h"
#include "render/sampler_lanes.h"

#if INTEGRATOR != 0 || !defined(HAS_LIGHTS) || !defined(HAS_TRIANGLES) || defined(HAS_SPHERES) ||       \
    defined(HAS_TEXTURES) || defined(HAS_AOVS) || defined(HAS_DELTA_LIGHTS) || defined(HAS_ENVIRONMENT) || \
    defined(HAS_INFINITE_LIGHTS) || defined(HAS_MATERIAL_CONDUCTOR) || defined(HAS_MATERIAL_DIELECTRIC) ||  \
    defined(HAS_MATERIAL_GLTF) || !defined(MATERIALS_SELECTED)
#error "path_lanes.h covers diffuse triangles lit by emissive triangles (megakernel.lanes_supported)"
#endif

/* The state of the lanes' paths: PathState per lane, and each path's SampleKey. */
typedef struct {
    pvec3 o, d, beta, L;
    pfloat pdf, eta_scale;
    pint depth;
    SampleKeyLanes key;
} PathLanes;

RT_INLINE void lanes_set_path(PathLanes *s, int k, PathState p, SampleKey key)
{
    pv3_set_lane(&s->o, k, p.o); pv3_set_lane(&s->d, k, p.d);
    pv3_set_lane(&s->beta, k, p.beta); pv3_set_lane(&s->L, k, p.L);
    PLANE(s->pdf, k) = p.pdf; PLANE(s->eta_scale, k) = p.eta_scale; PLANE_I(s->depth, k) = p.depth;
    PLANE_U(s->key.a, k) = key.a; PLANE_U(s->key.b, k) = key.b; PLANE_U(s->key.c, k) = key.c;
}

/* A triangle's vertices per lane (tris[3 * prim], ...). */
typedef struct { pvec3 p0, p1, p2; } TriLanes;

RT_INLINE TriLanes gather_triangles(__global const float4 *tris, pint prim)
{
    __global const float *f = (__global const float *)tris;
    const pint i = prim * 12; /* three float4 a triangle */
    TriLanes t;
    t.p0 = pv3(pgather(f, i), pgather(f, i + 1), pgather(f, i + 2));
    t.p1 = pv3(pgather(f, i + 4), pgather(f, i + 5), pgather(f, i + 6));
    t.p2 = pv3(pgather(f, i + 8), pgather(f, i + 9), pgather(f, i + 10));
    return t;
}

/* triangle_point (spawn.h): the point of barycentrics (u, v) and its error bound */
RT_INLINE pvec3 triangle_point_lanes(TriLanes t, pfloat u, pfloat v, pvec3 *err)
{
    const pfloat w = 1.0f - u - v;
    const pvec3 a = pv3_scale(t.p0, w), b = pv3_scale(t.p1, u), c = pv3_scale(t.p2, v);
    *err = pv3_scale(pv3_add(pv3_add(pv3_abs(a), pv3_abs(b)), pv3_abs(c)), PFLOAT(SPAWN_GAMMA7));
    return pv3_add(pv3_add(a, b), c);
}

/* offset_ray_origin_bound (spawn.h) */
RT_INLINE pfloat spawn_component_lanes(pfloat p, pfloat n)
{
    const pint of = convert_pint(SPAWN_INT_SCALE * n);
    const pfloat pi = as_pfloat(as_pint(p) + (p < 0.0f ? -of : of));
    return pabs(p) < SPAWN_ORIGIN ? p + SPAWN_FLOAT_SCALE * n : pi;
}

RT_INLINE pfloat spawn_away_lanes(pfloat x, pfloat off)
{
    const pfloat moved = pnextafter_inf(x, off > 0.0f);
    return ((off > 0.0f) | (off < 0.0f)) ? moved : x;
}

RT_INLINE pvec3 offset_ray_origin_bound_lanes(pvec3 p, pvec3 err, pvec3 n)
{
    const pvec3 off = pv3_scale(n, pv3_dot(pv3_abs(n), err));
    const pvec3 po = pv3_add(p, off);
    const pvec3 pb = pv3(spawn_away_lanes(po.x, off.x), spawn_away_lanes(po.y, off.y), spawn_away_lanes(po.z, off.z));
    const pvec3 pw = pv3(spawn_component_lanes(p.x, n.x), spawn_component_lanes(p.y, n.y), spawn_component_lanes(p.z, n.z));
    const pvec3 db = pv3_abs(pv3_sub(pb, p)), dw = pv3_abs(pv3_sub(pw, p));
    return pv3(db.x > dw.x ? pb.x : pw.x, db.y > dw.y ? pb.y : pw.y, db.z > dw.z ? pb.z : pw.z);
}

/* power_heuristic (sampling.h) */
RT_INLINE pfloat power_heuristic_lanes(pfloat a, pfloat b)
{
    const pfloat r = b / a;
    pfloat w = 1.0f / (1.0f + r * r);
    w = pisinf(a) ? (pisinf(b) ? PFLOAT(0.5f) : PFLOAT(1.0f)) : w;
    return b == 0.0f ? PFLOAT(1.0f) : w;
}

/* emitted (lights.h): the material's emission where it faces w (or is two-sided), else 0 */
RT_INLINE pvec3 emitted_lanes(pvec3 emission, pint two_sided, pvec3 ng, pvec3 w)
{
    const pint dark = ~two_sided & (pv3_dot(ng, w) <= 0.0f);
    return pv3_sel(emission, pv3_splat((float3)(0.0f)), dark);
}

/* The materials' fields the lanes use: albedo, emission, two-sidedness, ior. */
typedef struct {
    pvec3 albedo, emission;
    pint two_sided;
    pfloat ior;
} MaterialLanes;

RT_INLINE MaterialLanes gather_materials(__global const Material *materials, pint index)
{
    __global const float *f = (__global const float *)materials;
    const pint i = index * STRIDE_INDEX(Material);
    const pint albedo = i + FIELD_INDEX(Material, albedo), emission = i + FIELD_INDEX(Material, emission);
    MaterialLanes m;
    m.albedo = pv3(pgather(f, albedo), pgather(f, albedo + 1), pgather(f, albedo + 2));
    m.emission = pv3(pgather(f, emission), pgather(f, emission + 1), pgather(f, emission + 2));
    const pint flags = pgather_int((__global const int *)f, i + FIELD_INDEX(Material, flags));
    m.two_sided = (flags & MATERIAL_FLAG_TWO_SIDED) != 0; /* a vector comparison: -1 where true */
    m.ior = pgather(f, i + FIELD_INDEX(Material, ior));
    return m;
}

/* plane_distance (spawn.h) of ref from each lane's triangle; lanes in doubt (and in `live`) take
 * the scalar function, which refines in double precision */
RT_INLINE pfloat plane_distance_lanes(TriLanes t, pvec3 q, pint live)
{
    const pvec3 e1 = pv3_sub(t.p1, t.p0), e2 = pv3_sub(t.p2, t.p0), a = pv3_sub(q, t.p0);
    const pvec3 n = pv3_cross(e1, e2);
    const pvec3 n_abs = pv3(pabs(e1.y * e2.z) + pabs(e1.z * e2.y), pabs(e1.z * e2.x) + pabs(e1.x * e2.z),
                            pabs(e1.x * e2.y) + pabs(e1.y * e2.x));
    const pfloat h = pv3_dot(n, a);
    pfloat r = h / pv3_length(n, live);
    const pint doubt = live & (pabs(h) <= PLANE_DOUBT * pv3_dot(n_abs, pv3_abs(a)));
    if (pany(doubt))
        for (int k = 0; k < PACKET_WIDTH; ++k)
            if (PLANE_I(doubt, k))
                PLANE(r, k) = plane_distance(pv3_lane(t.p0, k), pv3_lane(t.p1, k), pv3_lane(t.p2, k), pv3_lane(q, k));
    return r;
}

/* make_onb (sampling.h) */
RT_INLINE void make_onb_lanes(pvec3 n, pvec3 *t, pvec3 *b)
{
    const pfloat sign = pcopysign(PFLOAT(1.0f), n.z);
    const pfloat a = -1.0f / (sign + n.z);
    const pfloat c = n.x * n.y * a;
    *t = pv3(1.0f + sign * n.x * n.x * a, sign * c, -sign * n.x);
    *b = pv3(c, sign + n.y * n.y * a, -n.y);
}

/* sample_concentric_disk and sample_cosine_hemisphere (sampling.h) */
RT_INLINE pvec3 sample_cosine_hemisphere_lanes(pfloat ux, pfloat uy)
{
    const pfloat ox = 2.0f * ux - 1.0f, oy = 2.0f * uy - 1.0f;
    const pint wide_x = pabs(ox) > pabs(oy);
    const pfloat major = wide_x ? ox : oy, minor = wide_x ? oy : ox;
    const pfloat x = (0.25f * PI_F) * (minor / major);
    const pfloat x2 = x * x;
    const pfloat s = SIN_QUARTER(x, x2), c = COS_QUARTER(x2); /* sincos_quarter */
    const pint center = (ox == 0.0f) & (oy == 0.0f);
    const pfloat dx = center ? PFLOAT(0.0f) : major * (wide_x ? c : s);
    const pfloat dy = center ? PFLOAT(0.0f) : major * (wide_x ? s : c);
    return pv3(dx, dy, psqrt(pfmax(PFLOAT(0.0f), 1.0f - dx * dx - dy * dy)));
}

/* Shades the lanes' hits (path_shade_hit for each lane in `hit`): returns the lanes whose paths
 * go on (s then holds their next rays) in *goes_on and those with a light sample to test in
 * *with_shadow (its ray in so, sd, what it adds in contribution).  `t`, `prim`, `u`, `v`: the
 * hits; lanes outside `hit` are left as they are. */
RT_INLINE void shade_lanes(__global const float4 *tris, __global const int *tri_material,
                           __global const int *tri_light, __global const Material *materials,
                           __global const Light *lights, const int n_lights, const int max_depth,
                           const int rr_depth, pint hit, pint prim, pfloat u, pfloat v, PathLanes *s,
                           pint *goes_on, pint *with_shadow, pvec3 *so, pvec3 *sd, pvec3 *contribution)
{
    prim = hit ? prim : PINT(0); /* a valid index in every lane for the gathers */
    *so = *sd = *contribution = pv3_splat((float3)(0.0f)); /* defined in every lane */
    const TriLanes tri = gather_triangles(tris, prim);
    pvec3 p_err;
    const pvec3 p = triangle_point_lanes(tri, u, v, &p_err);
    const pvec3 ng = pv3_normalize(pv3_cross(pv3_sub(tri.p1, tri.p0), pv3_sub(tri.p2, tri.p0)), hit);
    const pvec3 wo = pv3_neg(s->d);
    const pint front = pv3_dot(ng, wo) >= 0.0f;
    const pvec3 n = pv3_sel(pv3_neg(ng), ng, front);
    const pint mat_index = pgather_int(tri_material, prim), light_index = pgather_int(tri_light, prim);
    const MaterialLanes m = gather_materials(materials, mat_index);
    const puint dim = convert_puint(2 + DIMS_PER_BOUNCE * s->depth);

    /* -- emission seen by the path ---------------------------------------------------------- */
    const pvec3 Le = emitted_lanes(m.emission, m.two_sided, ng, wo);
    const pint glows = hit & (pv3_max3(Le) > 0.0f);
    if (pany(glows)) {
        /* MIS weight against light sampling (light_pdf of the hit light, from the ray's origin) */
        const pint mis = glows & (s->pdf > 0.0f) & (light_index >= 0);
        __global const float *light_f = (__global const float *)lights;
        const pint row = (light_index < 0 ? PINT(0) : light_index) * STRIDE_INDEX(Light);
        const pfloat pmf = pgather(light_f, row + FIELD_INDEX(Light, pmf));
        const pfloat area = pgather(light_f, row + FIELD_INDEX(Light, area));
        const pvec3 to_ref = pv3_sub(s->o, p);
        const pfloat dist2 = pv3_dot(to_ref, to_ref);
        const pfloat cos_l = pabs(pv3_dot(ng, to_ref)) * (1.0f / psqrt(dist2));
        const pfloat lpdf = cos_l > 0.0f ? dist2 / (area * cos_l) : PFLOAT(0.0f);
        const pfloat w = mis ? power_heuristic_lanes(s->pdf, pmf * lpdf) : PFLOAT(1.0f);
        s->L = pv3_sel(s->L, pv3_add(s->L, pv3_scale(pv3_mul(s->beta, Le), w)), glows);
    }

    const pint segments = s->depth + 1;
    const pint going = hit & (max_depth >= 0 ? segments < max_depth : PINT(-1));
    *goes_on = PINT(0);
    *with_shadow = PINT(0);
    if (!pany(going)) return;
    SampleKeyLanes key = s->key;
    const pfloat u_pick = sample_1d_lanes(key, dim + DIM_LIGHT_PICK);
    pfloat ulx, uly, ubx, uby;
    sample_2d_lanes(key, dim + DIM_LIGHT_POINT, &ulx, &uly);
    sample_2d_lanes(key, dim + DIM_BSDF, &ubx, &uby);
    const pvec3 ref = offset_ray_origin_bound_lanes(p, p_err, n);
    /* the spawn point on the other side: a shadow ray or a sample leaving below n */
    const pvec3 below = offset_ray_origin_bound_lanes(p, p_err, pv3_neg(n));

    /* -- next-event estimation: one emissive triangle, picked by power (sample_alias) -------- */
    {
        const pfloat x = u_pick * (float)n_lights;
        pint li = convert_pint(x);
        li = li < n_lights - 1 ? li : PINT(n_lights - 1);
        const pfloat frac = x - convert_pfloat(li);
        /* sample_alias: column li keeps its light below alias_prob, else takes its alias */
        __global const float *light_f = (__global const float *)lights;
        __global const int *light_i = (__global const int *)lights;
        const pint column = li * STRIDE_INDEX(Light);
        const pint pick = (frac >= pgather(light_f, column + FIELD_INDEX(Light, alias_prob)))
                              ? pgather_int(light_i, column + FIELD_INDEX(Light, alias)) : li;
        const pint row = pick * STRIDE_INDEX(Light);
        const pfloat pick_pmf = pgather(light_f, row + FIELD_INDEX(Light, pmf));
        const pfloat area = pgather(light_f, row + FIELD_INDEX(Light, area));
        const pint lprim = pgather_int(light_i, row + FIELD_INDEX(Light, prim));
        const pint lmat = pgather_int(light_i, row + FIELD_INDEX(Light, material));
        const TriLanes lt = gather_triangles(tris, going ? lprim : PINT(0));
        /* light_sample for a triangle: sample_triangle_barycentrics, then the point */
        const pint upper = uly > ulx;
        const pfloat b1 = upper ? 0.5f * ulx : ulx - 0.5f * uly;
        const pfloat b2 = upper ? uly - 0.5f * ulx : 0.5f * uly;
        pvec3 lp_err;
        const pvec3 lp = triangle_point_lanes(lt, b1, b2, &lp_err);
        const pvec3 lng = pv3_normalize(pv3_cross(pv3_sub(lt.p1, lt.p0), pv3_sub(lt.p2, lt.p0)), going);
        const pvec3 to_ref = pv3_sub(ref, lp);
        const pfloat dist2 = pv3_dot(to_ref, to_ref);
        const pfloat cos_l = plane_distance_lanes(lt, ref, going) * (1.0f / psqrt(dist2));
        const pvec3 ln = pv3_sel(pv3_neg(lng), lng, cos_l > 0.0f);
        const MaterialLanes lm = gather_materials(materials, going ? lmat : PINT(0));
        const pvec3 lLe = emitted_lanes(lm.emission, lm.two_sided, lng, ln);
        const pfloat ls_pdf = dist2 / (area * pabs(cos_l));
        const pint sampled = going & (pick_pmf > 0.0f) & (cos_l != 0.0f) & (dist2 != 0.0f) & (ls_pdf > 0.0f) &
                             (pv3_max3(lLe) > 0.0f);
        if (pany(sampled)) {
            pvec3 wi = pv3_sub(lp, ref);
            const pfloat dist = pv3_length(wi, sampled);
            wi = pv3_div(wi, dist);
            /* diffuse_eval */
            const pfloat cos_i = pv3_dot(n, wi);
            const pfloat bpdf = cos_i <= 0.0f ? PFLOAT(0.0f) : cos_i * INV_PI_F;
            const pvec3 f = pv3_sel(pv3_scale(m.albedo, cos_i * INV_PI_F), pv3_splat((float3)(0.0f)), cos_i <= 0.0f);
            const pint lit = sampled & (pv3_max3(f) > 0.0f) & (dist > 0.0f);
            if (pany(lit)) {
                const pfloat lpdf = pick_pmf * ls_pdf;
                const pfloat w = power_heuristic_lanes(lpdf, bpdf);
                const pvec3 o_shadow = pv3_sel(below, ref, cos_i > 0.0f);
                const pvec3 sp = offset_ray_origin_bound_lanes(lp, lp_err, ln);
                *so = o_shadow;
                *sd = pv3_sub(sp, o_shadow);
                *contribution = pv3_scale(pv3_mul(pv3_mul(s->beta, f), lLe), w / lpdf);
                *with_shadow = lit;
            }
        }
    }

    /* -- BSDF sampling continues the path: diffuse_sample ------------------------------------ */
    pvec3 t, b;
    make_onb_lanes(n, &t, &b);
    const pvec3 h = sample_cosine_hemisphere_lanes(ubx, uby);
    const pvec3 wi = pv3_normalize(pv3_add(pv3_add(pv3_scale(t, h.x), pv3_scale(b, h.y)), pv3_scale(n, h.z)), going);
    const pfloat pdf = pfmax(h.z, PFLOAT(0.0f)) * INV_PI_F;
    const pint sampled = going & (pdf > 0.0f) & (pv3_max3(m.albedo) > 0.0f);
    const pvec3 beta = pv3_mul(s->beta, m.albedo);
    /* eta_scale: dielectric_eta of a diffuse surface (1 unless it has an ior), for a sample below n */
    const pfloat ior = m.ior > 0.0f ? m.ior : PFLOAT(1.0f);
    const pfloat eta = front ? ior : 1.0f / ior;
    const pfloat eta_scale = pv3_dot(wi, n) < 0.0f ? s->eta_scale * (eta * eta) : s->eta_scale;
    const pint roulette = segments >= rr_depth;
#ifdef RR_NO_ETA
    const pfloat q = pfmin(pv3_max3(beta), PFLOAT(0.95f));
#else
    const pfloat q = pfmin(pv3_max3(beta) * eta_scale, PFLOAT(0.95f));
#endif
    pint on = sampled;
    if (pany(roulette & sampled))
        on &= ~roulette | (sample_1d_lanes(key, dim + DIM_RR) < q);
    s->beta = pv3_sel(s->beta, pv3_sel(beta, pv3_div(beta, q), roulette), on);
    const pvec3 o_next = pv3_sel(below, ref, (pv3_dot(ng, wi) > 0.0f) == front);
    s->o = pv3_sel(s->o, o_next, on);
    s->d = pv3_sel(s->d, wi, on);
    s->pdf = on ? pdf : s->pdf;
    s->eta_scale = on ? eta_scale : s->eta_scale;
    s->depth = on ? segments : s->depth;
    *goes_on = on;
}

#endif
