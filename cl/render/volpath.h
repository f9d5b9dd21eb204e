/* The volumetric steps of the path integrator (compiled with HAS_MEDIA: a scene with participating media
 * or index-matched boundaries), written over the lanes as cl/render/path.h is, from the building blocks
 * of cl/render/media.h.  They follow Mitsuba 3's volpath / volpathmis (and pbrt-v4's VolPathIntegrator):
 *
 *   path_start_media   a new path's medium (the camera's), hero channel and tracking stream
 *   path_medium        after the closest hit of a ray in a medium: a free flight to the hit (delta
 *                      tracking; the exponential distance in a homogeneous medium).  A real collision
 *                      scatters there: next-event estimation (one light sample, its transmittance
 *                      estimated on the way, MIS against phase sampling with the power heuristic;
 *                      weight 1 for delta lights), then a phase-function sample continues the path,
 *                      with Russian roulette as after a surface.  A ray that reaches an index-matched
 *                      (null) surface goes straight through it, into the medium behind it, without a
 *                      bounce (its depth and last scattering vertex unchanged: Mitsuba's null BSDF).
 *   path_surface_media after path_shade at ordinary surfaces: a surface with a MediumInterface that
 *                      is a transition (a dielectric, any shape bounding a medium) puts the BSDF sample
 *                      and the shadow ray in the medium on the side they leave to.
 *   volpath_vertex     the whole step at a path's next vertex, as every schedule takes it: path_medium,
 *                      then the environment or path_shade, then path_surface_media
 *   shadow_transmittance  a shadow ray's transmittance: through media (closed form in a homogeneous
 *                      one, ratio tracking in a grid) and through null surfaces; 0 if another surface
 *                      blocks it.
 *
 * Spectral MIS (SPECTRAL_MIS: a chromatic medium, RenderSettings.spectral_mis): the free flights
 * multiply the path's beta by f_k / p_c and its ratios r by p_k / p_c (media.h); the path then keeps
 * beta / mean(r) and r / mean(r), so that beta is the balance-heuristic estimate at every vertex (what
 * path_shade adds and rouletting weighs) and r keeps the channels' relative densities (mean 1) for the
 * next distances and the shadow rays' ratio tracking.  Without it r is not kept: beta alone is
 * Mitsuba volpath's single-channel estimate (exact for a grey medium, where r stays 1).
 *
 * The random numbers of a scattering vertex are the bounce's own sampler dimensions (light pick and
 * point, DIM_BSDF for the phase sample, DIM_RR): a vertex is in a medium or on a surface, never both.
 * Tracking draws from the path's stream (s->rng), which runs on over the whole path. */
#ifndef PYOPENCL_RT_VOLPATH_H
#define PYOPENCL_RT_VOLPATH_H

#include "render/path.h"
#include "render/media.h"

#ifdef HAS_MEDIA /* the integrator of scenes with media (PathState's media fields) */

#define MEDIA_PATH_PARAMS                                                                                   \
    __global const Medium *media, __global const MediumGrid *medium_grids, __global const float *grid_data, \
        __global const MediumInterface *medium_interfaces, __global const int *tri_interface,               \
        __global const int *shape_interface, const int spectral_mis
#define MEDIA_PATH_ARGS media, medium_grids, grid_data, medium_interfaces, tri_interface, shape_interface, spectral_mis

/* Whether the channels are combined by spectral MIS: always where SPECTRAL_MIS is the scene's; the
 * kernels' spectral_mis where SPECTRAL_MIS_RUNTIME compiles it in for every scene with media
 * (PYOPENCL_RT_KERNEL_FEATURES=all). */
#ifdef SPECTRAL_MIS_RUNTIME
#define SPECTRAL_MIS_ON (spectral_mis != 0)
#else
#define SPECTRAL_MIS_ON 1
#endif

/* at most this many surfaces a shadow ray passes through */
#define MAX_NULL_CROSSINGS 64

/* The lanes of `m` start paths in camera_medium. */
RT_INLINE void path_start_media(PathState *s, pint m, int camera_medium, SampleKey key)
{
    puint rng = hash_u32(key.a ^ hash_u32(key.b ^ hash_u32(key.c + 0x6D2B79F5u)));
    const pint channel = medium_channel(medium_uniform(&rng, m));
    s->medium = m ? PINT(camera_medium) : s->medium;
    s->channel = m ? channel : s->channel;
    s->rng = m ? rng : s->rng;
    s->r = pv3_sel(s->r, pv3_splat((float3)(1.0f)), m);
    s->ref = pv3_sel(s->ref, s->o, m);
}

