/* The wide traversal, written once over the node width WN (4 or 8): included by bvh_wide.h with
 * WN 4 and by bvh_wide8.h with WN 8 (the host expands a .tpl.h at every include; see
 * pyopencl_rt/device/kernels.py).  Names carry the width: WN_(intersect_children) is
 * intersect_children4 or intersect_children8, and so on; bvh_wide.h documents the buffers, the
 * ray constants and the stack. */
#define WFLOAT WN_(float)
#define WINT WN_(int)
#if WN == 4 /* any and abs are macros of the OpenCL headers: no WN_ pasting on them */
#define WSTACK WIDE_STACK_SIZE
#define WUNITS TRI4_UNITS
#define WANY any4
#define WABS abs4
#else
#define WSTACK WIDE8_STACK_SIZE
#define WUNITS TRI8_UNITS
#define WANY any8
#define WABS abs8
#endif

/* WN child boxes in one slab test.  Returns the hit mask (-1 per hit lane) and the entry distances
 * in *enter.  Conservative as intersect_box (cl/accel/intersect.h, "Conservative on purpose"): the
 * far distances are widened by SLAB_FAR_SCALE and the host pads every box by 2^-20 of the scene's
 * largest coordinate (bvh_wide.device_blob).  The widening is folded into the far planes' inverse
 * direction (inv_far), which rounds as much as widening each far distance does (two roundings
 * either way) and takes a multiply off the test's dependency chain; tmax joins the minimum there.
 * No operand can be NaN (bvh_wide.h), so the plain comparisons of VMIN/VMAX equal fmin/fmax
 * without their NaN handling.  An entry distance of +inf counts as a miss, as INFINITY is the
 * binary test's miss value. */
RT_INLINE WINT WN_(intersect_children)(__global const WFLOAT *node, const WideRay *r, float tmin, float tmax,
                                        WFLOAT *enter)
{
    const WFLOAT tnx = (node[r->nx] - r->o.x) * r->inv_d.x;
    const WFLOAT tny = (node[r->ny] - r->o.y) * r->inv_d.y;
    const WFLOAT tnz = (node[r->nz] - r->o.z) * r->inv_d.z;
    const WFLOAT tfx = (node[3 - r->nx] - r->o.x) * r->inv_far.x;
    const WFLOAT tfy = (node[5 - r->ny] - r->o.y) * r->inv_far.y;
    const WFLOAT tfz = (node[7 - r->nz] - r->o.z) * r->inv_far.z;
    const WFLOAT e = VMAX(VMAX(tnx, tny), VMAX(tnz, (WFLOAT)(tmin)));
    const WFLOAT l = VMIN(VMIN(tfx, tfy), VMIN(tfz, (WFLOAT)(tmax)));
    *enter = e;
    return (e <= l) & (e < (WFLOAT)(INFINITY));
}

/* The planes of a packet's WN triangles: triangle_plane (intersect.h) on WN lanes, the same
 * arithmetic (n, the magnitudes of its products, the sliver flag). */
RT_INLINE WINT WN_(tri_plane)(__global const WFLOAT *pk, WFLOAT *nx, WFLOAT *ny, WFLOAT *nz, WFLOAT *nabs_x,
                               WFLOAT *nabs_y, WFLOAT *nabs_z)
{
    const WFLOAT p0x = pk[0], p0y = pk[1], p0z = pk[2];
    const WFLOAT e1x = pk[3] - p0x, e1y = pk[4] - p0y, e1z = pk[5] - p0z;
    const WFLOAT e2x = pk[6] - p0x, e2y = pk[7] - p0y, e2z = pk[8] - p0z;
    *nx = e1y * e2z - e1z * e2y;
    *ny = e1z * e2x - e1x * e2z;
    *nz = e1x * e2y - e1y * e2x;
    *nabs_x = WABS(e1y * e2z) + WABS(e1z * e2y);
    *nabs_y = WABS(e1z * e2x) + WABS(e1x * e2z);
    *nabs_z = WABS(e1x * e2y) + WABS(e1y * e2x);
    return WABS(*nx) + WABS(*ny) + WABS(*nz) < SLIVER_CANCELLATION * (*nabs_x + *nabs_y + *nabs_z);
}

#ifdef cl_khr_fp64
/* The double-precision fallbacks on WN lanes: an edge function a b - c d, and t of the plane
 * equation (with *ok: den != 0), four lanes at a time (double8 would pass through PoCL's builtins
 * with a non-AVX-512 ABI: a warning per call site, and calls). */
