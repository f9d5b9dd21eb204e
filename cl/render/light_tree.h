/* The light BVH (LIGHT_TREE; pyopencl_rt/render/light_tree.py builds it and documents the design,
 * pbrt-v4's BVHLightSampler), over the lanes (cl/render/lanes.h): each lane descends from the root
 * toward the shading point p (normal n; 0 in a medium), at each inner node taking a child with
 * probability proportional to its importance, until a leaf names a light.
 *
 *   light_node_importance  a node's importance to (p, n): pbrt-v4's LightBounds::Importance
 *   light_tree_sample      a light and the probability of the descent that took it (0: none)
 *   light_tree_pmf         that probability for a given light: the same descent along its bit trail
 *                          (Light.trail), for the MIS weight of a BSDF sample that hit it
 *
 * Both walks compute a child's probability the same way (p0 = i0 / (i0 + i1), 1 - p0 for the second),
 * so a lane that samples a light and a lane that asks for its pmf from the same point get the same
 * float.  The float64 reference is light_tree.py's importance / tree_pmfs. */
#ifndef PYOPENCL_RT_LIGHT_TREE_H
#define PYOPENCL_RT_LIGHT_TREE_H

#include "render/lanes.h"

#define NODE_F(nodes, row, field) pgather((__global const float *)(nodes), (row) + FIELD_INDEX(LightNode, field))
#define NODE_I(nodes, row, field) pgather_int((__global const int *)(nodes), (row) + FIELD_INDEX(LightNode, field))
#define NODE_V3(nodes, row, field) \
    pv3(NODE_F(nodes, row, field), NODE_F(nodes, (row) + 1, field), NODE_F(nodes, (row) + 2, field))

/* cos(max(0, a - b)) and sin(max(0, a - b)) of angles given by their sines and cosines */
RT_INLINE pfloat cos_sub_clamped(pfloat sin_a, pfloat cos_a, pfloat sin_b, pfloat cos_b)
{
    return cos_a > cos_b ? PFLOAT(1.0f) : cos_a * cos_b + sin_a * sin_b;
}

RT_INLINE pfloat sin_sub_clamped(pfloat sin_a, pfloat cos_a, pfloat sin_b, pfloat cos_b)
{
    return cos_a > cos_b ? PFLOAT(0.0f) : sin_a * cos_b - cos_a * sin_b;
}

RT_INLINE pfloat sqrt_one_minus_sq(pfloat c) { return psqrt(pfmax(PFLOAT(0.0f), 1.0f - c * c)); }

/* The importance of node `node` (each lane's) to p with normal n (n = 0: no cosine bound): its power
 * over the squared distance to its box's centre (the node keeps the box's bounding sphere) (at least the half diagonal, as pbrt-v4 clamps it:
 * not a squared length, but it keeps the distance's weight inside big boxes), times the cosine
 * bounds of the emission cone toward p and of the incidence at p, both widened by the angle the
 * box's bounding sphere subtends from p; 0 past the cone's cos_e.  Inside that sphere, phi / d2. */
RT_INLINE pfloat light_node_importance(__global const LightNode *nodes, pint node, pvec3 p, pvec3 n)
{
    const pint row = node * STRIDE_INDEX(LightNode);
    const pvec3 pc = NODE_V3(nodes, row, centre), axis = NODE_V3(nodes, row, axis);
    const pfloat r = NODE_F(nodes, row, radius), phi = NODE_F(nodes, row, phi);
    const pfloat cos_o = NODE_F(nodes, row, cos_o), sin_o = NODE_F(nodes, row, sin_o), cos_e = NODE_F(nodes, row, cos_e);
    const pfloat r2 = r * r;
    const pvec3 to = pv3_sub(p, pc);
    const pfloat dist2 = pv3_dot(to, to);
    const pint inside = dist2 <= r2;
    const pfloat d2 = pfmax(pfmax(dist2, r), PFLOAT(FLT_MIN)); /* pbrt-v4's clamp: the half diagonal */
    const pvec3 wi = pv3_scale(to, 1.0f / psqrt(dist2 > 0.0f ? dist2 : PFLOAT(1.0f)));
    pfloat cos_w = pv3_dot(wi, axis);
    cos_w = NODE_I(nodes, row, two_sided) != 0 ? pabs(cos_w) : cos_w;
    const pfloat sin_w = sqrt_one_minus_sq(cos_w);
    const pfloat cos_b = inside ? PFLOAT(-1.0f) : psqrt(pfmax(PFLOAT(0.0f), 1.0f - r2 / (inside ? PFLOAT(1.0f) : dist2)));
    const pfloat sin_b = sqrt_one_minus_sq(cos_b);
    const pfloat cos_x = cos_sub_clamped(sin_w, cos_w, sin_o, cos_o);
    const pfloat sin_x = sin_sub_clamped(sin_w, cos_w, sin_o, cos_o);
    const pfloat cos_p = cos_sub_clamped(sin_x, cos_x, sin_b, cos_b);
    pfloat imp = cos_p > cos_e ? phi * cos_p / d2 : PFLOAT(0.0f);
    const pint has_n = pv3_dot(n, n) > 0.0f;
    const pfloat cos_i = pabs(pv3_dot(wi, n));
    const pfloat sin_i = sqrt_one_minus_sq(cos_i);
    imp = has_n ? imp * cos_sub_clamped(sin_i, cos_i, sin_b, cos_b) : imp;
    imp = pfmax(imp, PFLOAT(0.0f));
    return inside ? (cos_e < 1.0f ? phi / d2 : PFLOAT(0.0f)) : imp;
}

