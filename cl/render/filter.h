/* The pixel reconstruction filter, by filter importance sampling (pyopencl_rt/render/filters.py
 * explains the method and builds the tables): a camera sample's offset from its pixel's centre
 * is drawn, axis by axis, with a density proportional to |f|, and the sample carries the weight
 * sign(f) * filter_weight (the Camera record; 1 for filters without negative lobes), so that the
 * film's plain average of the weighted samples is the filtered pixel.  Written over the lanes of
 * cl/render/lanes.h; the filter is the same in every lane, so its method is a uniform branch.
 *
 *   FILTER_BOX        uniform over [-r, r]: with r = 0.5 the jitter is the sample itself
 *   FILTER_TENT       max(0, 1 - |x| / r), its CDF inverted in closed form
 *   FILTER_TABULATED  (gaussian, mitchell, lanczos) per axis, filter_knots knots of filter_cdf:
 *                     the knots x, the filter f there and the CDF of |f|; the cell by binary
 *                     search (cdf_find), the offset within it by inverting |f| interpolated
 *                     linearly across the cell (the sign of f is constant over a cell) */
#ifndef PYOPENCL_RT_FILTER_H
#define PYOPENCL_RT_FILTER_H

#include "render/sampling.h"

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
    const int n = cam->filter_knots;
    __global const float *x = table + axis * 3 * n, *f = x + n, *cdf = f + n;
    const pint i = cdf_find(cdf, PINT(0), n - 1, u);
    const pfloat c0 = pgather(cdf, i), c1 = pgather(cdf, i + 1);
    const pfloat x0 = pgather(x, i), x1 = pgather(x, i + 1);
    const pfloat f0 = pgather(f, i), f1 = pgather(f, i + 1);
    /* the fraction t of the cell where the area under the line from a = |f0| to b = |f1| reaches
     * the fraction s of the cell's: (a t + (b - a) t^2 / 2) / ((a + b) / 2) = s, in the form that
     * stays exact as b - a goes to 0 */
    const pfloat a = pabs(f0), b = pabs(f1);
    const pfloat s = pclamp((u - c0) / (c1 - c0), 0.0f, 1.0f);
    const pfloat den = a + psqrt((a * a) * (1.0f - s) + (b * b) * s);
    const pfloat t = den > 0.0f ? pfmin(s * (a + b) / den, PFLOAT(1.0f)) : s;
    *negative = (f0 + f1) < 0.0f;
    return 0.5f + (x0 + t * (x1 - x0));
}

/* The weight of a sample whose offsets fell where the filter's axes have these signs. */
RT_INLINE pfloat filter_weight(const Camera *cam, pint negative_x, pint negative_y)
{
    return (negative_x ^ negative_y) ? PFLOAT(-cam->filter_weight) : PFLOAT(cam->filter_weight);
}

#endif