#if WN == 4
RT_INLINE float4 edge_double_w4(float4 a, float4 b, float4 c, float4 d) { return edge_double4(a, b, c, d); }
RT_INLINE float4 plane_t_double_w4(__global const float4 *pk, const WideRay *r, int4 *ok)
{
    return plane_t_double4(pk[0], pk[1], pk[2], pk[3], pk[4], pk[5], pk[6], pk[7], pk[8], r, ok);
}
#else
RT_INLINE float8 edge_double_w8(float8 a, float8 b, float8 c, float8 d)
{
    return (float8)(edge_double4(a.lo, b.lo, c.lo, d.lo), edge_double4(a.hi, b.hi, c.hi, d.hi));
}
RT_INLINE float8 plane_t_double_w8(__global const float8 *pk, const WideRay *r, int8 *ok)
{
    const float8 p0x = pk[0], p0y = pk[1], p0z = pk[2], p1x = pk[3], p1y = pk[4], p1z = pk[5];
    const float8 p2x = pk[6], p2y = pk[7], p2z = pk[8];
    int4 ok_lo, ok_hi;
    const float4 t_lo = plane_t_double4(p0x.lo, p0y.lo, p0z.lo, p1x.lo, p1y.lo, p1z.lo, p2x.lo, p2y.lo, p2z.lo, r, &ok_lo);
    const float4 t_hi = plane_t_double4(p0x.hi, p0y.hi, p0z.hi, p1x.hi, p1y.hi, p1z.hi, p2x.hi, p2y.hi, p2z.hi, r, &ok_hi);
    *ok = (int8)(ok_lo, ok_hi);
    return (float8)(t_lo, t_hi);
}
#endif
#endif

/* Watertight test of WN triangles (one packet): intersect_triangle (cl/accel/intersect.h) per lane,
 * with the same arithmetic in the same order, so each lane gives the scalar test's result bit for
 * bit (tests/accel/test_bvh_wide.py compares every layout with the binary one):
 *  - FP_CONTRACT is off (common.h): the edge function of a shared edge must be the exact
 *    negation in both triangles, which a fused multiply-add would break.
 *  - An edge function that rounds to exactly 0 is recomputed in double precision (where the
 *    device has fp64), per lane: only the lanes with a zero take the double results, and the
 *    double path runs only when some lane needs it.
 *  - t comes from the plane equation n.(v0 - o) / n.d with n = (v1 - v0) x (v2 - v0), not from
 *    the paper's T = U*Az + V*Bz + W*Cz, which cancels catastrophically on long slivers (its sign
 *    flipped and rays left thin closed meshes from inside; tests/accel/test_traversal.py).  The plane
 *    equation is evaluated in the original x, y, z order, as dot() and cross() do; slivers and a
 *    numerator whose sign is in doubt take t in double, per lane, as intersect_triangle does
 *    (SLIVER_CANCELLATION and NUM_DOUBT there).
 *  - Padding lanes have NaN vertices: U, V, W and det are NaN, and "det != 0" is written as
 *    det < 0 || det > 0, which is false for NaN, so they are rejected with the lanes the sign
 *    test rejects (and NaN == 0 is false: no double path; t > tmin && t < tmax would reject
 *    them too).  A packet whose lanes are all rejected there returns before the plane
 *    equation, the common case.
 * Returns the hit mask; *t_out, *U_out, *V_out, *W_out hold the lanes' values. */
