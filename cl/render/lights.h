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
 *
 * light_sample_all() adds the lights that are not surfaces (conventions of pbrt-v4; the Light
 * record's fields are documented in pyopencl_rt/device/abi.py):
 *
 *   point        (HAS_DELTA_LIGHTS) intensity I [W/sr] at p: Le = I / dist^2, a delta light:
 *                ls->delta = 1, ls->pdf = 1 and MIS weight 1 (BSDF sampling never hits it)
 *   directional  (HAS_DELTA_LIGHTS) irradiance E on a surface perpendicular to the direction of
 *                travel `dir`: Le = E, delta as above, infinitely far
 *   environment  (HAS_ENVIRONMENT) radiance from every direction: constant (uniform sampling of
 *                the sphere, pdf 1 / 4 pi) or an equirectangular map (env_map, RGB rows from the
 *                top, +y up: direction (-sin t sin f, cos t, sin t cos f) for theta t = pi v and
 *                phi f = 2 pi u, so u = 0.5 looks along -z and u grows to the right seen from
 *                inside), times rgb.  The map is piecewise constant (the nearest texel, no
 *                filtering) and so is its sampling density in (u, v): a marginal CDF over rows and
 *                a conditional CDF per row of luminance x sin(theta at the row centre) (env_cdf:
 *                H + 1 floats, then H rows of W + 1), pdf_solid_angle = p(u, v) / (2 pi^2 sin t).
 *
 * Infinitely distant lights (directional, environment) set ls->far > 0: ls->n is then the unit
 * direction toward the light and the shadow ray runs far enough along it to leave the scene's
 * bounding sphere (centre p, radius `radius` in the record), ls->far = 1.01 (|ref - p| + radius),
 * so huge and tiny scenes alike are handled without adding a far point to ref.
 */
#ifndef PYOPENCL_RT_LIGHTS_H
#define PYOPENCL_RT_LIGHTS_H

#include "scene/scene.h"

typedef struct {
    float3 p;   /* point on the light */
    float3 err; /* bound on the rounding error of p, per coordinate (for the shadow ray's end) */
    float3 n;   /* unit normal of the light at p, on the emitting side facing the reference */
    float3 Le;  /* emitted radiance toward the reference point */
    float pdf;  /* solid-angle density at the reference point (not including the pick pmf) */
    float far;  /* set by light_sample_all: > 0 for an infinitely distant light (directional,
                 * environment): n is then the unit direction toward it, far the shadow ray's length */
    int delta;  /* set by light_sample_all: 1 for a delta light (point, directional): Le is the
                 * contribution over pdf = 1, no MIS (BSDF sampling cannot hit it) */
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
        ls->p = triangle_point(p0, p1, p2, b.x, b.y, &ls->err);
        const float3 ng = normalize(cross(p1 - p0, p2 - p0));
        const float3 to_ref = ref - ls->p;
        const float dist2 = dot(to_ref, to_ref);
        /* the side of the plane from the plane itself (plane_distance), not from ls->p */
        const float cos_l = plane_distance(p0, p1, p2, ref) * rsqrt(dist2);
        if (cos_l == 0.0f || dist2 == 0.0f) return 0;
        ls->n = cos_l > 0.0f ? ng : -ng;
        ls->Le = emitted(m, ng, ls->n);
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
        ls->p = c + r * normalize(ref + th * w - c); /* re-projected: error relative to |c| + r */
        ls->err = HIT_GAMMA5 * (fabs(ls->p) + fabs(c));
        ls->n = normalize(ls->p - c);
        ls->Le = emitted(m, ls->n, -w);
        ls->pdf = 1.0f / (2.0f * PI_F * one_minus_cos);
        return 1;
    }
    /* inside the sphere: uniform in area, seen from inside (its inner side) */
    const float3 dir = sample_uniform_sphere(u);
    ls->p = c + r * dir;
    ls->err = HIT_GAMMA5 * (fabs(ls->p) + fabs(c));
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

/* -- lights that are not surfaces -------------------------------------------------------------- */

/* Length of a shadow ray from ref that leaves the scene's bounding sphere (centre lt->p, radius
 * lt->radius) of a directional or environment light. */
RT_INLINE float light_far(__global const Light *lt, float3 ref)
{
    return fmax((length(ref - vload3(0, lt->p)) + lt->radius) * 1.01f, 1e-30f);
}

#ifdef HAS_ENVIRONMENT
/* Equirectangular (u, v) in [0, 1]^2 of a unit direction (see the top of this file). */
RT_INLINE float2 env_dir_to_uv(float3 w)
{
    float phi = atan2(-w.x, w.z);
    if (phi < 0.0f) phi += 2.0f * PI_F;
    return (float2)(phi * (0.5f * INV_PI_F), acos(clamp(w.y, -1.0f, 1.0f)) * INV_PI_F);
}

RT_INLINE float3 env_uv_to_dir(float2 uv)
{
    const float theta = PI_F * uv.y, phi = 2.0f * PI_F * uv.x;
    const float st = sin(theta);
    return (float3)(-st * sin(phi), cos(theta), st * cos(phi));
}

/* Largest i in [0, n - 1] with cdf[i] <= u (cdf[0] = 0, cdf[n] = 1, u in [0, 1)): then
 * cdf[i] <= u < cdf[i + 1], an interval of positive mass. */
RT_INLINE int cdf_find(__global const float *cdf, int n, float u)
{
    int lo = 0, hi = n - 1;
    while (lo < hi) {
        const int mid = (lo + hi + 1) >> 1;
        if (cdf[mid] <= u) lo = mid;
        else hi = mid - 1;
    }
    return lo;
}

/* (column, row) of the texel that direction w falls in, in a W x H map. */
RT_INLINE int2 env_texel(float3 w, int W, int H)
{
    const float2 uv = env_dir_to_uv(w);
    return (int2)(clamp((int)(uv.x * (float)W), 0, W - 1), clamp((int)(uv.y * (float)H), 0, H - 1));
}

/* Radiance of the environment seen along the unit direction w (nearest texel). */
RT_INLINE float3 env_radiance(__global const Light *lt, __global const float *env_map, float3 w)
{
    const float3 scale = vload3(0, lt->rgb);
    const int W = lt->prim, H = lt->material;
    if (W <= 0) return scale;
    const int2 t = env_texel(w, W, H);
    return scale * vload3(t.y * W + t.x, env_map);
}

/* Solid-angle density with which env_sample() draws the unit direction w. */
RT_INLINE float env_pdf(__global const Light *lt, __global const float *env_cdf, float3 w)
{
    const int W = lt->prim, H = lt->material;
    if (W <= 0) return 0.25f * INV_PI_F;
    const float sin_theta = sqrt(fmax(0.0f, 1.0f - w.y * w.y));
    if (!(sin_theta > 0.0f)) return 0.0f;
    const int2 t = env_texel(w, W, H);
    __global const float *cond = env_cdf + (H + 1) + t.y * (W + 1);
    const float p_uv = (env_cdf[t.y + 1] - env_cdf[t.y]) * (float)H * ((cond[t.x + 1] - cond[t.x]) * (float)W);
    return p_uv / (2.0f * PI_F * PI_F * sin_theta);
}

/* A direction *wi toward the environment from u in [0, 1)^2, its density *pdf (0: no sample)
 * and the radiance from there. */
RT_INLINE float3 env_sample(__global const Light *lt, __global const float *env_map, __global const float *env_cdf,
                            float2 u, float3 *wi, float *pdf)
{
    const float3 scale = vload3(0, lt->rgb);
    const int W = lt->prim, H = lt->material;
    if (W <= 0) {
        *wi = sample_uniform_sphere(u);
        *pdf = 0.25f * INV_PI_F;
        return scale;
    }
    const int row = cdf_find(env_cdf, H, u.y);
    const float m0 = env_cdf[row], m1 = env_cdf[row + 1];
    __global const float *cond = env_cdf + (H + 1) + row * (W + 1);
    const int col = cdf_find(cond, W, u.x);
    const float c0 = cond[col], c1 = cond[col + 1];
    const float v = ((float)row + clamp((u.y - m0) / (m1 - m0), 0.0f, 1.0f)) / (float)H;
    const float uu = ((float)col + clamp((u.x - c0) / (c1 - c0), 0.0f, 1.0f)) / (float)W;
    const float3 w = env_uv_to_dir((float2)(uu, v));
    *wi = w;
    const float sin_theta = sqrt(fmax(0.0f, 1.0f - w.y * w.y));
    if (!(sin_theta > 0.0f)) {
        *pdf = 0.0f;
        return (float3)(0.0f);
    }
    *pdf = (m1 - m0) * (float)H * ((c1 - c0) * (float)W) / (2.0f * PI_F * PI_F * sin_theta);
    return scale * vload3(row * W + col, env_map);
}
#endif

/* light_sample() for every kind of light: the area lights above, and point, directional and
 * environment lights where compiled in.  Also sets ls->far and ls->delta (0 for area lights). */
RT_INLINE int light_sample_all(__global const float4 *tris, __global const Sphere *spheres,
                               __global const Material *materials, __global const float *env_map,
                               __global const float *env_cdf, __global const Light *light,
                               float3 ref, float2 u, LightSample *ls)
{
    ls->far = 0.0f;
    ls->delta = 0;
#if defined(HAS_DELTA_LIGHTS) || defined(HAS_ENVIRONMENT)
    ls->err = (float3)(0.0f);
#endif
#ifdef HAS_DELTA_LIGHTS
    if (light->kind == LIGHT_POINT) {
        ls->p = vload3(0, light->p);
        const float3 to_ref = ref - ls->p;
        const float dist2 = dot(to_ref, to_ref);
        if (!(dist2 > 0.0f)) return 0;
        ls->n = to_ref * rsqrt(dist2);
        ls->Le = vload3(0, light->rgb) / dist2;
        ls->pdf = 1.0f;
        ls->delta = 1;
        return 1;
    }
    if (light->kind == LIGHT_DIRECTIONAL) {
        ls->n = -vload3(0, light->dir);
        ls->far = light_far(light, ref);
        ls->p = ref + ls->far * ls->n;
        ls->Le = vload3(0, light->rgb);
        ls->pdf = 1.0f;
        ls->delta = 1;
        return 1;
    }
#endif
#ifdef HAS_ENVIRONMENT
    if (light->kind == LIGHT_ENVIRONMENT) {
        float3 wi;
        ls->Le = env_sample(light, env_map, env_cdf, u, &wi, &ls->pdf);
        ls->n = wi;
        ls->far = light_far(light, ref);
        ls->p = ref + ls->far * wi;
        return ls->pdf > 0.0f;
    }
#endif
    return light_sample(tris, spheres, materials, light, ref, u, ls);
}

#endif
