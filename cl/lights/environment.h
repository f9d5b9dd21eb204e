/* The environment light ("environment", pyopencl_rt/scene/lights.py's Environment): radiance from
 * every direction, constant (uniform sampling of the sphere, pdf 1 / 4 pi) or an equirectangular
 * map (env_map: a header, then RGB rows from the top; pyopencl_rt/device/abi.py ENV_MAP_HEADER),
 * times rgb.  A world direction is turned into the map's frame by the header's rotation; there +y
 * is up and the direction (-sin t sin f, cos t, sin t cos f) has theta t = pi v, phi f = 2 pi u,
 * so u = 0.5 looks along -z and u grows to the right seen from inside.  The texels are
 * interpolated bilinearly (wrapping around in u, clamped in v), their columns centred at u = (i +
 * 0.5) / W, their rows at y = v v_scale + v_offset (centred, or on the poles as in Mitsuba).  The
 * sampling density in (u, v) is piecewise constant over cells x cells cells per texel (the
 * record's `cells`): a marginal CDF over rows of cells and a conditional CDF per row of the cell's
 * weight (env_cdf: H' + 1 floats, then H' rows of W' + 1, H' = cells H, W' = cells W;
 * pyopencl_rt/render/lights.py weighs a cell by the interpolated luminance over it, never 0 where
 * the radiance is not), pdf_solid_angle = p(u, v) / (2 pi^2 sin t).  There is one environment
 * light: every lane whose light is LIGHT_ENVIRONMENT names the same record (lights + env_light).
 * Infinitely far: its shadow ray leaves the scene's bounding sphere (ls->far).  env_radiance and
 * env_pdf serve the rays that escape (cl/render/path.h).  Compiled with HAS_ENVIRONMENT. */
#ifndef PYOPENCL_RT_ENVIRONMENT_H
#define PYOPENCL_RT_ENVIRONMENT_H

#include "render/light_sample.h"

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

/* The lanes of `sel` sample the one environment light (the first lane's record). */
RT_INLINE pint light_sample_environment(LIGHT_UNIT_PARAMS)
{
    int k = 0;
    while (!PLANE_I(sel, k)) ++k;
    __global const Light *lt = lights + PLANE_I(light_index, k);
    pvec3 wi;
    pfloat pdf = PFLOAT(0.0f);
    const pvec3 Le = env_sample(lt, env_map, env_cdf, ux, uy, &wi, &pdf);
    light_sample_far(ls, lights, row, sel, ref, wi, Le, pdf);
    return sel & (pdf > 0.0f);
}
#define LIGHT_CASE_ENVIRONMENT(X) X(environment, ENVIRONMENT)
#endif

#endif