RT_INLINE WINT WN_(intersect_tri)(__global const WFLOAT *pk, const WideRay *r, float tmin, float tmax,
                                  WFLOAT *t_out, WFLOAT *U_out, WFLOAT *V_out, WFLOAT *W_out)
{
    /* vertices relative to the origin, axes permuted to (kx, ky, kz): packet row 3 * vertex + k */
    const WFLOAT Ax = pk[r->kx] - r->okx, Ay = pk[r->ky] - r->oky, Az = pk[r->kz] - r->okz;
    const WFLOAT Bx = pk[3 + r->kx] - r->okx, By = pk[3 + r->ky] - r->oky, Bz = pk[3 + r->kz] - r->okz;
    const WFLOAT Cx = pk[6 + r->kx] - r->okx, Cy = pk[6 + r->ky] - r->oky, Cz = pk[6 + r->kz] - r->okz;
    SHEARED_EDGES(WFLOAT, Ax, Ay, Az, Bx, By, Bz, Cx, Cy, Cz, r->sx, r->sy);
#ifdef cl_khr_fp64
    const WINT zero = (U == 0.0f) | (V == 0.0f) | (W == 0.0f);
    if (WANY(zero)) {
        U = SEL(U, WN_(edge_double_w)(cx, by, cy, bx), zero);
        V = SEL(V, WN_(edge_double_w)(ax, cy, ay, cx), zero);
        W = SEL(W, WN_(edge_double_w)(bx, ay, by, ax), zero);
    }
#endif
    const WINT mixed = ((U < 0.0f) | (V < 0.0f) | (W < 0.0f)) & ((U > 0.0f) | (V > 0.0f) | (W > 0.0f));
    const WFLOAT det = U + V + W;
    const WINT inside = ~mixed & ((det < 0.0f) | (det > 0.0f)); /* det != 0, and false for NaN */
    if (!WANY(inside)) /* the common case: the ray passes outside all of them */
        return inside;
    /* plane equation, original axis order: n = (p1 - p0) x (p2 - p0), a = p0 - o */
    const WFLOAT p0x = pk[0], p0y = pk[1], p0z = pk[2];
    WFLOAT nx, ny, nz, nabs_x, nabs_y, nabs_z;
    const WINT sliver = WN_(tri_plane)(pk, &nx, &ny, &nz, &nabs_x, &nabs_y, &nabs_z);
    const WFLOAT den = nx * r->d.x + ny * r->d.y + nz * r->d.z;
    const WFLOAT ax0 = p0x - r->o.x, ay0 = p0y - r->o.y, az0 = p0z - r->o.z;
    const WFLOAT num = nx * ax0 + ny * ay0 + nz * az0;
    const WINT doubt = WABS(num) <= NUM_DOUBT * (nabs_x * WABS(ax0) + nabs_y * WABS(ay0) + nabs_z * WABS(az0));
    WFLOAT tt = num / den;
    WINT ok = den != 0.0f;
#ifdef cl_khr_fp64
    const WINT refine = inside & (sliver | doubt);
    if (WANY(refine)) {
        WINT dok;
        tt = SEL(tt, WN_(plane_t_double_w)(pk, r, &dok), refine);
        ok = SEL(ok, dok, refine);
    }
#else
    ok &= ~doubt;
#endif
    *t_out = tt; *U_out = U; *V_out = V; *W_out = W;
    return inside & ok & (tt > tmin) & (tt < tmax);
}

/* The smallest lane (operands never NaN) */
#if WN == 4
RT_INLINE float hmin4(float4 v) { const float2 h2 = VMIN(v.lo, v.hi); return FAST_MIN(h2.x, h2.y); }
#else
RT_INLINE float hmin8(float8 v) { const float4 h4 = VMIN(v.lo, v.hi); const float2 h2 = VMIN(h4.lo, h4.hi); return FAST_MIN(h2.x, h2.y); }
#endif

/* Closest hit of a leaf's packets: the nearest lane of each packet, the lowest lane among equal t
 * (the scalar loop's order: a later triangle replaces a hit only when strictly nearer). */
RT_INLINE void WN_(intersect_leaf)(__global const WFLOAT *pk, int count, const WideRay *r, float tmin, Hit *hit)
{
    for (int p = 0; p < count; ++p, pk += WUNITS) {
        WFLOAT t, U, V, W;
        const WINT m = WN_(intersect_tri)(pk, r, tmin, hit->t, &t, &U, &V, &W);
        if (!WANY(m))
            continue;
        const WFLOAT tm = SEL((WFLOAT)(INFINITY), t, m);
        const float best = WN_(hmin)(tm);
        const int k = lowest_bit(WN_(mask_bits)(tm == (WFLOAT)(best)));
        const float u = WN_(lane)(U, k), v = WN_(lane)(V, k), w = WN_(lane)(W, k);
        const float rcp = 1.0f / (u + v + w);
        hit->t = best;
        hit->u = v * rcp;
        hit->v = w * rcp;
        hit->prim = ((__global const int *)(pk + 9))[k];
    }
}

RT_INLINE int WN_(occluded_leaf)(__global const WFLOAT *pk, int count, const WideRay *r, float tmin, float tmax)
{
    for (int p = 0; p < count; ++p, pk += WUNITS) {
        WFLOAT t, U, V, W;
        if (WANY(WN_(intersect_tri)(pk, r, tmin, tmax, &t, &U, &V, &W)))
            return 1;
    }
    return 0;
}

/* One compare-exchange stage of a sorting network on (key, lane id) pairs: each lane has a partner
 * (pk, pl are the keys and ids permuted accordingly); lanes flagged in `lower` keep the smaller
 * key of their pair, the others the larger.  Both lanes of a pair take the same decision (swap iff
 * the upper key is strictly smaller), so the ids stay a permutation. */
