/* Emitters for next-event estimation: emissive triangles and spheres, picked by power, and (where
 * compiled in) point, directional and environment lights; over the lanes (cl/render/lanes.h).
 *
 * light_sample_all() returns a point on one light and the solid-angle density (at the reference
 * point) of having sampled it, *without* the probability of picking that light; light_pdf()
 * returns the same density for a point on an area light that a BSDF-sampled ray happened to hit,
 * so that multiple importance sampling weighs both strategies consistently.  light_sample() is
 * light_sample_all()'s part for the area lights:
 *
 *   triangle: uniform in area, pdf_solid_angle = dist^2 / (area * |cos_light|)
 *   sphere, reference point outside: uniform in the cone of directions that sees it,
 *           pdf = 1 / (2 pi (1 - cos_max)), with 1 - cos_max computed as sin^2 / (1 + cos)
 *           to keep precision for small, far spheres
 *   sphere, reference point inside: uniform in area, as a triangle
 *
 * Emission is one-sided (the geometric normal's side / a sphere's outside) unless the
 * material has MATERIAL_FLAG_TWO_SIDED.
 *
 * The lights that are not surfaces (conventions of pbrt-v4; the Light record's fields are
 * documented in pyopencl_rt/device/abi.py):
 *
 *   point        (HAS_DELTA_LIGHTS) intensity I [W/sr] at p: Le = I / dist^2, a delta light:
 *                ls->delta set, ls->pdf = 1 and MIS weight 1 (BSDF sampling never hits it)
 *   directional  (HAS_DELTA_LIGHTS) irradiance E on a surface perpendicular to the direction of
 *                travel `dir`: Le = E, delta as above, infinitely far
 *   spot         (HAS_DELTA_LIGHTS) a point light at p whose intensity I (on its axis, local +z)
 *                falls off with the angle theta from the axis: with l = frame (ref - p) the
 *                reference point in the light's frame and cos theta = l.z / |l|, Le = I f / dist^2
 *                with Mitsuba's f (spot.cpp): 1 for cos theta >= cos beam, (cutoff - acos(cos
 *                theta)) / (cutoff - beam) down to the cutoff, 0 for cos theta <= cos cutoff; or
 *                pbrt-v4's (LIGHT_SPOT_SMOOTHSTEP): smoothstep(cos cutoff, cos beam, cos theta);
 *                times the texture (if any) at (u, v) = 0.5 + uv_scale (l.x / l.z, l.y / l.z)
 *   projector    (HAS_DELTA_LIGHTS) a pinhole at p projecting (u, v) = 0.5 + uv_scale (l.x / l.z,
 *                l.y / l.z) for l.z > 0 and (u, v) in [0, 1]^2 (0 elsewhere): Mitsuba's
 *                (projector.cpp, LIGHT_PROJECTOR_COS3) Le = rgb tex(u, v) / (l.z^2 cos) with cos =
 *                dir . (ref - p) / dist, so that the irradiance on the plane at z = 1 is rgb tex
 *                (rgb = pi scale irradiance); pbrt-v4's Le = rgb tex(u, v) / dist^2
 *                Both set ls->tex / ls->uv for the texture, applied by cl/scene/textures.h.
 *   directional area (HAS_DELTA_LIGHTS) a triangle emitting only along its geometric normal n
 *                (Mitsuba 3's directionalarea: its flux per unit area is the radiance value rgb,
 *                all along n, as its particle tracer emits it).  The one point of it that lights
 *                ref is ref's projection along -n onto its plane, when that lies inside it and ref
 *                in front: Le = rgb there, a delta light as above (a parallel beam: no falloff);
 *                elsewhere no sample.  Mitsuba's path tracer does not sample it at all (its
 *                directionalarea.cpp leaves that to be done "with a flat surface"); this is that.
 *   environment  (HAS_ENVIRONMENT) radiance from every direction: constant (uniform sampling of
 *                the sphere, pdf 1 / 4 pi) or an equirectangular map (env_map: a header, then RGB
 *                rows from the top; pyopencl_rt/device/abi.py ENV_MAP_HEADER), times rgb.  A world
 *                direction is turned into the map's frame by the header's rotation; there +y is up
 *                and the direction (-sin t sin f, cos t, sin t cos f) has theta t = pi v, phi
 *                f = 2 pi u, so u = 0.5 looks along -z and u grows to the right seen from inside.
 *                The texels are interpolated bilinearly (wrapping around in u, clamped in v), their
 *                columns centred at u = (i + 0.5) / W, their rows at y = v v_scale + v_offset
 *                (centred, or on the poles as in Mitsuba).  The sampling density in (u, v) is
 *                piecewise constant over cells x cells cells per texel (the record's `cells`): a
 *                marginal CDF over rows of cells and a conditional CDF per row of the cell's weight
 *                (env_cdf: H' + 1 floats, then H' rows of W' + 1, H' = cells H, W' = cells W;
 *                pyopencl_rt/render/lights.py weighs a cell by the interpolated luminance over it,
 *                never 0 where the radiance is not), pdf_solid_angle = p(u, v) / (2 pi^2 sin t).
 *                There is one environment light: every lane whose light is LIGHT_ENVIRONMENT
 *                names the same record (lights + env_light).
 *
 * Infinitely distant lights (directional, environment) set ls->far > 0: ls->n is then the unit
 * direction toward the light and the shadow ray runs far enough along it to leave the scene's
 * bounding sphere (centre p, radius `radius` in the record), ls->far = 1.01 (|ref - p| + radius),
 * so huge and tiny scenes alike are handled without adding a far point to ref.
 *
 * Lanes: each lane samples its own light, lights[light_index] (light_index valid in every lane).
 * light_sample_all() dispatches on Light.kind over the lanes: each kind present among the active
 * lanes (pany) is computed over all lanes, with the record fields gathered per lane (the
 * triangle's vertices, the sphere, the material, at index 0 in the lanes of other kinds), and
 * selected into the lanes of that kind.  Each lane computes exactly what the one-path code
 * (PACKET_WIDTH 1) computes for it, so every width gives the same bits.  The early returns of
 * the one-path code are masks: light_sample_all() returns the mask of the lanes that got a
 * sample (a comparison's mask: 0 / 1 at width 1, 0 / -1 in vectors), and ls->delta is such a
 * mask.  rsqrt(x) is written 1 / sqrt(x), as cpu_builtins.h defines it.
 */
