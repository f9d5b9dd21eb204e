/* Participating media: the building blocks of the volumetric integrator, written once over the lanes
 * of cl/render/lanes.h (each lane one path, PACKET_WIDTH 1, 8 or 16; every width gives each lane the
 * bits width 1 gives it).  The records (Medium, MediumGrid, MediumInterface) are the ABI table's
 * (pyopencl_rt/device/abi.py); pyopencl_rt/scene/media.py packs them.
 *
 *   medium_lanes        a medium's parameters (and its grids' headers) gathered into the lanes
 *   grid_ray_box        the part of a ray inside a grid's box (a slab test in the grid's local space)
 *   grid_eval           a grid's value at a point: trilinear as Mitsuba's gridvolume (clamped at the
 *                       edges) or pbrt-v4's SampledGrid (0 beyond the edges), or nearest
 *   medium_coefficients sigma_t and sigma_s at a point
 *   medium_sample_free_flight  free-flight sampling: delta tracking against the majorant (in a
 *                       homogeneous medium the exponential distance in closed form: the first
 *                       tentative collision is real), with spectral-MIS weights
 *   medium_transmittance  transmittance of a segment: closed form in a homogeneous medium, ratio
 *                       tracking in a grid, with the same weights
 *   phase_eval / phase_sample  isotropic and Henyey-Greenstein phase functions (Mitsuba's sampling)
 *   medium_after_crossing  the medium a ray is in after crossing a surface (Mitsuba's target_medium)
 *
 * Colour.  Media are RGB and may be chromatic (sigma_t differs per channel).  As Mitsuba's volpath and
 * volpathmis and pbrt-v4 do, a path picks one "hero" channel c once (medium_channel: uniformly, from
 * its first 1D sample) and samples every distance with channel c's coefficients.  The weights follow
 * pbrt-v4's and volpathmis's path-space spectral MIS: each event multiplies the throughput *beta by
 * f_k / p_c and the ratios *r by p_k / p_c, per channel k, where p_k is the density of the event had
 * channel k been the hero.  beta / mean(r) (spectral_mis_estimate) is then the balance heuristic over
 * the three channels' strategies: the contribution of volpathmis (use_spectral_mis) and pbrt-v4's
 * VolPathIntegrator, unbiased in every channel.  beta alone is the single-channel estimate of
 * Mitsuba's plain volpath (throughput *= tr / pdf[channel]): also unbiased in a homogeneous medium,
 * but noisy in a chromatic one, and biased in a grid where channel c's null-collision density vanishes
 * where another channel's does not.  A grey medium (the same numbers in every channel) leaves r at 1.
 *
 * Random numbers: tracking needs as many as the collisions it meets, so it draws them from a per-lane
 * stream (medium_uniform: a Weyl sequence through hash_u32) that the caller keys, e.g. with
 * rng_hash(seed, pixel, pass, dimension of the bounce): the same key gives the same bits on every
 * device and at every width.
 *
 * Directions: wi points back along the incoming ray (-ray.d, Mitsuba's mi.wi and pbrt's wo), wo the
 * way the path goes on; phase functions are normalised over the sphere (value = pdf). */
#ifndef PYOPENCL_RT_MEDIA_H
#define PYOPENCL_RT_MEDIA_H

#include "accel/intersect.h"
#include "render/phase.h"
#include "render/rng.h"
#include "render/sampling.h"

/* ------------------------------------------------------------------------------------------------
 * Per-channel helpers */

/* v's channel c (0, 1 or 2) in each lane */
RT_INLINE pfloat pv3_channel(pvec3 v, pint c) { return c == 0 ? v.x : (c == 1 ? v.y : v.z); }

RT_INLINE pfloat pv3_mean(pvec3 v) { return (v.x + v.y + v.z) / 3.0f; }

/* The hero channel from a uniform u: min(floor(3 u), 2), as Mitsuba's volpath picks it. */
RT_INLINE pint medium_channel(pfloat u)
{
    const pint c = convert_pint(u * 3.0f);
    return c < 2 ? c : PINT(2);
}