RT_INLINE void WN_(sort_stage)(WFLOAT *k, WINT *l, WFLOAT pk, WINT pl, WINT lower)
{
    const WINT swap = SEL(*k < pk, pk < *k, lower);
    *k = SEL(*k, pk, swap);
    *l = SEL(*l, pl, swap);
}

#if WN == 4
#define WIDE_LANE_IDS ((int4)(0, 1, 2, 3))
/* Sorts keys ascending with their lane ids: the network (0,1)(2,3), (0,2)(1,3), (1,2). */
RT_INLINE void sort4(float4 *k, int4 *l)
{
    sort_stage4(k, l, (*k).s1032, (*l).s1032, (int4)(-1, 0, -1, 0));
    sort_stage4(k, l, (*k).s2301, (*l).s2301, (int4)(-1, -1, 0, 0));
    sort_stage4(k, l, (*k).s0213, (*l).s0213, (int4)(0, -1, 0, 0));
}
#else
#define WIDE_LANE_IDS ((int8)(0, 1, 2, 3, 4, 5, 6, 7))
/* Sorts eight keys ascending with their lane ids: Batcher's bitonic network, six stages, each lane
 * exchanging with lane i ^ 1, i ^ 2 or i ^ 4; `lower` marks the lanes keeping the smaller key. */
RT_INLINE void sort8(float8 *k, int8 *l)
{
    sort_stage8(k, l, (*k).s10325476, (*l).s10325476, (int8)(-1, 0, 0, -1, -1, 0, 0, -1));
    sort_stage8(k, l, (*k).s23016745, (*l).s23016745, (int8)(-1, -1, 0, 0, 0, 0, -1, -1));
    sort_stage8(k, l, (*k).s10325476, (*l).s10325476, (int8)(-1, 0, -1, 0, 0, -1, 0, -1));
    sort_stage8(k, l, (*k).s45670123, (*l).s45670123, (int8)(-1, -1, -1, -1, 0, 0, 0, 0));
    sort_stage8(k, l, (*k).s23016745, (*l).s23016745, (int8)(-1, -1, 0, 0, -1, -1, 0, 0));
    sort_stage8(k, l, (*k).s10325476, (*l).s10325476, (int8)(-1, 0, -1, 0, -1, 0, -1, 0));
}
#endif

/* The node or leaf of a stack code (bvh_wide.h): *cnt 0 and the node's offset, or a leaf's packets */
RT_INLINE void WN_(wide_decode)(__global const WFLOAT *base, int code, int *off, int *cnt)
{
    if (code >= 0) { *off = code; *cnt = 0; return; }
    const int ref = -1 - code;
    __global const WFLOAT *parent = base + (ref & ~7);
    *off = ((__global const int *)(parent + 6))[ref & 7];
    *cnt = ((__global const int *)(parent + 7))[ref & 7];
}

/* The node at off: the hit mask of its children (entry distances in *enter) and its child and
 * count slots */
RT_INLINE WINT WN_(wide_node)(__global const WFLOAT *base, int off, const WideRay *r, float tmin, float tmax,
                              WFLOAT *enter, __global const int **child, __global const int **count)
{
    __global const WFLOAT *node = base + off;
    *child = (__global const int *)(node + 6);
    *count = (__global const int *)(node + 7);
    return WN_(intersect_children)(node, r, tmin, tmax, enter);
}

/* The traversal of the subtree at (off, cnt) (a node: cnt 0; a leaf: cnt packets) in (tmin, tmax),
 * once for both queries (any_hit is a constant where it is inlined, so each query compiles to its
 * own loop):
 *  - closest hit (any_hit 0), closer than hit->t: the hit children of a node nearest entry first
 *    (two compared directly, more through the sorting network), the others pushed far to near with
 *    their entry distances, and a popped entry skipped when it was entered beyond the closest hit
 *    found since; returns 0 (the hit is *hit).
 *  - any hit (any_hit 1): children in slot order; returns 1 as soon as one triangle is hit, else 0.
 * From the root (0, 0) for bvh_wide_closest_hit4/8 and bvh_wide_any_hit4/8; the packet traversal
 * (bvh_packet.h) calls it for the few rays that enter a subtree. */