/* The medium interface of each lane's primitive (-1: none; prim valid in every lane) */
RT_INLINE pint hit_interface(__global const int *tri_interface, __global const int *shape_interface, pint prim)
{
#if defined(HAS_SHAPES) && defined(HAS_TRIANGLES)
    const pint shape = IS_SHAPE(prim);
    const pint si = shape ? SHAPE_INDEX(prim) : PINT(0), ti = shape ? PINT(0) : prim;
    return shape ? pgather_int(shape_interface, si) : pgather_int(tri_interface, ti);
#elif defined(HAS_SHAPES)
    return pgather_int(shape_interface, SHAPE_INDEX(prim));
#else
    return pgather_int(tri_interface, prim);
#endif
}

/* The flags of interface ii (0 where ii < 0) */
RT_INLINE pint interface_flags(__global const MediumInterface *interfaces, pint ii)
{
    const pint has = ii >= 0;
    const pint f = pgather_int((__global const int *)interfaces,
                               (has ? ii : PINT(0)) * STRIDE_INDEX(MediumInterface) + FIELD_INDEX(MediumInterface, flags));
    return has ? f : PINT(0);
}

/* beta / mean(r) and r / mean(r) in the lanes of `m` (see the top); r stays 1 without spectral MIS
 * (`on`: SPECTRAL_MIS_ON) */
RT_INLINE void spectral_normalise(pvec3 *beta, pvec3 *r, pint m, int on)
{
#ifdef SPECTRAL_MIS
    if (on) {
        const pfloat mean = pv3_mean(*r);
        const pint ok = m & (mean > 0.0f) & pisfinite(mean);
        *beta = pv3_sel(*beta, pv3_sel(pv3_zero(), pv3_div(*beta, ok ? mean : PFLOAT(1.0f)), ok), m);
        *r = pv3_sel(*r, pv3_sel(pv3_splat((float3)(1.0f)), pv3_div(*r, ok ? mean : PFLOAT(1.0f)), ok), m);
        return;
    }
#endif
    *r = pv3_sel(*r, pv3_splat((float3)(1.0f)), m);
}

/* Thin dielectric sheets (MATERIAL_FLAG_THIN, Mitsuba's thindielectric) are null boundaries that
 * reflect: Mitsuba flags their straight-through lobe Null, so volpath crosses them without a bounce and
 * its shadow rays pass them with the transmission 1 - R (R = 2F / (1 + F), F = Fr(|cos|, eta)), cos
 * in the shading frame (n: the interpolated normal where the mesh has one, as Mitsuba's BSDFs see
 * it).  The lanes of `live` whose primitive's material is one: *thin, with the transmission along d. */
RT_INLINE pfloat thin_sheet(__global const int *tri_material, __global const int *shape_material,
                            __global const Material *materials, pint prim, pint live, pvec3 ng, pvec3 d, pint *thin)
{
    pint mi, li_unused;
    hit_records(tri_material, tri_material, shape_material, shape_material, prim, &mi, &li_unused);
    __global const int *n = (__global const int *)materials;
    const pint base = mi * STRIDE_INDEX(Material);
    const pint type = pgather_int(n, base + FIELD_INDEX(Material, type));
    const pint flags = pgather_int(n, base + FIELD_INDEX(Material, flags));
    *thin = live & (type == MATERIAL_DIELECTRIC) & ((flags & MATERIAL_FLAG_THIN) != 0);
    pfloat t = PFLOAT(1.0f);
    if (pany(*thin)) {
        const pfloat ior = pgather((__global const float *)materials, base + FIELD_INDEX(Material, ior));
        const pfloat cos = pabs(pv3_dot(ng, d)) / pv3_length(d, *thin);
        const pfloat F = fresnel_dielectric(pclamp(cos, 0.0f, 1.0f), ior);
        t = *thin ? 1.0f - 2.0f * F / (1.0f + F) : t;
    }
    return t;
}