/* beta / mean(r), 0 where mean(r) is 0 (or not finite): the spectral-MIS estimate (see the top). */
RT_INLINE pvec3 spectral_mis_estimate(pvec3 beta, pvec3 r)
{
    const pfloat m = pv3_mean(r);
    const pint ok = (m > 0.0f) & pisfinite(m);
    return pv3_sel(pv3_zero(), pv3_div(beta, ok ? m : PFLOAT(1.0f)), ok);
}

/* a * f / p per channel in the lanes of `m` where p > 0, 0 where p <= 0 (as Mitsuba's
 * select(pdf > 0, tr / pdf, 0)); a elsewhere. */
RT_INLINE pvec3 pv3_weigh(pvec3 a, pvec3 f, pfloat p, pint m)
{
    const pint ok = p > 0.0f;
    const pvec3 w = pv3_sel(pv3_zero(), pv3_div(pv3_mul(a, f), ok ? p : PFLOAT(1.0f)), ok);
    return pv3_sel(a, w, m);
}

/* exp(-mu s) per channel, 1 where mu is 0 (also for s = infinity: no collision can happen there) */
RT_INLINE pvec3 majorant_transmittance(pvec3 mu, pfloat s)
{
    return pv3(mu.x == 0.0f ? PFLOAT(1.0f) : pexp(-(mu.x * s)), mu.y == 0.0f ? PFLOAT(1.0f) : pexp(-(mu.y * s)),
               mu.z == 0.0f ? PFLOAT(1.0f) : pexp(-(mu.z * s)));
}

/* A distance of density sigma exp(-sigma t): -log(1 - u) / sigma (Mitsuba's sample_interaction);
 * infinity for sigma = 0. */
RT_INLINE pfloat sample_exponential(pfloat u, pfloat sigma) { return -plog(1.0f - u) / sigma; }

/* The next uniform in [0, 1) of each lane's tracking stream; the state advances in `active` lanes only. */
RT_INLINE pfloat medium_uniform(puint *state, pint active)
{
    const puint next = *state + 0x9E3779B9u;
    *state = active ? next : *state;
    return u32_to_unit_float(hash_u32(next));
}

/* ------------------------------------------------------------------------------------------------
 * Grids */

typedef struct {
    pint offset, nx, ny, nz, channels, filter, outside;
    pfloat m[12]; /* world -> local, row-major 3 x 4 */
} GridLanes;

/* grids[gi] in each lane (gi valid in every lane) */
RT_INLINE GridLanes grid_lanes(__global const MediumGrid *grids, pint gi)
{
    __global const float *f = (__global const float *)grids;
    __global const int *n = (__global const int *)grids;
    const pint base = gi * STRIDE_INDEX(MediumGrid);
    GridLanes g;
#define GRID_INT(x) g.x = pgather_int(n, base + FIELD_INDEX(MediumGrid, x));
    GRID_INT(offset) GRID_INT(nx) GRID_INT(ny) GRID_INT(nz) GRID_INT(channels) GRID_INT(filter) GRID_INT(outside)
#undef GRID_INT
    for (int k = 0; k < 12; ++k) g.m[k] = pgather(f, base + FIELD_INDEX(MediumGrid, to_local) + k);
    return g;
}

RT_INLINE pvec3 grid_to_local(const GridLanes *g, pvec3 p)
{
    return pv3(g->m[0] * p.x + g->m[1] * p.y + g->m[2] * p.z + g->m[3],
               g->m[4] * p.x + g->m[5] * p.y + g->m[6] * p.z + g->m[7],
               g->m[8] * p.x + g->m[9] * p.y + g->m[10] * p.z + g->m[11]);
}

RT_INLINE pvec3 grid_dir_to_local(const GridLanes *g, pvec3 d)
{
    return pv3(g->m[0] * d.x + g->m[1] * d.y + g->m[2] * d.z, g->m[4] * d.x + g->m[5] * d.y + g->m[6] * d.z,
               g->m[8] * d.x + g->m[9] * d.y + g->m[10] * d.z);
}