RT_INLINE int WN_(wide_traverse)(__global const WFLOAT *base, const WideRay *rp, float tmin, float tmax, Hit *hitp,
                                 int off, int cnt, const int any_hit)
{
    const WideRay r = *rp;
    Hit hit = *hitp;
    int stack_code[WSTACK];
    float stack_t[WSTACK];
    int sp = 0;
    for (;;) {
        if (cnt == 0) {
            WFLOAT enter;
            __global const int *child, *count;
            const WINT m = WN_(wide_node)(base, off, &r, tmin, any_hit ? tmax : hit.t, &enter, &child, &count);
            int bits = WN_(mask_bits)(m);
            if (bits && any_hit) {
                const int k = lowest_bit(bits);
                for (bits &= bits - 1; bits; bits &= bits - 1)
                    stack_code[sp++] = WIDE_CODE(off, lowest_bit(bits));
                off = child[k]; cnt = count[k];
                continue;
            }
            if (bits) {
                const int k0 = lowest_bit(bits);
                bits &= bits - 1;
                if (bits == 0) { /* one child */
                    off = child[k0]; cnt = count[k0];
                    continue;
                }
                if ((bits & (bits - 1)) == 0) { /* two children: push the farther */
                    const int k1 = lowest_bit(bits);
                    const float t0 = WN_(lane)(enter, k0), t1 = WN_(lane)(enter, k1);
                    const int near = t1 < t0 ? k1 : k0, far = t1 < t0 ? k0 : k1;
                    stack_code[sp] = WIDE_CODE(off, far); stack_t[sp] = FAST_MAX(t0, t1); ++sp;
                    off = child[near]; cnt = count[near];
                    continue;
                }
                WFLOAT key = SEL((WFLOAT)(INFINITY), enter, m); /* misses sort last */
                WINT lane = WIDE_LANE_IDS;
                WN_(sort)(&key, &lane);
                const float *ks = (const float *)&key;
                const int *ls = (const int *)&lane;
                for (int j = bit_count(bits); j >= 1; --j) { /* bits holds n - 1 children: push far to near */
                    stack_code[sp] = WIDE_CODE(off, ls[j]); stack_t[sp] = ks[j]; ++sp;
                }
                off = child[ls[0]]; cnt = count[ls[0]];
                continue;
            }
        } else if (any_hit) {
            if (WN_(occluded_leaf)(base + off, cnt, &r, tmin, tmax)) return 1;
        } else {
            WN_(intersect_leaf)(base + off, cnt, &r, tmin, &hit);
        }
        /* pop (closest hit: skipping entries entered beyond the closest hit found since) */
        for (;;) {
            if (sp == 0) {
                if (!any_hit) *hitp = hit;
                return 0;
            }
            --sp;
            if (any_hit || stack_t[sp] <= hit.t) { WN_(wide_decode)(base, stack_code[sp], &off, &cnt); break; }
        }
    }
}

RT_INLINE void WN_(wide_closest_from)(__global const WFLOAT *base, const WideRay *r, float tmin, Hit *hit, int off,
                                      int cnt)
{
    WN_(wide_traverse)(base, r, tmin, hit->t, hit, off, cnt, 0);
}

RT_INLINE int WN_(wide_any_from)(__global const WFLOAT *base, const WideRay *r, float tmin, float tmax, int off, int cnt)
{
    Hit none; none.t = tmax; none.u = 0.0f; none.v = 0.0f; none.prim = PRIM_MISS;
    return WN_(wide_traverse)(base, r, tmin, tmax, &none, off, cnt, 1);
}

/* Closest hit in (tmin, tmax) from the root (hit.prim = PRIM_MISS when nothing is hit) and any hit:
 * bvh_closest_hit / bvh_any_hit of this layout (traverse.h). */
RT_INLINE Hit WN_(bvh_wide_closest_hit)(__global const void *bvh, __global const float4 *tris, float3 o, float3 d,
                                        float tmin, float tmax)
{
    Hit hit; hit.t = tmax; hit.u = 0.0f; hit.v = 0.0f; hit.prim = PRIM_MISS;
    const WideRay r = wide_ray(o, d);
    WN_(wide_closest_from)((__global const WFLOAT *)bvh, &r, tmin, &hit, 0, 0); /* from the root */
    return hit;
}

RT_INLINE int WN_(bvh_wide_any_hit)(__global const void *bvh, __global const float4 *tris, float3 o, float3 d,
                                    float tmin, float tmax)
{
    const WideRay r = wide_ray(o, d);
    return WN_(wide_any_from)((__global const WFLOAT *)bvh, &r, tmin, tmax, 0, 0); /* from the root */
}

#undef WFLOAT
#undef WINT
#undef WSTACK
#undef WUNITS
#undef WANY
#undef WABS
#undef WIDE_LANE_IDS
