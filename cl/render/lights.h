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
 * The lights that are not surfaces follow pbrt-v4's conventions; each type is a unit of its own,
 * cl/lights/<name>.h (its formulas on top), paired by name with the Light record's kind
 * (LIGHT_<NAME>, the enum of pyopencl_rt/device/abi.py, whose fields are documented there):
 * point, directional, spot, projector, directional_area and goniometric (HAS_DELTA_LIGHTS: delta
 * lights, ls->delta set, pdf 1 and MIS weight 1, BSDF sampling never hits them), environment
 * (HAS_ENVIRONMENT).  The generated header "lights/units.h" includes them and lists their cases
 * (LIGHT_CASES), which light_sample_all() dispatches to; cl/render/light_sample.h holds what they
 * share.
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

#include "render/light_sample.h"

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

/* -- lights that are not surfaces: their types (cl/lights/) ------------------------------------ */

#include "lights/units.h"

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
    /* each type's lanes (disjoint), where some active lane has that type; a delta light's lanes are
     * marked (LIGHT_DELTA_<NAME>: the ABI's DELTA_LIGHTS) */
#define LIGHT_SAMPLE_CASE(name, NAME)                                                               \
    {                                                                                               \
        const pint sel = active & (kind == LIGHT_##NAME);                                           \
        if (pany(sel)) {                                                                            \
            got = got | light_sample_##name(LIGHT_UNIT_ARGS);                                       \
            if (LIGHT_DELTA_##NAME) ls->delta = ls->delta | sel;                                    \
        }                                                                                           \
    }
    LIGHT_CASES(LIGHT_SAMPLE_CASE)
#undef LIGHT_SAMPLE_CASE
#endif
    return got;
}

#endif
