/* Emitters for next-event estimation: emissive triangles and spheres, picked by power.
 *
 * light_sample() returns a point on one light and the solid-angle density (at the reference
 * point) of having sampled it, *without* the probability of picking that light; light_pdf()
 * returns the same density for a point that a BSDF-sampled ray happened to hit, so that
 * multiple importance sampling weighs both strategies consistently.
 *
 *   triangle: uniform in area, pdf_solid_angle = dist^2 / (area * |cos_light|)
 *   sphere, reference point outside: uniform in the cone of directions that sees it,
 *           pdf = 1 / (2 pi (1 - cos_max)), with 1 - cos_max computed as sin^2 / (1 + cos)
 *           to keep precision for small, far spheres
 *   sphere, reference point inside: uniform in area, as a triangle
 *
 * Emission is one-sided (the geometric normal's side / a sphere's outside) unless the
 * material has MATERIAL_FLAG_TWO_SIDED.
 */
#ifndef PYOPENCL_RT_LIGHTS_H
#define PYOPENCL_RT_LIGHTS_H

#include "scene.h"

#define LIGHT_TRIANGLE 0
#define LIGHT_SPHERE 1
#define MATERIAL_FLAG_TWO_SIDED 1

typedef struct {
    float3 p;   /* point on the light */
    float3 n;   /* unit normal of the light at p, on the emitting side facing the reference */
    float3 Le;  /* emitted radiance toward the reference point */
    float pdf;  /* solid-angle density at the reference point (not including the pick pmf) */
} LightSample;

/* Radiance leaving an emitter with material m at a point of geometric normal ng toward w. */
RT_INLINE float3 emitted(__global const Material *m, float3 ng, float3 w)
{
    if ((m->flags & MATERIAL_FLAG_TWO_SIDED) == 0 && dot(ng, w) <= 0.0f)
        return (float3)(0.0f);
    return material_emission(m);
}

RT_INLINE float sphere_one_minus_cos_max(float r, float dc2)
{
    const float sin2 = fmin(r * r / dc2, 1.0f);
    const float cos_max = sqrt(fmax(0.0f, 1.0f - sin2));
    return sin2 / (1.0f + cos_max);
}

RT_INLINE int light_sample(__global const float4 *tris, __global const Sphere *spheres,
                        __global const Material *materials, __global const Light *light,
                        float3 ref, float2 u, LightSample *ls)
{
    __global const Material *m = materials + light->material;
    if (light->kind == LIGHT_TRIANGLE) {
        const int i = light->prim;
        const float3 p0 = tris[3 * i].xyz, p1 = tris[3 * i + 1].xyz, p2 = tris[3 * i + 2].xyz;
        const float2 b = sample_triangle_barycentrics(u);
        ls->p = (1.0f - b.x - b.y) * p0 + b.x * p1 + b.y * p2;
        const float3 ng = normalize(cross(p1 - p0, p2 - p0));
        const float3 to_ref = ref - ls->p;
        const float dist2 = dot(to_ref, to_ref);
        const float cos_l = dot(ng, to_ref) * rsqrt(dist2);
        if (cos_l == 0.0f || dist2 == 0.0f) return 0;
        ls->Le = emitted(m, ng, to_ref);
        ls->n = cos_l > 0.0f ? ng : -ng;
        ls->pdf = dist2 / (light->area * fabs(cos_l));
        return 1;
    }
    /* sphere */
    __global const Sphere *s = spheres + light->prim;
    const float3 c = vload3(0, s->center);
    const float r = s->radius;
    const float3 to_c = c - ref;
    const float dc2 = dot(to_c, to_c);
    if (dc2 > r * r) {
        const float dc = sqrt(dc2);
        const float3 axis = to_c / dc;
        const float one_minus_cos = sphere_one_minus_cos_max(r, dc2);
        float3 t, b;
        make_onb(axis, &t, &b);
        const float3 w = normalize(to_world(sample_uniform_cone(u, 1.0f - one_minus_cos), t, b, axis));
        float th;
        if (!intersect_sphere(ref, w, c, r, 0.0f, INFINITY, &th))
            th = dot(to_c, w); /* grazing the silhouette: the tangent point */
        ls->p = ref + th * w;
        ls->n = normalize(ls->p - c);
        ls->Le = emitted(m, ls->n, -w);
        ls->pdf = 1.0f / (2.0f * PI_F * one_minus_cos);
        return 1;
    }
    /* inside the sphere: uniform in area, seen from inside (its inner side) */
    const float3 dir = sample_uniform_sphere(u);
    ls->p = c + r * dir;
    const float3 to_ref = ref - ls->p;
    const float dist2 = dot(to_ref, to_ref);
    const float cos_l = dot(dir, to_ref) * rsqrt(dist2);
    if (cos_l == 0.0f) return 0;
    ls->Le = emitted(m, dir, to_ref);
    ls->n = cos_l > 0.0f ? dir : -dir;
    ls->pdf = dist2 / (light->area * fabs(cos_l));
    return 1;
}

/* Density light_sample() would have had for point p (normal ng) on light `light`. */
RT_INLINE float light_pdf(__global const Sphere *spheres, __global const Light *light, float3 ref, float3 p, float3 ng)
{
    if (light->kind == LIGHT_SPHERE) {
        __global const Sphere *s = spheres + light->prim;
        const float3 to_c = vload3(0, s->center) - ref;
        const float dc2 = dot(to_c, to_c);
        if (dc2 > s->radius * s->radius)
            return 1.0f / (2.0f * PI_F * sphere_one_minus_cos_max(s->radius, dc2));
    }
    const float3 to_ref = ref - p;
    const float dist2 = dot(to_ref, to_ref);
    const float cos_l = fabs(dot(ng, to_ref)) * rsqrt(dist2);
    return cos_l > 0.0f ? dist2 / (light->area * cos_l) : 0.0f;
}

#endif