/* The normal a thin sheet's BSDF sees at the lanes' hits: the interpolated vertex normal of a
 * smooth mesh, else the geometric normal ng. */
RT_INLINE pvec3 sheet_normal(__global const float *face_normal, __global const int *prim_ids, pint live, pint prim,
                             pfloat u, pfloat v, pvec3 ng)
{
#ifdef HAS_SHADING_NORMALS
    pint has;
    return interpolated_normal(face_normal, prim_ids, live & (prim >= 0), prim, u, v, ng, &has);
#else
    return ng;
#endif
}

/* The transmittance of the shadow rays o + t d, t in (0, 1), of the lanes of `active`, which start in
 * `medium`: through media and null surfaces (crossing into the medium behind each), 0 where another
 * surface (or more than MAX_NULL_CROSSINGS null ones) blocks it.  r: the path's ratios (mean 1); the
 * result is the spectral-MIS estimate of the transmittance given them. */
RT_INLINE pvec3 shadow_transmittance(__global const BVHNode *nodes, __global const float4 *tris, MESH_PARAMS,
                                     __global const float *face_normal,
                                     __global const BVHNode *shape_nodes, __global const Shape *shapes, __global const int *tri_material,
                                     __global const int *shape_material, __global const Material *materials,
                                     MEDIA_PATH_PARAMS, pvec3 o, pvec3 d,
                                     pint medium, pint channel, puint *rng, pvec3 r, pint active)
{
    pvec3 T = pv3_splat((float3)(1.0f)), ratios = r;
    const pvec3 end = pv3_add(o, d);
    pint live = active;
    for (int crossing = 0; crossing <= MAX_NULL_CROSSINGS && pany(live); ++crossing) {
        const pvec3 seg = pv3_sub(end, o);
        pfloat th, u, v;
        pint prim;
        scene_closest_hit(nodes, tris, shape_nodes, shapes, o, seg, live, &th, &prim, &u, &v);
        const pint blocked = live & (prim != PRIM_MISS) & (th < 1.0f);
        const pint inside = live & (medium >= 0);
        if (pany(inside)) {
            const pfloat len = pv3_length(seg, inside);
            const pvec3 dir = pv3_div(seg, inside ? len : PFLOAT(1.0f));
            const MediumLanes med = medium_lanes(media, medium_grids, inside ? medium : PINT(0));
            medium_transmittance(&med, grid_data, o, dir, PFLOAT(0.0f), (blocked ? th : PFLOAT(1.0f)) * len, channel,
                                 rng, inside, &T, &ratios);
        }
        live = blocked & (pv3_max3(T) > 0.0f);
        if (!pany(live)) break;
        const pint at = live ? prim : PINT(ANY_PRIM);
        const pint ii = hit_interface(tri_interface, shape_interface, at);
        pint null = live & ((interface_flags(medium_interfaces, ii) & MEDIUM_IF_NULL) != 0);
#ifdef HAS_MATERIAL_DIELECTRIC
        {
            pvec3 p_err;
            const pvec3 ph = hit_point(MESH_ARGS, shapes, at, o, seg, th, u, v, &p_err);
            pint thin;
            const pvec3 sn = sheet_normal(face_normal, prim_ids, live, at, u, v, hit_normal(MESH_ARGS, shapes, at, ph, live));
            const pfloat tr = thin_sheet(tri_material, shape_material, materials, at, live & pnot(null), sn, seg, &thin);
            T = pv3_sel(T, pv3_scale(T, tr), thin);
            null |= thin;
        }
#endif
        const int last = crossing == MAX_NULL_CROSSINGS; /* a scalar: select masks with it, never & */
        T = pv3_sel(T, pv3_zero(), (live & pnot(null)) | (last ? null : PINT(0)));
        live = last ? PINT(0) : null;
        if (!pany(live)) break;
        pvec3 p_err;
        const pvec3 p = hit_point(MESH_ARGS, shapes, at, o, seg, th, u, v, &p_err);
        const pvec3 ng = hit_normal(MESH_ARGS, shapes, at, p, live);
        pint unused;
        const pint next = medium_after_crossing(medium_interfaces, ii, ng, seg, medium, &unused);
        medium = live ? next : medium;
        const pvec3 beyond = offset_ray_origin_bound(p, p_err, pv3_sel(pv3_neg(ng), ng, pv3_dot(ng, seg) > 0.0f));
        o = pv3_sel(o, beyond, live);
    }
#ifdef SPECTRAL_MIS
    if (SPECTRAL_MIS_ON) return spectral_mis_estimate(T, ratios);
#endif
    return T;
}