/* The part [*t0, *t1] of the ray o + t d, t in [tmin, tmax], inside the grid's box (the unit cube of its
 * local space; t stays the world ray's parameter, the map being affine).  Returns the lanes (of
 * `active`) where it is not empty. */
RT_INLINE pint grid_ray_box(const GridLanes *g, pvec3 o, pvec3 d, pfloat tmin, pfloat tmax, pint active, pfloat *t0,
                            pfloat *t1)
{
    const pvec3 lo = grid_to_local(g, o), ld = grid_dir_to_local(g, d);
    const pvec3 inv = pv3(psafe_rcp(ld.x), psafe_rcp(ld.y), psafe_rcp(ld.z));
    const pvec3 ta = pv3_mul(pv3_neg(lo), inv), tb = pv3_mul(pv3_sub(pv3_splat((float3)(1.0f)), lo), inv);
    const pfloat near = pfmax(pfmax(pfmin(ta.x, tb.x), pfmin(ta.y, tb.y)), pfmin(ta.z, tb.z));
    const pfloat far = pfmin(pfmin(pfmax(ta.x, tb.x), pfmax(ta.y, tb.y)), pfmax(ta.z, tb.z));
    *t0 = pfmax(near, tmin);
    *t1 = pfmin(far, tmax);
    return active & (*t0 <= *t1);
}

/* texel (x, y, z) (valid indices), channels 0..2 (G and B repeat R for a one-channel grid) */
RT_INLINE pvec3 grid_texel(const GridLanes *g, __global const float *data, pint x, pint y, pint z, int rgb)
{
    const pint i = g->offset + ((z * g->ny + y) * g->nx + x) * g->channels;
    const pfloat r = pgather(data, i);
    if (!rgb) return pv3(r, r, r);
    const pint three = g->channels == 3;
    return pv3(r, pgather(data, three ? i + 1 : i), pgather(data, three ? i + 2 : i));
}

/* The texel at integer position (ix, iy, iz), which may lie outside the grid: clamped to its edge
 * (GRID_CLAMP) or 0 (GRID_ZERO) */
RT_INLINE pvec3 grid_fetch(const GridLanes *g, __global const float *data, pint ix, pint iy, pint iz, int rgb)
{
    const pint inside = (ix >= 0) & (ix < g->nx) & (iy >= 0) & (iy < g->ny) & (iz >= 0) & (iz < g->nz);
    ix = ix < 0 ? PINT(0) : (ix < g->nx ? ix : g->nx - 1);
    iy = iy < 0 ? PINT(0) : (iy < g->ny ? iy : g->ny - 1);
    iz = iz < 0 ? PINT(0) : (iz < g->nz ? iz : g->nz - 1);
    const pvec3 v = grid_texel(g, data, ix, iy, iz, rgb);
    return pv3_sel(pv3_zero(), v, inside | (g->outside == GRID_CLAMP));
}

RT_INLINE pvec3 pv3_lerp(pfloat w0, pvec3 a, pfloat w1, pvec3 b) { return pv3_add(pv3_scale(a, w0), pv3_scale(b, w1)); }

/* The grid's value at the local point q (RGB; a one-channel grid's value in every channel) in the lanes
 * of `active` (0 elsewhere).  Trilinear: q * n - 0.5 lies between the texel centres it interpolates, the
 * weights applied along x, then y, then z, as Dr.Jit's texture (Mitsuba's gridvolume) and pbrt-v4's
 * SampledGrid do; nearest: the texel floor(q * n).  No lookup leaves the grid's data. */