#ifndef PYOPENCL_RT_LIGHTS_H
#define PYOPENCL_RT_LIGHTS_H

#include "scene/scene.h"
#include "render/sampling.h"

typedef struct {
    pvec3 p;     /* point on the light */
    pvec3 err;   /* bound on the rounding error of p, per coordinate (for the shadow ray's end) */
    pvec3 n;     /* unit normal of the light at p, on the emitting side facing the reference */
    pvec3 Le;    /* emitted radiance toward the reference point */
    pfloat pdf;  /* solid-angle density at the reference point (not including the pick pmf) */
    pfloat far;  /* > 0 for an infinitely distant light (directional, environment): n is then the
                  * unit direction toward it, far the shadow ray's length; 0 otherwise */
    pint delta;  /* mask of the delta lights' lanes (point, directional, spot, projector): Le is the
                  * contribution over pdf = 1, no MIS (BSDF sampling cannot hit it) */
    pint tex;    /* spot, projector: the texture that multiplies Le at uv (textures.h), else -1 */
    pfloat tu, tv;
} LightSample;

/* Radiance leaving an emitter with material m at a point of geometric normal ng toward w. */
RT_INLINE pvec3 emitted(const MaterialLanes *m, pvec3 ng, pvec3 w)
{
    const pint dark = ((m->flags & MATERIAL_FLAG_TWO_SIDED) == 0) & (pv3_dot(ng, w) <= 0.0f);
    return pv3_sel(m->emission, pv3_zero(), dark);
}

RT_INLINE pfloat sphere_one_minus_cos_max(pfloat r, pfloat dc2)
{
    const pfloat sin2 = pfmin(r * r / dc2, PFLOAT(1.0f));
    const pfloat cos_max = psqrt(pfmax(PFLOAT(0.0f), 1.0f - sin2));
    return sin2 / (1.0f + cos_max);
}

/* -- the fields of the lanes' records ----------------------------------------------------------- */

#define LIGHT_F(lights, row, field) pgather((__global const float *)(lights), (row) + FIELD_INDEX(Light, field))
#define LIGHT_I(lights, row, field) pgather_int((__global const int *)(lights), (row) + FIELD_INDEX(Light, field))
#define LIGHT_V3(lights, row, field)                                                                \
    pv3(LIGHT_F(lights, row, field), LIGHT_F(lights, (row) + 1, field), LIGHT_F(lights, (row) + 2, field))

