/* The pixel reconstruction filter, by filter importance sampling (pyopencl_rt/render/filters.py
 * explains the method and builds the tables): a camera sample's offset from its pixel's centre
 * is drawn, axis by axis, with a density proportional to |f|, and the sample carries the weight
 * sign(f) * filter_weight (the Camera record; 1 for filters without negative lobes), so that the
 * film's plain average of the weighted samples is the filtered pixel.  Written over the lanes of
 * cl/render/lanes.h; the filter is the same in every lane, so its method is a uniform branch.
 *
 *   FILTER_BOX        uniform over [-r, r]: with r = 0.5 the jitter is the sample itself
 *   FILTER_TENT       max(0, 1 - |x| / r), its CDF inverted in closed form
 *   FILTER_TABULATED  (gaussian, mitchell, lanczos) per axis, the filter's stretches of one sign
 *                     (segments) in cells of equal mass of |f|: the segment by comparing u with
 *                     their starts (the same values in every lane), the cell by multiplying, the
 *                     offset within it by inverting |f| interpolated linearly between its knots;
 *                     no search, four gathers */
#ifndef PYOPENCL_RT_FILTER_H
#define PYOPENCL_RT_FILTER_H

#include "render/lanes.h"

/* The jitter along `axis` (0: x, 1: y), in pixels from the pixel's top-left corner (0.5 is its
 * centre; 0.5 - r .. 0.5 + r), of the uniform sample u in [0, 1); *negative: the lanes where
 * the filter is negative there. */
RT_INLINE pfloat filter_jitter(const Camera *cam, __global const float *table, int axis, pfloat u, pint *negative)
{
    const float r = cam->filter_radius[axis];
    *negative = PINT(0);
    if (cam->filter == FILTER_BOX)
        return (0.5f - r) + (2.0f * r) * u;
    if (cam->filter == FILTER_TENT) {
        /* the CDF (r + x)^2 / 2r^2 left of the centre, 1 - (r - x)^2 / 2r^2 right of it */
        const pint left = u < 0.5f;
        const pfloat s = psqrt(left ? 2.0f * u : 2.0f - 2.0f * u);
        return 0.5f + (left ? r * (s - 1.0f) : r * (1.0f - s));
    }
    __global const float *seg = table + axis * (FILTER_MAX_SEGMENTS * FILTER_SEGMENT_FLOATS + 2 * cam->filter_knots);
    __global const float *knots = seg + FILTER_MAX_SEGMENTS * FILTER_SEGMENT_FLOATS; /* (x, f) pairs */
    pfloat start = PFLOAT(seg[0]), rate = PFLOAT(seg[1]), first = PFLOAT(seg[2]), last = PFLOAT(seg[3]);
    pint neg = PFLOAT(seg[4]) != 0.0f;
    for (int k = 1; k < cam->filter_segments[axis]; ++k) { /* the last segment starting at or before u */
        __global const float *g = seg + k * FILTER_SEGMENT_FLOATS;
        const pint in = u >= g[0];
        start = in ? PFLOAT(g[0]) : start;
        rate = in ? PFLOAT(g[1]) : rate;
        first = in ? PFLOAT(g[2]) : first;
        last = in ? PFLOAT(g[3]) : last;
        neg = in ? (PFLOAT(g[4]) != 0.0f) : neg;
    }
    const pfloat c = pfmax((u - start) * rate, PFLOAT(0.0f)); /* cells into the segment */
    const pfloat cell = pfmin(first + convert_pfloat(convert_pint(c)), last); /* c >= 0: truncation floors */
    const pfloat s = pclamp(c - (cell - first), 0.0f, 1.0f);   /* the fraction of the cell's mass */
    const pint i = 2 * convert_pint(cell);
    const pfloat x0 = pgather(knots, i), f0 = pgather(knots, i + 1);
    const pfloat x1 = pgather(knots, i + 2), f1 = pgather(knots, i + 3);
    /* the fraction t of the cell where the area under the line from a = |f0| to b = |f1| reaches
     * s of the cell's: (a t + (b - a) t^2 / 2) / ((a + b) / 2) = s, in the form that stays exact
     * as b - a goes to 0 */
    const pfloat a = pabs(f0), b = pabs(f1);
    const pfloat den = a + psqrt((a * a) * (1.0f - s) + (b * b) * s);
    const pfloat t = den > 0.0f ? pfmin(s * (a + b) / den, PFLOAT(1.0f)) : s;
    *negative = neg;
    return 0.5f + (x0 + t * (x1 - x0));
}

/* The weight of a sample whose offsets fell where the filter's axes have these signs. */
RT_INLINE pfloat filter_weight(const Camera *cam, pint negative_x, pint negative_y)
{
    return (negative_x ^ negative_y) ? PFLOAT(-cam->filter_weight) : PFLOAT(cam->filter_weight);
}

#endif