RT_INLINE pvec3 grid_eval(const GridLanes *g, __global const float *data, pvec3 q, pint active)
{
    const int rgb = pany(active & (g->channels == 3));
    const pfloat nx = convert_pfloat(g->nx), ny = convert_pfloat(g->ny), nz = convert_pfloat(g->nz);
    const pint nearest = g->filter == GRID_NEAREST;
    /* positions kept finite and within a few texels of the grid, so the integer conversions are exact */
    const pfloat px = pclamp(nearest ? q.x * nx : q.x * nx - 0.5f, -2.0f, 1e7f);
    const pfloat py = pclamp(nearest ? q.y * ny : q.y * ny - 0.5f, -2.0f, 1e7f);
    const pfloat pz = pclamp(nearest ? q.z * nz : q.z * nz - 0.5f, -2.0f, 1e7f);
    const pfloat fx = pfloor(px), fy = pfloor(py), fz = pfloor(pz);
    pint ix = convert_pint(fx), iy = convert_pint(fy), iz = convert_pint(fz);
    const pint lanes = active & pisfinite(px) & pisfinite(py) & pisfinite(pz);
    ix = lanes ? ix : PINT(0);
    iy = lanes ? iy : PINT(0);
    iz = lanes ? iz : PINT(0);
    pvec3 v = grid_fetch(g, data, ix, iy, iz, rgb);
    const pint linear = lanes & pnot(nearest);
    if (pany(linear)) {
        const pfloat w1x = px - fx, w1y = py - fy, w1z = pz - fz;
        const pfloat w0x = 1.0f - w1x, w0y = 1.0f - w1y, w0z = 1.0f - w1z;
        const pint jx = ix + 1, jy = iy + 1, jz = iz + 1;
        const pvec3 f00 = pv3_lerp(w0x, v, w1x, grid_fetch(g, data, jx, iy, iz, rgb));
        const pvec3 f01 = pv3_lerp(w0x, grid_fetch(g, data, ix, iy, jz, rgb), w1x, grid_fetch(g, data, jx, iy, jz, rgb));
        const pvec3 f10 = pv3_lerp(w0x, grid_fetch(g, data, ix, jy, iz, rgb), w1x, grid_fetch(g, data, jx, jy, iz, rgb));
        const pvec3 f11 = pv3_lerp(w0x, grid_fetch(g, data, ix, jy, jz, rgb), w1x, grid_fetch(g, data, jx, jy, jz, rgb));
        const pvec3 f0 = pv3_lerp(w0y, f00, w1y, f10), f1 = pv3_lerp(w0y, f01, w1y, f11);
        v = pv3_sel(v, pv3_lerp(w0z, f0, w1z, f1), linear);
    }
    return pv3_sel(pv3_zero(), v, lanes);
}

/* ------------------------------------------------------------------------------------------------
 * Media */

typedef struct {
    pint type, phase, density_grid, albedo_grid, flags;
    pvec3 sigma_t, albedo, majorant;
    pfloat g;
    GridLanes density, albedo_map; /* gathered where the index is >= 0 in some lane (grid 0 in the others) */
} MediumLanes;


/* media[mi] in each lane (mi valid in every lane; pass 0 where a lane has no medium) */
RT_INLINE MediumLanes medium_lanes(__global const Medium *media, __global const MediumGrid *grids, pint mi)
{
    __global const float *f = (__global const float *)media;
    __global const int *n = (__global const int *)media;
    const pint base = mi * STRIDE_INDEX(Medium);
    MediumLanes m;
#define MEDIUM_INT(x) m.x = pgather_int(n, base + FIELD_INDEX(Medium, x));
#define MEDIUM_VEC3(x) m.x = pv3_gather(f, base + FIELD_INDEX(Medium, x));
    MEDIUM_INT(type) MEDIUM_INT(phase) MEDIUM_INT(density_grid) MEDIUM_INT(albedo_grid) MEDIUM_INT(flags)
    MEDIUM_VEC3(sigma_t) MEDIUM_VEC3(albedo) MEDIUM_VEC3(majorant)
#undef MEDIUM_INT
#undef MEDIUM_VEC3
    m.g = pgather(f, base + FIELD_INDEX(Medium, g));
    const pint dense = m.density_grid >= 0, mapped = m.albedo_grid >= 0;
    if (pany(dense)) m.density = grid_lanes(grids, dense ? m.density_grid : PINT(0));
    if (pany(mapped)) m.albedo_map = grid_lanes(grids, mapped ? m.albedo_grid : PINT(0));
    return m;
}