/* ls's fields in the lanes of `sel` */
RT_INLINE void light_sample_set(LightSample *ls, pint sel, pvec3 p, pvec3 err, pvec3 n, pvec3 Le, pfloat pdf)
{
    ls->p = pv3_sel(ls->p, p, sel);
    ls->err = pv3_sel(ls->err, err, sel);
    ls->n = pv3_sel(ls->n, n, sel);
    ls->Le = pv3_sel(ls->Le, Le, sel);
    ls->pdf = sel ? pdf : ls->pdf;
}

/* -- area lights -------------------------------------------------------------------------------- */

/* The triangle lights of the lanes in `sel` (`row`: each lane's light record, in floats) */
RT_INLINE pint light_sample_triangle(MESH_PARAMS, __global const Material *materials,
                                     __global const Light *lights, pint row, pint sel, pvec3 ref, pfloat ux,
                                     pfloat uy, LightSample *ls)
{
    const pint i = sel ? LIGHT_I(lights, row, prim) : PINT(0);
    const pvec3 p0 = tri_vertex(MESH_ARGS, i, 0), p1 = tri_vertex(MESH_ARGS, i, 1), p2 = tri_vertex(MESH_ARGS, i, 2);
    const MaterialLanes m = material_lanes(materials, sel ? LIGHT_I(lights, row, material) : PINT(0));
    pfloat b1, b2;
    sample_triangle_barycentrics(ux, uy, &b1, &b2);
    pvec3 err;
    const pvec3 p = triangle_point(p0, p1, p2, b1, b2, &err);
    const pvec3 ng = pv3_normalize(pv3_cross(pv3_sub(p1, p0), pv3_sub(p2, p0)), sel);
    const pvec3 to_ref = pv3_sub(ref, p);
    const pfloat dist2 = pv3_dot(to_ref, to_ref);
    /* the side of the plane from the plane itself (plane_distance), not from p */
    const pfloat cos_l = plane_distance(p0, p1, p2, ref, sel) * (1.0f / psqrt(dist2));
    const pvec3 n = pv3_sel(pv3_neg(ng), ng, cos_l > 0.0f);
    const pvec3 Le = emitted(&m, ng, n);
    const pfloat pdf = dist2 / (LIGHT_F(lights, row, area) * pabs(cos_l));
    light_sample_set(ls, sel, p, err, n, Le, pdf);
    return sel & (cos_l != 0.0f) & (dist2 != 0.0f);
}

/* The sphere lights of the lanes in `sel` */
RT_INLINE pint light_sample_sphere(__global const Sphere *spheres, __global const Material *materials,
                                   __global const Light *lights, pint row, pint sel, pvec3 ref, pfloat ux,
                                   pfloat uy, LightSample *ls)
{
    const pint s = sel ? LIGHT_I(lights, row, prim) : PINT(0);
    const pvec3 c = sphere_center(spheres, s);
    const pfloat r = sphere_radius(spheres, s);
    const MaterialLanes m = material_lanes(materials, sel ? LIGHT_I(lights, row, material) : PINT(0));
    const pvec3 to_c = pv3_sub(c, ref);
    const pfloat dc2 = pv3_dot(to_c, to_c);
    const pint outside = sel & (dc2 > r * r), inside = sel & pnot(dc2 > r * r);
    pint got = PINT(0);
    if (pany(outside)) {
        const pfloat dc = psqrt(dc2);
        const pvec3 axis = pv3_div(to_c, dc);
        const pfloat one_minus_cos = sphere_one_minus_cos_max(r, dc2);
        pvec3 t, b;
        make_onb(axis, &t, &b);
        const pvec3 w = pv3_normalize(to_world(sample_uniform_cone(ux, uy, 1.0f - one_minus_cos), t, b, axis), outside);
        pfloat th = pv3_dot(to_c, w); /* grazing the silhouette (no root): the tangent point */
        intersect_sphere(ref, w, c, r, PFLOAT(0.0f), PFLOAT(INFINITY), &th, outside);
        /* re-projected: error relative to |c| + r */
        const pvec3 p = pv3_add(c, pv3_scale(pv3_normalize(pv3_sub(pv3_add(ref, pv3_scale(w, th)), c), outside), r));
        const pvec3 err = pv3_scale(pv3_add(pv3_abs(p), pv3_abs(c)), PFLOAT(HIT_GAMMA5));
        const pvec3 n = pv3_normalize(pv3_sub(p, c), outside);
        const pvec3 Le = emitted(&m, n, pv3_neg(w));
        light_sample_set(ls, outside, p, err, n, Le, 1.0f / (2.0f * PI_F * one_minus_cos));
        got = outside;
    }
    if (pany(inside)) {
        /* inside the sphere: uniform in area, seen from inside (its inner side) */
        const pvec3 dir = sample_uniform_sphere(ux, uy);
        const pvec3 p = pv3_add(c, pv3_scale(dir, r));
        const pvec3 err = pv3_scale(pv3_add(pv3_abs(p), pv3_abs(c)), PFLOAT(HIT_GAMMA5));
        const pvec3 to_ref = pv3_sub(ref, p);
        const pfloat dist2 = pv3_dot(to_ref, to_ref);
        const pfloat cos_l = pv3_dot(dir, to_ref) * (1.0f / psqrt(dist2));
        const pvec3 Le = emitted(&m, dir, to_ref);
        const pvec3 n = pv3_sel(pv3_neg(dir), dir, cos_l > 0.0f);
        light_sample_set(ls, inside, p, err, n, Le, dist2 / (LIGHT_F(lights, row, area) * pabs(cos_l)));
        got = got | (inside & (cos_l != 0.0f));
    }
    return got;
}