/* The probability of the first of the children (first, second) of the lanes in `inner` (its
 * importance's share; 0 when neither matters: both walks stop there) */
RT_INLINE pfloat light_tree_first(__global const LightNode *nodes, pint inner, pint first, pint second, pvec3 p,
                                  pvec3 n, pfloat *total)
{
    const pfloat i0 = light_node_importance(nodes, inner ? first : PINT(0), p, n);
    const pfloat i1 = light_node_importance(nodes, inner ? second : PINT(0), p, n);
    *total = i0 + i1;
    return *total > 0.0f ? i0 / *total : PFLOAT(0.0f);
}

/* A light of the tree for the lanes of `active` from u in [0, 1): its row, *pmf the probability of
 * the descent (0 where the lane got none: inactive, or every light out of reach of p). */
RT_INLINE pint light_tree_sample(__global const LightNode *nodes, pint active, pvec3 p, pvec3 n, pfloat u,
                                 pfloat *pmf)
{
    pint node = PINT(0);
    pfloat prob = PFLOAT(1.0f);
    pint live = active;
    pint child = NODE_I(nodes, node * STRIDE_INDEX(LightNode), child); /* < 0: a leaf, -1 - its light */
    pint inner = live & (child >= 0);
    while (pany(inner)) {
        const pint second = child;
        pfloat total;
        const pfloat p0 = light_tree_first(nodes, inner, node + 1, second, p, n, &total);
        const pint first = u < p0;
        u = pfmin(first ? u / p0 : (u - p0) / (1.0f - p0), PFLOAT(0x1.fffffep-1f));
        prob = inner ? prob * (first ? p0 : 1.0f - p0) : prob;
        live &= pnot(inner & pnot(total > 0.0f));
        node = inner ? (first ? node + 1 : second) : node;
        inner &= live;
        child = NODE_I(nodes, node * STRIDE_INDEX(LightNode), child);
        inner &= child >= 0;
    }
    *pmf = live ? prob : PFLOAT(0.0f);
    return live ? -1 - child : PINT(0);
}

/* The probability that light_tree_sample() from (p, n) takes the light of bit trail `trail` (each
 * lane's; < 0: not in the tree, 0) */
RT_INLINE pfloat light_tree_pmf(__global const LightNode *nodes, pint trail, pvec3 p, pvec3 n)
{
    pint node = PINT(0);
    pfloat prob = PFLOAT(1.0f);
    pint live = trail >= 0;
    pint child = NODE_I(nodes, PINT(0), child); /* < 0: a leaf */
    pint inner = live & (child >= 0);
    while (pany(inner)) {
        const pint second = child;
        pfloat total;
        const pfloat p0 = light_tree_first(nodes, inner, node + 1, second, p, n, &total);
        const pint take_second = (trail & 1) != 0;
        prob = inner ? prob * (take_second ? 1.0f - p0 : p0) : prob;
        live &= pnot(inner & pnot(total > 0.0f));
        node = inner ? (take_second ? second : node + 1) : node;
        trail = inner ? trail >> 1 : trail;
        inner &= live;
        child = NODE_I(nodes, node * STRIDE_INDEX(LightNode), child);
        inner &= child >= 0;
    }
    return live ? prob : PFLOAT(0.0f);
}

#undef NODE_F
#undef NODE_I
#undef NODE_V3

#endif