/* sigma_t and sigma_s at the point p, in the lanes of `active`: sigma_t times the density grid's value
 * (a grid medium; the caller keeps p inside its box) and times the albedo, or the albedo grid's value. */
RT_INLINE void medium_coefficients(const MediumLanes *m, __global const float *grid_data, pvec3 p, pint active,
                                   pvec3 *sigma_t, pvec3 *sigma_s)
{
    pvec3 st = m->sigma_t, a = m->albedo;
    const pint dense = active & (m->density_grid >= 0);
    if (pany(dense))
        st = pv3_sel(st, pv3_mul(st, grid_eval(&m->density, grid_data, grid_to_local(&m->density, p), dense)), dense);
    const pint mapped = active & (m->albedo_grid >= 0);
    if (pany(mapped))
        a = pv3_sel(a, grid_eval(&m->albedo_map, grid_data, grid_to_local(&m->albedo_map, p), mapped), mapped);
    *sigma_t = st;
    *sigma_s = pv3_mul(st, a);
}

/* The stretch [*t0, *t1] of o + t d, t in [tmin, tmax], where the lanes' media can interact: all of it in
 * a homogeneous medium, the part inside the density grid's box in a grid medium. */
RT_INLINE pint medium_segment(const MediumLanes *m, pvec3 o, pvec3 d, pfloat tmin, pfloat tmax, pint active, pfloat *t0,
                              pfloat *t1)
{
    *t0 = tmin;
    *t1 = tmax;
    pint live = active & (tmin <= tmax);
    const pint boxed = active & (m->density_grid >= 0);
    if (pany(boxed)) {
        pfloat b0, b1;
        const pint in = grid_ray_box(&m->density, o, d, tmin, tmax, boxed, &b0, &b1);
        *t0 = boxed ? b0 : *t0;
        *t1 = boxed ? b1 : *t1;
        live = boxed ? in : live;
    }
    return live;
}

/* One tentative collision of the trackers below (rate mu = majorant[channel] from tc along o + t d):
 * draws the step *s; the lanes of *live whose collision lies at or beyond t1 (or whose step is NaN)
 * leave *live, with *a and *r weighed by the majorant transmittance of the rest, [tc, t1], over its
 * channel's; the others advance *tc to the collision and get its coefficients *st, *ss.  Returns 0
 * where no lane is left. */
RT_INLINE int medium_tracking_step(const MediumLanes *m, __global const float *grid_data, pvec3 o, pvec3 d, pfloat t1,
                                   pint channel, puint *rng, pint *live, pfloat *tc, pfloat *s, pvec3 *a, pvec3 *r,
                                   pvec3 *st, pvec3 *ss)
{
    const pvec3 mu = m->majorant;
    *s = sample_exponential(medium_uniform(rng, *live), pv3_channel(mu, channel));
    const pfloat next = *tc + *s;
    const pint escaped = *live & pnot(next < t1);
    if (pany(escaped)) {
        const pvec3 T = majorant_transmittance(mu, t1 - *tc);
        const pfloat p = pv3_channel(T, channel);
        *a = pv3_weigh(*a, T, p, escaped);
        *r = pv3_weigh(*r, T, p, escaped);
        *live &= pnot(escaped);
    }
    if (!pany(*live)) return 0;
    *tc = *live ? next : *tc;
    medium_coefficients(m, grid_data, pv3_add(o, pv3_scale(d, *tc)), *live, st, ss);
    return 1;
}