/* A sample of the area light (triangle or sphere) lights[light_index] of each lane in `active`
 * (light_index valid in every lane): the mask of the lanes that got one, ls filled in there (and
 * set in every lane: far 0, delta 0, the rest 0 in the lanes of other kinds). */
RT_INLINE pint light_sample(MESH_PARAMS, __global const Sphere *spheres,
                            __global const Material *materials, __global const Light *lights, pint light_index,
                            pint active, pvec3 ref, pfloat ux, pfloat uy, LightSample *ls)
{
    const pint row = light_index * STRIDE_INDEX(Light);
    const pint kind = LIGHT_I(lights, row, kind);
    ls->p = ls->err = ls->n = ls->Le = pv3_zero();
    ls->pdf = ls->far = ls->tu = ls->tv = PFLOAT(0.0f);
    ls->delta = PINT(0);
    ls->tex = PINT(-1);
    pint got = PINT(0);
    const pint tri = active & (kind == LIGHT_TRIANGLE);
    if (pany(tri)) got = got | light_sample_triangle(MESH_ARGS, materials, lights, row, tri, ref, ux, uy, ls);
    const pint sphere = active & (kind == LIGHT_SPHERE);
    if (pany(sphere)) got = got | light_sample_sphere(spheres, materials, lights, row, sphere, ref, ux, uy, ls);
    return got;
}

/* Density light_sample_all() would have had for point p (geometric normal ng) on the area light
 * lights[light_index] (triangle or sphere; light_index valid in every lane). */
RT_INLINE pfloat light_pdf(__global const Sphere *spheres, __global const Light *lights, pint light_index, pvec3 ref,
                           pvec3 p, pvec3 ng)
{
    const pint row = light_index * STRIDE_INDEX(Light);
    const pvec3 to_ref = pv3_sub(ref, p);
    const pfloat dist2 = pv3_dot(to_ref, to_ref);
    const pfloat cos_l = pabs(pv3_dot(ng, to_ref)) * (1.0f / psqrt(dist2));
    pfloat pdf = cos_l > 0.0f ? dist2 / (LIGHT_F(lights, row, area) * cos_l) : PFLOAT(0.0f);
    const pint sphere = LIGHT_I(lights, row, kind) == LIGHT_SPHERE;
    if (pany(sphere)) {
        const pint s = sphere ? LIGHT_I(lights, row, prim) : PINT(0);
        const pvec3 to_c = pv3_sub(sphere_center(spheres, s), ref);
        const pfloat r = sphere_radius(spheres, s);
        const pfloat dc2 = pv3_dot(to_c, to_c);
        pdf = (sphere & (dc2 > r * r)) ? 1.0f / (2.0f * PI_F * sphere_one_minus_cos_max(r, dc2)) : pdf;
    }
    return pdf;
}

/* -- lights that are not surfaces -------------------------------------------------------------- */

#ifdef HAS_DELTA_LIGHTS
/* Spot and projector lights (the lanes of `spot`, `proj`): the reference point in the light's
 * frame, Le and the texture coordinates (see the top of this file). */