/* The medium step of the lanes of `live` (see the top), after their closest hits (prim, t, u, v; `hit`:
 * the lanes that hit a surface).  *scattered: the lanes whose path met a real collision (continued by a
 * phase sample in *goes_on, or ended); *crossed: the lanes that went through a null surface (their
 * next ray set, in *goes_on too).  Neither is shaded at its surface; the others' beta carries the
 * free flight's weight.  *with_shadow, *shadow, *shadow_medium: the scattering lanes' light samples.
 * *iface, *ng: each hit lane's surface interface and front normal (path_surface_media). */
RT_INLINE void path_medium(PATH_PARAMS, MEDIA_PATH_PARAMS, SampleKey key, pint live, pint hit, pint prim, pfloat t,
                           pfloat u, pfloat v, PathState *s, pint *scattered, pint *crossed, pint *goes_on,
                           pint *with_shadow, ShadowRay *shadow, pint *shadow_medium, pint *iface, pvec3 *ng)
{
    *scattered = *crossed = *goes_on = *with_shadow = PINT(0);
    *shadow_medium = PINT(MEDIUM_VACUUM);
    shadow->o = shadow->d = shadow->contribution = pv3_zero();
    const pint at = hit ? prim : PINT(ANY_PRIM);
    *iface = hit ? hit_interface(tri_interface, shape_interface, at) : PINT(-1);
    *ng = pv3_zero();

    /* -- the free flight ------------------------------------------------------------------------ */
    const pint inside = live & (s->medium >= 0);
    pint real = PINT(0);
    pfloat ts = t;
    MediumLanes med;
    if (pany(inside)) {
        med = medium_lanes(media, medium_grids, inside ? s->medium : PINT(0));
        pvec3 beta = s->beta, r = s->r;
        real = medium_sample_free_flight(&med, grid_data, s->o, s->d, PFLOAT(0.0f), hit ? t : PFLOAT(INFINITY),
                                         s->channel, &s->rng, inside, &ts, &beta, &r);
        spectral_normalise(&beta, &r, inside, SPECTRAL_MIS_ON);
        s->beta = pv3_sel(s->beta, beta, inside);
        s->r = pv3_sel(s->r, r, inside);
    }
    *scattered = real;

    /* -- null surfaces: straight through, into the medium behind ------------------------------- */
    const pint surf = hit & pnot(real);
#ifdef HAS_MATERIAL_DIELECTRIC
    const pint boundary = surf;
#else
    const pint boundary = surf & (*iface >= 0);
#endif
    if (pany(boundary)) {
        pvec3 p_err;
        const pvec3 p = hit_point(MESH_ARGS, shapes, at, s->o, s->d, t, u, v, &p_err);
        *ng = hit_normal(MESH_ARGS, shapes, at, p, boundary);
        pint null;
        const pint next = medium_after_crossing(medium_interfaces, *iface, *ng, s->d, s->medium, &null);
        null &= boundary;
#ifdef HAS_MATERIAL_DIELECTRIC
        /* a thin sheet: straight through with probability 1 - R, a null event; else a delta reflection
         * (a bounce) about the shading normal, as Mitsuba's thindielectric reflects in its shading
         * frame; the choice from the tracking stream (a crossing takes no sampler dimension) */
        pint thin;
        const pvec3 sn = sheet_normal(face_normal, prim_ids, boundary, at, u, v, *ng);
        const pfloat tr = thin_sheet(tri_material, shape_material, materials, at, boundary & pnot(null), sn, s->d, &thin);
        if (pany(thin)) {
            const pint pass = thin & (medium_uniform(&s->rng, thin) < tr);
            null |= pass;
            const pint mirror = thin & pnot(pass);
            if (pany(mirror)) {
                const pint segments = s->depth + 1;
                const pint on = mirror & (max_depth >= 0 ? segments < max_depth : PTRUE);
                const pvec3 r = pv3_sub(s->d, pv3_scale(sn, 2.0f * pv3_dot(s->d, sn)));
                const pvec3 side = pv3_sel(pv3_neg(*ng), *ng, pv3_dot(*ng, r) > 0.0f); /* where r leaves to */
                s->o = pv3_sel(s->o, offset_ray_origin_bound(p, p_err, side), on);
                s->d = pv3_sel(s->d, r, on);
                s->pdf = on ? PFLOAT(0.0f) : s->pdf;
                s->depth = on ? segments : s->depth;
                *crossed |= on;
                *scattered |= mirror & pnot(on); /* ends here, unshaded */
            }
        }
#endif
        if (pany(null)) {
            const pvec3 beyond = offset_ray_origin_bound(p, p_err, pv3_sel(pv3_neg(*ng), *ng, pv3_dot(*ng, s->d) > 0.0f));
            s->o = pv3_sel(s->o, beyond, null);
            s->medium = null ? next : s->medium;
            *crossed |= null & (pv3_max3(s->beta) > 0.0f);
        }
    }

    if (!pany(real)) {
        *goes_on = *crossed;
        return;
    }
    /* -- a real collision: scattering ---------------------------------------------------------- */
    const pvec3 p = pv3_add(s->o, pv3_scale(s->d, ts));
    const pvec3 wi_back = pv3_neg(s->d);
    const pint segments = s->depth + 1;
    const pint going = real & (max_depth >= 0 ? segments < max_depth : PTRUE) & (pv3_max3(s->beta) > 0.0f);
    const puint dim = convert_puint(2 + DIMS_PER_BOUNCE * s->depth);
#ifdef HAS_LIGHTS
    const pint nee = going & ((med.flags & MEDIUM_FLAG_SAMPLE_EMITTERS) != 0);
    if (integrator != INTEGRATOR_BSDF && n_lights > 0 && pany(nee)) {
        LightSample ls;
        pfloat pick_pmf, dist;
        pvec3 wl;
        const pint sampled = nee_light_sample(PATH_ARGS, key, dim, nee, p, pv3_zero(), &ls, &pick_pmf, &wl, &dist);
        if (pany(sampled)) {
            const pfloat ph = phase_eval(&med, wi_back, wl);
            const pint lit = sampled & (ph > 0.0f) & (dist > 0.0f);
            if (pany(lit)) {
                const pfloat lpdf = pick_pmf * ls.pdf;
                const pfloat w = nee_mis_weight(integrator, ls.delta, lpdf, ph);
                const pvec3 sp = offset_ray_origin_bound(ls.p, ls.err, ls.n);
                shadow->o = pv3_sel(shadow->o, p, lit);
                shadow->d = pv3_sel(shadow->d, pv3_sub(sp, p), lit);
#ifdef HAS_INFINITE_LIGHTS
                shadow->d = pv3_sel(shadow->d, pv3_scale(wl, ls.far), lit & (ls.far > 0.0f));
#endif
                shadow->contribution = pv3_sel(shadow->contribution, pv3_scale(pv3_mul(s->beta, ls.Le), ph * w / lpdf), lit);
                *shadow_medium = lit ? s->medium : *shadow_medium;
                *with_shadow = lit;
            }
        }
    }
#endif
    /* -- phase sampling continues the path ---------------------------------------------------- */
    pfloat u1, u2, pdf;
    sample_2d(key, dim + DIM_BSDF, &u1, &u2);
    const pvec3 wo = phase_sample(&med, wi_back, u1, u2, &pdf);
    pint on = going & (pdf > 0.0f);
    const pint roulette = segments >= rr_depth;
#ifdef RR_NO_ETA
    const pfloat q = pfmin(pv3_max3(s->beta), PFLOAT(0.95f));
#else
    const pfloat q = pfmin(pv3_max3(s->beta) * s->eta_scale, PFLOAT(0.95f));
#endif
    if (pany(roulette & on)) on &= pnot(roulette) | (sample_1d(key, dim + DIM_RR) < q);
    s->beta = pv3_sel(s->beta, pv3_div(s->beta, q), on & roulette);
    s->o = pv3_sel(s->o, p, on);
    s->ref = pv3_sel(s->ref, p, on);
#ifdef LIGHT_TREE
    s->nref = pv3_sel(s->nref, pv3_zero(), on); /* a medium's point: no cosine at it */
#endif
    s->d = pv3_sel(s->d, wo, on);
    /* a medium that does not sample emitters: the next emitter hit counts in full (Mitsuba's specular chain) */
    const pint emitters = (med.flags & MEDIUM_FLAG_SAMPLE_EMITTERS) != 0;
    s->pdf = on ? (emitters ? pdf : PFLOAT(0.0f)) : s->pdf;
    s->depth = on ? segments : s->depth;
    *goes_on = on | *crossed;
}