/* sigma_n = mu - sigma_t, at least 0: the null collisions' coefficient under the majorant mu */
RT_INLINE pvec3 majorant_null(pvec3 mu, pvec3 sigma_t)
{
    return pv3(pfmax(mu.x - sigma_t.x, PFLOAT(0.0f)), pfmax(mu.y - sigma_t.y, PFLOAT(0.0f)),
               pfmax(mu.z - sigma_t.z, PFLOAT(0.0f)));
}

/* Free-flight sampling along o + t d, t in [tmin, tmax] (tmax: the next surface, or infinity), in the lanes
 * of `active`, with the hero channel `channel` and the tracking stream *rng (see the top).  Delta tracking:
 * tentative collisions at rate mu = majorant[channel] from the start of the medium's segment; one at x is
 * real with probability sigma_t[channel](x) / mu, else null and tracking goes on.  In a homogeneous medium
 * mu = sigma_t: the first distance, -log(1 - u) / sigma_t[channel], is the collision (Mitsuba's
 * sample_interaction).  Returns the lanes with a real collision, at *t (in [tmin, tmax)); the others reach
 * tmax (*t = tmax).  Each event multiplies *beta by f_k / p_c and *r by p_k / p_c per channel k (the top),
 * with T_k = exp(-mu_k s) over the step s: a null collision f_k = p_k = T_k sigma_n_k (sigma_n = mu -
 * sigma_t, at least 0); the real one f_k = T_k sigma_s_k (a scattering event, the albedo included) and
 * p_k = T_k sigma_t_k; reaching tmax f_k = p_k = T_k over the rest of the segment.  A weight whose p_c is
 * 0 is 0. */
RT_INLINE pint medium_sample_free_flight(const MediumLanes *m, __global const float *grid_data, pvec3 o, pvec3 d,
                                         pfloat tmin, pfloat tmax, pint channel, puint *rng, pint active, pfloat *t,
                                         pvec3 *beta, pvec3 *r)
{
    pfloat tc, t1; /* tracking starts where the segment does */
    pint live = medium_segment(m, o, d, tmin, tmax, active, &tc, &t1);
    const pvec3 mu = m->majorant;
    const pfloat mu_c = pv3_channel(mu, channel);
    pint real = PINT(0);
    while (pany(live)) {
        pfloat s;
        pvec3 st, ss;
        if (!medium_tracking_step(m, grid_data, o, d, t1, channel, rng, &live, &tc, &s, beta, r, &st, &ss)) break;
        const pfloat u = medium_uniform(rng, live);
        const pfloat st_c = pv3_channel(st, channel);
        const pint hit = live & (u * mu_c < st_c); /* u < sigma_t_c / mu_c */
        const pvec3 T = majorant_transmittance(mu, s);
        const pfloat T_c = pv3_channel(T, channel);
        if (pany(hit)) {
            const pfloat p = T_c * st_c;
            *beta = pv3_weigh(*beta, pv3_mul(T, ss), p, hit);
            *r = pv3_weigh(*r, pv3_mul(T, st), p, hit);
            real |= hit;
        }
        const pint null = live & pnot(hit);
        const pvec3 sn = majorant_null(mu, st);
        const pvec3 f = pv3_mul(T, sn);
        const pfloat p = pv3_channel(f, channel);
        *beta = pv3_weigh(*beta, f, p, null);
        *r = pv3_weigh(*r, f, p, null);
        live &= pnot(hit) & (p > 0.0f); /* a null collision of zero weight ends the path too */
    }
    *t = real ? tc : tmax;
    return real;
}

/* Transmittance of the segment o + t d, t in [tmin, tmax], in the lanes of `active`: multiplies *T by it.
 * A homogeneous medium: exp(-sigma_t (tmax - tmin)) (1 where sigma_t is 0), exactly (*r unchanged).  A grid: ratio tracking, with
 * tentative collisions at rate mu = majorant[channel] through the grid's box; each multiplies *T by
 * T_k sigma_n_k / p_c and *r by T_k mu_k / p_c (p_c = T_c mu_c, the density of the collision), and the
 * rest of the box *T and *r by T_k / T_c.  *T / mean(*r) then estimates the transmittance of every
 * channel with the balance heuristic over the channels' strategies (pbrt-v4's T_ray and r_l); with a grey
 * majorant *r stays 1 and *T is the classic product of 1 - sigma_t / mu. */