RT_INLINE pint light_sample_cone(__global const Light *lights, pint row, pint spot, pint proj, pvec3 ref,
                                 LightSample *ls)
{
    const pint sel = spot | proj;
    const pvec3 p = LIGHT_V3(lights, row, p);
    const pvec3 to_ref = pv3_sub(ref, p);
    const pfloat dist2 = pv3_dot(to_ref, to_ref);
    const pfloat dist = psqrt(dist2);
    const pvec3 l = pv3(pv3_dot(LIGHT_V3(lights, row, frame), to_ref), pv3_dot(LIGHT_V3(lights, row + 3, frame), to_ref),
                        pv3_dot(LIGHT_V3(lights, row + 6, frame), to_ref));
    const pint flags = LIGHT_I(lights, row, flags);
    const pfloat inv_z = 1.0f / l.z;
    const pfloat u = 0.5f + LIGHT_F(lights, row, uv_scale) * (l.x * inv_z);
    const pfloat v = 0.5f + LIGHT_F(lights, row + 1, uv_scale) * (l.y * inv_z);
    pfloat f = PFLOAT(0.0f);
    if (pany(spot)) {
        const pfloat cos_t = l.z / pv3_length(l, spot);
        const pfloat cos_cut = LIGHT_F(lights, row, cone), cos_beam = LIGHT_F(lights, row + 1, cone);
        /* Mitsuba: linear in the angle between the beam width and the cutoff */
        const pfloat ramp = (LIGHT_F(lights, row + 2, cone) - pacos(pclamp(cos_t, -1.0f, 1.0f))) *
                            LIGHT_F(lights, row + 3, cone);
        pfloat fm = cos_t >= cos_beam ? PFLOAT(1.0f) : ramp;
        fm = cos_t > cos_cut ? fm : PFLOAT(0.0f);
        /* pbrt-v4: smoothstep in the cosine */
        const pfloat t = cos_beam == cos_cut ? (cos_t < cos_cut ? PFLOAT(0.0f) : PFLOAT(1.0f))
                                             : pclamp((cos_t - cos_cut) / (cos_beam - cos_cut), 0.0f, 1.0f);
        const pfloat fs = t * t * (3.0f - 2.0f * t);
        f = ((flags & LIGHT_SPOT_SMOOTHSTEP) != 0) ? fs : fm;
        f = spot ? f / dist2 : f;
    }
    if (pany(proj)) {
        const pint inside = (l.z > 0.0f) & (u >= 0.0f) & (u <= 1.0f) & (v >= 0.0f) & (v <= 1.0f);
        const pfloat cos_n = pv3_dot(LIGHT_V3(lights, row, dir), to_ref) / dist;
        const pfloat fp = ((flags & LIGHT_PROJECTOR_COS3) != 0) ? 1.0f / (l.z * l.z * cos_n) : 1.0f / dist2;
        f = proj ? (inside ? fp : PFLOAT(0.0f)) : f;
    }
    light_sample_set(ls, sel, p, pv3_zero(), pv3_scale(to_ref, 1.0f / dist), pv3_scale(LIGHT_V3(lights, row, rgb), f),
                     PFLOAT(1.0f));
    ls->delta = ls->delta | sel;
    ls->tex = sel ? LIGHT_I(lights, row, texture) : ls->tex;
    ls->tu = sel ? u : ls->tu;
    ls->tv = sel ? v : ls->tv;
    return sel & (dist2 > 0.0f);
}
#endif

/* Directional area lights (the lanes of `sel`): ref projected along the triangle's -n onto it. */
RT_INLINE pint light_sample_directional_area(MESH_PARAMS, __global const Light *lights, pint row,
                                             pint sel, pvec3 ref, LightSample *ls)
{
    const pint i = sel ? LIGHT_I(lights, row, prim) : PINT(0);
    const pvec3 p0 = tri_vertex(MESH_ARGS, i, 0), p1 = tri_vertex(MESH_ARGS, i, 1), p2 = tri_vertex(MESH_ARGS, i, 2);
    const pvec3 e1 = pv3_sub(p1, p0), e2 = pv3_sub(p2, p0), to_ref = pv3_sub(ref, p0);
    const pvec3 n = pv3_normalize(pv3_cross(e1, e2), sel);
    const pfloat h = pv3_dot(to_ref, n); /* ref's height above the plane, on the emitting side */
    const pvec3 q = pv3_sub(to_ref, pv3_scale(n, h)); /* the projection, from p0 */
    /* its barycentrics (b1, b2) from the normal equations of q = b1 e1 + b2 e2 */
    const pfloat d11 = pv3_dot(e1, e1), d12 = pv3_dot(e1, e2), d22 = pv3_dot(e2, e2);
    const pfloat q1 = pv3_dot(q, e1), q2 = pv3_dot(q, e2);
    const pfloat det = d11 * d22 - d12 * d12;
    const pint ok = sel & (h > 0.0f) & (det > 0.0f);
    const pfloat inv = 1.0f / (ok ? det : PFLOAT(1.0f));
    const pfloat b1 = (d22 * q1 - d12 * q2) * inv, b2 = (d11 * q2 - d12 * q1) * inv;
    const pint inside = ok & (b1 >= 0.0f) & (b2 >= 0.0f) & (b1 + b2 <= 1.0f);
    pvec3 err;
    const pvec3 p = triangle_point(p0, p1, p2, b1, b2, &err);
    light_sample_set(ls, sel, p, err, n, LIGHT_V3(lights, row, rgb), PFLOAT(1.0f));
    return inside;
}