/* After path_shade at the ordinary surfaces of `surface` (iface, ng: path_medium's): the BSDF samples of
 * `going` and the shadow rays of `with_shadow` enter the medium on the side they leave to where the
 * surface is a medium transition; the BSDF samples' origins become the last scattering vertex. */
RT_INLINE void path_surface_media(__global const MediumInterface *medium_interfaces, pint surface, pint iface,
                                  pvec3 ng, pint going, pint with_shadow, const ShadowRay *shadow, PathState *s,
                                  pint *shadow_medium)
{
    pint unused;
    const pint sh = with_shadow & surface;
    if (pany(sh)) {
        const pint m = medium_after_crossing(medium_interfaces, sh ? iface : PINT(-1), ng, shadow->d, s->medium, &unused);
        *shadow_medium = sh ? m : *shadow_medium;
    }
    const pint on = going & surface;
    if (pany(on & (iface >= 0))) {
        const pint m = medium_after_crossing(medium_interfaces, on ? iface : PINT(-1), ng, s->d, s->medium, &unused);
        s->medium = on ? m : s->medium;
    }
    s->ref = pv3_sel(s->ref, s->o, on);
}

/* One vertex of the volumetric path for the lanes of `live` after their closest hits (prim, t, u, v),
 * the step every schedule takes (the megakernel's lanes, the wavefront's shade stage): the medium step
 * (path_medium), the environment for the rays that left the scene unscattered, path_shade at the
 * surfaces neither scattered before nor crossed (null), then path_surface_media.  *goes_on: the lanes
 * whose paths go on; *with_shadow, *shadow, *shadow_medium: their light samples (a medium's or a
 * surface's: a vertex has one), whose shadow_transmittance the caller adds after this vertex's emission.
 * `slot`: each lane's AOV entry (path_shade). */
