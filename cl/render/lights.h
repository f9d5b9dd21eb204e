/* Emitters for next-event estimation: emissive triangles and analytic shapes, picked by power or
 * by the light BVH, and (where compiled in) point, directional and environment lights; over the
 * lanes (cl/render/lanes.h).
 *
 * light_sample_all() returns a point on one light and the solid-angle density (at the reference
 * point) of having sampled it, *without* the probability of picking that light; light_pdf()
 * returns the same density for a point on an area light that a BSDF-sampled ray happened to hit,
 * so that multiple importance sampling weighs both strategies consistently.  light_sample() is
 * light_sample_all()'s part for the area lights:
 *
 *   triangle: uniform in area, pdf_solid_angle = dist^2 / (area * |cos_light|)
 *   shape:    its unit's sampling (cl/shapes/<name>.h: a sphere by the cone that sees it, a disk
 *             uniform in area), through scene/shapes.h's dispatch
 *
 * Emission is one-sided (the geometric normal's side, a shape's front) unless the
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
 * triangle's vertices, the shape, the material, at index 0 in the lanes of other kinds), and
 * selected into the lanes of that kind.  Each lane computes exactly what the one-path code
 * (PACKET_WIDTH 1) computes for it, so every width gives the same bits.  The early returns of
 * the one-path code are masks: light_sample_all() returns the mask of the lanes that got a
 * sample (a comparison's mask: 0 / 1 at width 1, 0 / -1 in vectors), and ls->delta is such a
 * mask.  rsqrt(x) is written 1 / sqrt(x), as cpu_builtins.h defines it.
 */
#ifndef PYOPENCL_RT_LIGHTS_H
#define PYOPENCL_RT_LIGHTS_H

#include "render/light_sample.h"

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

/* A sample of the area light (triangle or shape) lights[light_index] of each lane in `active`
 * (light_index valid in every lane): the mask of the lanes that got one, ls filled in there (and
 * set in every lane: far 0, delta 0, the rest 0 in the lanes of other kinds). */
RT_INLINE pint light_sample(MESH_PARAMS, __global const Shape *shapes,
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
#ifdef HAS_SHAPES
    const pint shape = active & (kind == LIGHT_SHAPE);
    if (pany(shape)) {
        const MaterialLanes m = material_lanes(materials, shape ? LIGHT_I(lights, row, material) : PINT(0));
        got = got | shape_light_sample(shapes, shape ? LIGHT_I(lights, row, prim) : PINT(0), shape, &m,
                                       LIGHT_F(lights, row, area), ref, ux, uy, ls);
    }
#else
    (void)shapes;
#endif
    return got;
}

/* Density light_sample_all() would have had for point p (geometric normal ng) on the area light
 * lights[light_index] (triangle or shape; light_index valid in every lane). */
RT_INLINE pfloat light_pdf(__global const Shape *shapes, __global const Light *lights, pint light_index, pvec3 ref,
                           pvec3 p, pvec3 ng)
{
    const pint row = light_index * STRIDE_INDEX(Light);
    const pvec3 to_ref = pv3_sub(ref, p);
    const pfloat dist2 = pv3_dot(to_ref, to_ref);
    const pfloat cos_l = pabs(pv3_dot(ng, to_ref)) * (1.0f / psqrt(dist2));
    pfloat pdf = cos_l > 0.0f ? dist2 / (LIGHT_F(lights, row, area) * cos_l) : PFLOAT(0.0f);
#ifdef HAS_SHAPES
    const pint shape = LIGHT_I(lights, row, kind) == LIGHT_SHAPE;
    if (pany(shape)) pdf = shape_light_pdf(shapes, shape ? LIGHT_I(lights, row, prim) : PINT(0), shape, ref, pdf);
#else
    (void)shapes;
#endif
    return pdf;
}

/* -- lights that are not surfaces: their types (cl/lights/) ------------------------------------ */

#include "lights/units.h"

/* A sample of the light lights[light_index] of each lane in `active` (light_index valid in every
 * lane; ref, ux, uy finite in the others): the area lights (light_sample), and point, directional
 * and environment lights where compiled in.  Returns the mask of the lanes that got a sample, ls
 * filled in there (ls->far and ls->delta too: 0 for area lights). */
RT_INLINE pint light_sample_all(MESH_PARAMS, __global const Shape *shapes,
                                __global const Material *materials, __global const float *env_map,
                                __global const float *env_cdf, __global const Light *lights, pint light_index,
                                pint active, pvec3 ref, pfloat ux, pfloat uy, LightSample *ls)
{
    pint got = light_sample(MESH_ARGS, shapes, materials, lights, light_index, active, ref, ux, uy, ls);
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