/* Length of a shadow ray from ref that leaves the scene's bounding sphere (centre, radius: the
 * record's p and radius) of a directional or environment light. */
RT_INLINE pfloat light_far(pvec3 center, pfloat radius, pvec3 ref, pint live)
{
    return pfmax((pv3_length(pv3_sub(ref, center), live) + radius) * 1.01f, PFLOAT(1e-30f));
}

#ifdef HAS_ENVIRONMENT
/* Equirectangular (u, v) in [0, 1]^2 of a unit direction (see the top of this file). */
RT_INLINE void env_dir_to_uv(pvec3 w, pfloat *u, pfloat *v)
{
    pfloat phi = patan2(-w.x, w.z);
    phi = phi < 0.0f ? phi + 2.0f * PI_F : phi;
    *u = phi * (0.5f * INV_PI_F);
    *v = pacos(pclamp(w.y, -1.0f, 1.0f)) * INV_PI_F;
}

RT_INLINE pvec3 env_uv_to_dir(pfloat u, pfloat v)
{
    const pfloat theta = PI_F * v, phi = 2.0f * PI_F * u;
    const pfloat st = psin(theta);
    return pv3(-st * psin(phi), pcos(theta), st * pcos(phi));
}

/* Largest i in [0, n - 1] with cdf[base + i] <= u (cdf[base] = 0, cdf[base + n] = 1, u in [0, 1)),
 * per lane: then cdf[base + i] <= u < cdf[base + i + 1], an interval of positive mass.  The
 * binary search of each lane, the lanes' steps side by side. */
RT_INLINE pint cdf_find(__global const float *cdf, pint base, int n, pfloat u)
{
    pint lo = PINT(0), hi = PINT(n - 1);
    for (pint going = lo < hi; pany(going); going = lo < hi) {
        const pint mid = (lo + hi + 1) >> 1;
        const pint below = pgather(cdf, base + mid) <= u;
        lo = (going & below) ? mid : lo;
        hi = (going & pnot(below)) ? mid - 1 : hi;
    }
    return lo;
}

/* The map's frame: world direction w turned by the header's rotation, and back. */
RT_INLINE pvec3 env_to_map(__global const float *env_map, pvec3 w)
{
    const float3 r0 = vload3(0, env_map), r1 = vload3(0, env_map + 4), r2 = vload3(0, env_map + 8);
    return pv3(w.x * r0.x + w.y * r0.y + w.z * r0.z, w.x * r1.x + w.y * r1.y + w.z * r1.z,
               w.x * r2.x + w.y * r2.y + w.z * r2.z);
}

RT_INLINE pvec3 env_from_map(__global const float *env_map, pvec3 d)
{
    const float3 r0 = vload3(0, env_map), r1 = vload3(0, env_map + 4), r2 = vload3(0, env_map + 8);
    return pv3(d.x * r0.x + d.y * r1.x + d.z * r2.x, d.x * r0.y + d.y * r1.y + d.z * r2.y,
               d.x * r0.z + d.y * r1.z + d.z * r2.z);
}

/* sampling cell (column, row) of the W x H grid that (u, v) falls in */
RT_INLINE void env_cell(pfloat u, pfloat v, int W, int H, pint *col, pint *row)
{
    pint x = convert_pint(u * (float)W), y = convert_pint(v * (float)H); /* clamp(x, 0, W - 1): */
    x = x < 0 ? PINT(0) : x;
    *col = x > W - 1 ? PINT(W - 1) : x;
    y = y < 0 ? PINT(0) : y;
    *row = y > H - 1 ? PINT(H - 1) : y;
}

/* texel i of the map (RGB) */
RT_INLINE pvec3 env_texel_rgb(__global const float *env_map, pint i)
{
    return pv3_gather(env_map + ENV_MAP_HEADER, 3 * i);
}