RT_INLINE void medium_transmittance(const MediumLanes *m, __global const float *grid_data, pvec3 o, pvec3 d,
                                    pfloat tmin, pfloat tmax, pint channel, puint *rng, pint active, pvec3 *T,
                                    pvec3 *r)
{
    const pint homogeneous = active & (m->density_grid < 0) & (tmin < tmax);
    if (pany(homogeneous)) {
        const pvec3 tr = majorant_transmittance(m->sigma_t, tmax - tmin);
        *T = pv3_sel(*T, pv3_mul(*T, tr), homogeneous);
    }
    pfloat tc, t1; /* tracking starts where the segment does */
    pint live = medium_segment(m, o, d, tmin, tmax, active & (m->density_grid >= 0), &tc, &t1);
    const pvec3 mu = m->majorant;
    const pfloat mu_c = pv3_channel(mu, channel);
    while (pany(live)) {
        pfloat s;
        pvec3 st, ss;
        if (!medium_tracking_step(m, grid_data, o, d, t1, channel, rng, &live, &tc, &s, T, r, &st, &ss)) break;
        const pvec3 Tm = majorant_transmittance(mu, s);
        const pfloat p = pv3_channel(Tm, channel) * mu_c;
        const pvec3 sn = majorant_null(mu, st);
        *T = pv3_weigh(*T, pv3_mul(Tm, sn), p, live);
        *r = pv3_weigh(*r, pv3_mul(Tm, mu), p, live);
        live &= (pv3_max3(*T) > 0.0f) & (p > 0.0f); /* nothing left to carry */
    }
}

/* ------------------------------------------------------------------------------------------------
 * Phase functions */

/* the medium's phase function (render/phase.h) */
RT_INLINE pfloat phase_eval(const MediumLanes *m, pvec3 wi, pvec3 wo) { return phase_eval_pg(m->phase, m->g, wi, wo); }

RT_INLINE pvec3 phase_sample(const MediumLanes *m, pvec3 wi, pfloat u1, pfloat u2, pfloat *pdf)
{
    return phase_sample_pg(m->phase, m->g, wi, u1, u2, pdf);
}

/* ------------------------------------------------------------------------------------------------
 * Boundaries */

/* The medium of a ray along d after it crosses a surface whose interface is ii (-1: none) and whose
 * front side's normal is ng ((v1 - v0) x (v2 - v0) of a triangle, a sphere's outward normal): with
 * MEDIUM_IF_TRANSITION, exterior where dot(d, ng) > 0, else interior (Mitsuba's target_medium);
 * otherwise `current` (pbrt-v4's rule for a surface that is no medium transition).  *null: the lanes
 * whose surface is index-matched (MEDIUM_IF_NULL: no scattering there). */
RT_INLINE pint medium_after_crossing(__global const MediumInterface *interfaces, pint ii, pvec3 ng, pvec3 d,
                                     pint current, pint *null)
{
    __global const int *n = (__global const int *)interfaces;
    const pint has = ii >= 0;
    const pint base = (has ? ii : PINT(0)) * STRIDE_INDEX(MediumInterface);
    const pint flags = has ? pgather_int(n, base + FIELD_INDEX(MediumInterface, flags)) : PINT(0);
    const pint interior = pgather_int(n, base + FIELD_INDEX(MediumInterface, interior));
    const pint exterior = pgather_int(n, base + FIELD_INDEX(MediumInterface, exterior));
    *null = (flags & MEDIUM_IF_NULL) != 0;
    const pint target = pv3_dot(d, ng) > 0.0f ? exterior : interior;
    return (flags & MEDIUM_IF_TRANSITION) != 0 ? target : current;
}

#endif