RT_INLINE void volpath_vertex(PATH_PARAMS, MEDIA_PATH_PARAMS, int env_light, pint slot, SampleKey key, pint live,
                              pint prim, pfloat t, pfloat u, pfloat v, PathState *s, pint *goes_on,
                              pint *with_shadow, ShadowRay *shadow, pint *shadow_medium)
{
    pint hit = live & (prim != PRIM_MISS), escaped = live & pnot(hit);
    pint scattered, crossed, medium_on, medium_shadow, iface;
    pvec3 ng;
    ShadowRay mshadow;
    path_medium(PATH_ARGS, MEDIA_PATH_ARGS, key, live, hit, prim, t, u, v, s, &scattered, &crossed, &medium_on,
                &medium_shadow, &mshadow, shadow_medium, &iface, &ng);
    escaped &= pnot(scattered);
    hit &= pnot(scattered | crossed) & (pv3_max3(s->beta) > 0.0f);
#ifdef HAS_ENVIRONMENT
    path_escape(lights, env_light, env_map, env_cdf, integrator, escaped, s);
#endif
    /* path_shade leaves lanes outside `hit` as they are: none to shade, nothing to call (a path
     * that scattered or crossed skips the material's gathers) */
    *goes_on = *with_shadow = PINT(0);
    shadow->o = shadow->d = shadow->contribution = pv3_zero();
    if (pany(hit)) path_shade(PATH_ARGS, slot, key, hit, prim, t, u, v, s, goes_on, with_shadow, shadow);
    path_surface_media(medium_interfaces, hit, iface, ng, *goes_on, *with_shadow, shadow, s, shadow_medium);
    *goes_on |= medium_on;
    shadow->o = pv3_sel(shadow->o, mshadow.o, medium_shadow);
    shadow->d = pv3_sel(shadow->d, mshadow.d, medium_shadow);
    shadow->contribution = pv3_sel(shadow->contribution, mshadow.contribution, medium_shadow);
    *with_shadow |= medium_shadow;
}

#endif /* HAS_MEDIA */
#endif