/* The map at (u, v), interpolated bilinearly between the four texels around it. */
RT_INLINE pvec3 env_lookup(__global const float *env_map, int W, int H, pfloat u, pfloat v)
{
    const pfloat fx = u * (float)W - 0.5f, fy = pclamp(v, 0.0f, 1.0f) * env_map[3] + env_map[7];
    const pfloat x0f = pfloor(fx), y0f = pfloor(fy), ax = fx - x0f, ay = fy - y0f;
    pint x0 = convert_pint(x0f), y0 = convert_pint(y0f);
    x0 = x0 < 0 ? x0 + W : x0; /* u in [0, 1]: x0 in [-1, W] */
    x0 = x0 > W - 1 ? x0 - W : x0;
    pint x1 = x0 + 1;
    x1 = x1 > W - 1 ? x1 - W : x1;
    pint y1 = y0 + 1;
    y0 = y0 < 0 ? PINT(0) : (y0 > H - 1 ? PINT(H - 1) : y0);
    y1 = y1 < 0 ? PINT(0) : (y1 > H - 1 ? PINT(H - 1) : y1);
    const pvec3 top = pv3_add(pv3_scale(env_texel_rgb(env_map, y0 * W + x0), 1.0f - ax),
                              pv3_scale(env_texel_rgb(env_map, y0 * W + x1), ax));
    const pvec3 bottom = pv3_add(pv3_scale(env_texel_rgb(env_map, y1 * W + x0), 1.0f - ax),
                                 pv3_scale(env_texel_rgb(env_map, y1 * W + x1), ax));
    return pv3_add(pv3_scale(top, 1.0f - ay), pv3_scale(bottom, ay));
}

/* Radiance of the environment lt seen along the unit direction w. */
RT_INLINE pvec3 env_radiance(__global const Light *lt, __global const float *env_map, pvec3 w)
{
    const float3 scale = vload3(0, lt->rgb);
    const int W = lt->prim, H = lt->material;
    if (W <= 0) return pv3_splat(scale);
    pfloat u, v;
    env_dir_to_uv(env_to_map(env_map, w), &u, &v);
    return pv3_mul(pv3_splat(scale), env_lookup(env_map, W, H, u, v));
}

/* Solid-angle density with which env_sample() draws the unit direction w. */
RT_INLINE pfloat env_pdf(__global const Light *lt, __global const float *env_map, __global const float *env_cdf,
                         pvec3 w)
{
    const int W = lt->prim * lt->cells, H = lt->material * lt->cells; /* the sampling cells */
    if (W <= 0) return PFLOAT(0.25f * INV_PI_F);
    const pvec3 d = env_to_map(env_map, w);
    const pfloat sin_theta = psqrt(pfmax(PFLOAT(0.0f), 1.0f - d.y * d.y));
    pfloat u, v;
    pint col, row;
    env_dir_to_uv(d, &u, &v);
    env_cell(u, v, W, H, &col, &row);
    const pint cond = (H + 1) + row * (W + 1);
    const pfloat p_uv = (pgather(env_cdf, row + 1) - pgather(env_cdf, row)) * (float)H *
                        ((pgather(env_cdf, cond + col + 1) - pgather(env_cdf, cond + col)) * (float)W);
    return sin_theta > 0.0f ? p_uv / (2.0f * PI_F * PI_F * sin_theta) : PFLOAT(0.0f);
}

/* A direction *wi toward the environment lt from (ux, uy) in [0, 1)^2, its density *pdf (0: no
 * sample) and the radiance from there. */
RT_INLINE pvec3 env_sample(__global const Light *lt, __global const float *env_map, __global const float *env_cdf,
                           pfloat ux, pfloat uy, pvec3 *wi, pfloat *pdf)
{
    const float3 scale = vload3(0, lt->rgb);
    const int W = lt->prim * lt->cells, H = lt->material * lt->cells; /* the sampling cells */
    if (W <= 0) {
        *wi = sample_uniform_sphere(ux, uy);
        *pdf = PFLOAT(0.25f * INV_PI_F);
        return pv3_splat(scale);
    }
    const pint row = cdf_find(env_cdf, PINT(0), H, uy);
    const pfloat m0 = pgather(env_cdf, row), m1 = pgather(env_cdf, row + 1);
    const pint cond = (H + 1) + row * (W + 1);
    const pint col = cdf_find(env_cdf, cond, W, ux);
    const pfloat c0 = pgather(env_cdf, cond + col), c1 = pgather(env_cdf, cond + col + 1);
    const pfloat v = (convert_pfloat(row) + pclamp((uy - m0) / (m1 - m0), 0.0f, 1.0f)) / (float)H;
    const pfloat uu = (convert_pfloat(col) + pclamp((ux - c0) / (c1 - c0), 0.0f, 1.0f)) / (float)W;
    const pvec3 d = env_uv_to_dir(uu, v);
    *wi = env_from_map(env_map, d);
    const pfloat sin_theta = psqrt(pfmax(PFLOAT(0.0f), 1.0f - d.y * d.y));
    const pint ok = sin_theta > 0.0f;
    *pdf = ok ? (m1 - m0) * (float)H * ((c1 - c0) * (float)W) / (2.0f * PI_F * PI_F * sin_theta) : PFLOAT(0.0f);
    return pv3_sel(pv3_zero(), pv3_mul(pv3_splat(scale), env_lookup(env_map, lt->prim, lt->material, uu, v)), ok);
}
#endif

/* A sample of the light lights[light_index] of each lane in `active` (light_index valid in every
 * lane; ref, ux, uy finite in the others): the area lights (light_sample), and point, directional
 * and environment lights where compiled in.  Returns the mask of the lanes that got a sample, ls
 * filled in there (ls->far and ls->delta too: 0 for area lights). */
RT_INLINE pint light_sample_all(MESH_PARAMS, __global const Sphere *spheres,
                                __global const Material *materials, __global const float *env_map,
                                __global const float *env_cdf, __global const Light *lights, pint light_index,
                                pint active, pvec3 ref, pfloat ux, pfloat uy, LightSample *ls)
{
    pint got = light_sample(MESH_ARGS, spheres, materials, lights, light_index, active, ref, ux, uy, ls);
#if defined(HAS_DELTA_LIGHTS) || defined(HAS_ENVIRONMENT)
    const pint row = light_index * STRIDE_INDEX(Light);
    const pint kind = LIGHT_I(lights, row, kind);
#ifdef HAS_DELTA_LIGHTS
    const pint point = active & (kind == LIGHT_POINT), directional = active & (kind == LIGHT_DIRECTIONAL);
    if (pany(point)) {
        const pvec3 p = LIGHT_V3(lights, row, p);
        const pvec3 to_ref = pv3_sub(ref, p);
        const pfloat dist2 = pv3_dot(to_ref, to_ref);
        light_sample_set(ls, point, p, pv3_zero(), pv3_scale(to_ref, 1.0f / psqrt(dist2)),
                         pv3_div(LIGHT_V3(lights, row, rgb), dist2), PFLOAT(1.0f));
        ls->delta = ls->delta | point;
        got = got | (point & (dist2 > 0.0f));
    }
    const pint spot = active & (kind == LIGHT_SPOT), proj = active & (kind == LIGHT_PROJECTOR);
    if (pany(spot | proj)) got = got | light_sample_cone(lights, row, spot, proj, ref, ls);
    const pint beam = active & (kind == LIGHT_DIRECTIONAL_AREA);
    if (pany(beam)) {
        got = got | light_sample_directional_area(MESH_ARGS, lights, row, beam, ref, ls);
        ls->delta = ls->delta | beam;
    }
#else
    const pint directional = PINT(0);
#endif
#ifdef HAS_ENVIRONMENT
    const pint env = active & (kind == LIGHT_ENVIRONMENT);
#else
    const pint env = PINT(0);
#endif
    /* infinitely far: directional and environment lights */
    const pint far = directional | env;
    if (pany(far)) {
        pvec3 n = pv3_neg(LIGHT_V3(lights, row, dir));
        const pfloat far_t = light_far(LIGHT_V3(lights, row, p), LIGHT_F(lights, row, radius), ref, far);
        pvec3 Le = LIGHT_V3(lights, row, rgb);
        pfloat pdf = PFLOAT(1.0f);
#ifdef HAS_ENVIRONMENT
        if (pany(env)) {
            int k = 0; /* the first lane's record: there is one environment light */
            while (!PLANE_I(env, k)) ++k;
            __global const Light *lt = lights + PLANE_I(light_index, k);
            pvec3 wi;
            pfloat env_pdf_ = PFLOAT(0.0f);
            const pvec3 env_Le = env_sample(lt, env_map, env_cdf, ux, uy, &wi, &env_pdf_);
            n = pv3_sel(n, wi, env);
            Le = pv3_sel(Le, env_Le, env);
            pdf = env ? env_pdf_ : pdf;
            got = got | (env & (env_pdf_ > 0.0f));
        }
#endif
        light_sample_set(ls, far, pv3_add(ref, pv3_scale(n, far_t)), pv3_zero(), n, Le, pdf);
        ls->far = far ? far_t : ls->far;
        ls->delta = ls->delta | directional;
        got = got | directional;
    }
#endif
    return got;
}

#undef LIGHT_F
#undef LIGHT_I
#undef LIGHT_V3

#endif
