/* sin, cos, atan2, acos, exp and log over lanes, inline (included by cl/render/lanes.h, which declares the
 * lane types): the same additions, products and selects at every width, so each lane computes the
 * bits the width-1 build computes, and a vector never becomes PACKET_WIDTH calls of PoCL's scalar
 * library (out of line, with its own argument reduction: in the textured scene under the sky
 * 40% of the lane kernel's time went to _cl_atan2, _cl_sin, _cl_cos and acos, for the environment
 * map's direction <-> (u, v) maps; docs/BENCHMARKS.md, issue 23).
 *
 * Polynomials of SLEEF's single-precision functions of 3.5-ulp class (sincosf_u35, atan2f_u35,
 * asinf_u35), without fused multiply-adds (FP_CONTRACT is off): over [-20, 20] (sin, cos),
 * directions of the unit sphere (atan2) and [-1, 1] (acos) within 1.9, 2.6 and 1.3 ulp of the
 * double-precision value (8.8e-8, 3.1e-7 and 3.0e-7 absolute; tests/render/test_lanes_math.py).
 * sin and cos reduce by pi/2 in three parts of which the first two have 12 significant bits
 * (exact products for |x| < 4096 * pi/2); lanes beyond 4096 (and infinities) call the library. */
#ifndef PYOPENCL_RT_LANES_MATH_H
#define PYOPENCL_RT_LANES_MATH_H

/* the lane types (lanes.h includes this file once they are declared) */
#include "render/lanes.h"

#define LM_PIO2_A 1.57080078125f
#define LM_PIO2_B (-4.453584551811218e-06f)
#define LM_PIO2_C (-8.705516307827565e-10f)
#define LM_PIO2_F 1.57079632679489661923f
#define LM_PI_F 3.14159265358979323846f
#define LM_SIGN PUINT(0x80000000u)

/* sin(x) and cos(x) of one reduction: x = q pi/2 + r, |r| <= pi/4, the quadrant q picks and
 * signs the two polynomials */
RT_INLINE void psincos(pfloat x, pfloat *sin_x, pfloat *cos_x)
{
    const pfloat q = (x * 0.636619772367581343076f + 12582912.0f) - 12582912.0f; /* rint(x 2/pi), |x| < 2^22 */
    const pint qi = convert_pint(q);
    pfloat r = x - q * LM_PIO2_A;
    r = r - q * LM_PIO2_B;
    r = r - q * LM_PIO2_C;
    const pfloat s = r * r;
    pfloat u = PFLOAT(-0.000195169282960705459117889f);
    u = u * s + 0.00833215750753879547119141f;
    u = u * s + -0.166666537523269653320312f;
    const pfloat sn = r + (u * s) * r;
    u = PFLOAT(-2.71811842367242206819355e-07f);
    u = u * s + 2.47990446951007470488548e-05f;
    u = u * s + -0.00138888787478208541870117f;
    u = u * s + 0.0416666641831398010253906f;
    u = u * s + -0.5f;
    const pfloat cs = u * s + 1.0f;
    const pint odd = (qi & 1) != 0;
    pfloat sv = odd ? cs : sn, cv = odd ? sn : cs;
    sv = ((qi & 2) != 0) ? -sv : sv;
    cv = (((qi + 1) & 2) != 0) ? -cv : cv;
    /* beyond the reduction's range (and NaN: |q| < 4096 below) the library's sincos: one call for
     * both, as a compiler may fuse a sin and a cos of the same argument into a sincos of other bits
     * (Intel's does where both are used), so psin alone gives psincos's sine */
    const pint big = pnot(pabs(x) <= 6433.0f);
#if PACKET_WIDTH == 1
    if (big) { float c; sv = sincos(x, &c); cv = c; }
#else
    if (pany(big))
        for (int k = 0; k < PACKET_WIDTH; ++k)
            if (PLANE_I(big, k)) { float c; PLANE(sv, k) = sincos(PLANE(x, k), &c); PLANE(cv, k) = c; }
#endif
    *sin_x = sv;
    *cos_x = cv;
}

RT_INLINE pfloat psin(pfloat x) { pfloat s, c; psincos(x, &s, &c); return s; }
RT_INLINE pfloat pcos(pfloat x) { pfloat s, c; psincos(x, &s, &c); return c; }

/* atan2(y, x), IEEE signs of zeros (atan2(+-0, -0) = +-pi); atan of min/max(|x|, |y|) in [0, 1] */
RT_INLINE pfloat patan2(pfloat y, pfloat x)
{
    const pfloat ax = pabs(x), ay = pabs(y);
    const pint swap = ay > ax;
    const pfloat num = swap ? ax : ay, den = swap ? ay : ax;
    pfloat s = num / (den == 0.0f ? PFLOAT(1.0f) : den); /* 0 / 0: 0 */
    const pfloat t = s * s;
    pfloat u = PFLOAT(0.00282363896258175373077393f);
    u = u * t + -0.0159569028764963150024414f;
    u = u * t + 0.0425049886107444763183594f;
    u = u * t + -0.0748900920152664184570312f;
    u = u * t + 0.106347933411598205566406f;
    u = u * t + -0.142027363181114196777344f;
    u = u * t + 0.199926957488059997558594f;
    u = u * t + -0.333331018686294555664062f;
    pfloat r = (u * t) * s + s;
    r = swap ? LM_PIO2_F - r : r;
    r = (as_pint(x) < 0) ? LM_PI_F - r : r; /* x's sign bit */
    return as_pfloat(as_puint(r) ^ (as_puint(y) & LM_SIGN));
}

/* acos(x) for x in [-1, 1]: pi/2 -+ asin(|x|) below 1/2, else 2 asin(sqrt((1 - |x|) / 2)) (pi
 * minus it for x < 0) */
RT_INLINE pfloat pacos(pfloat x)
{
    const pfloat ax = pabs(x);
    const pint small = ax < 0.5f;
    const pfloat x2 = small ? x * x : (1.0f - ax) * 0.5f;
    const pfloat a = small ? ax : psqrt(x2);
    pfloat u = PFLOAT(0.4197454825e-1f);
    u = u * x2 + 0.2424046025e-1f;
    u = u * x2 + 0.4547423869e-1f;
    u = u * x2 + 0.7495029271e-1f;
    u = u * x2 + 0.1666677296e+0f;
    const pfloat asin_a = (u * x2) * a + a;
    const pint neg = as_pint(x) < 0;
    const pfloat r_small = neg ? LM_PIO2_F + asin_a : LM_PIO2_F - asin_a;
    const pfloat r_large = neg ? LM_PI_F - 2.0f * asin_a : 2.0f * asin_a;
    return small ? r_small : r_large;
}

/* ln 2 in two parts, the first of 15 significant bits: its products with integers below 2^8 are exact */
#define LM_LN2_A 0.693145751953125f
#define LM_LN2_B 1.428606765330187e-06f

/* e^x (the media's transmittance, the Beckmann distribution): x = n ln2 + r, |r| <= ln2 / 2, e^r by
 * its Taylor polynomial of degree 7 (the remainder below 0.15 ulp), times 2^n in two factors of
 * 2^(n/2), so that results in the denormals are rounded once; x clamped to [-104, 89] first,
 * beyond which the result is 0 or +inf anyway (the factors underflow or overflow). */
RT_INLINE pfloat pexp(pfloat x)
{
    const pfloat xc = pfmin(pfmax(x, PFLOAT(-104.0f)), PFLOAT(89.0f));
    const pfloat q = (xc * 1.44269504088896341f + 12582912.0f) - 12582912.0f; /* rint(x / ln2) */
    const pint n = convert_pint(q);
    pfloat r = xc - q * LM_LN2_A;
    r = r - q * LM_LN2_B;
    pfloat p = PFLOAT(1.0f / 5040.0f);
    p = p * r + (1.0f / 720.0f);
    p = p * r + (1.0f / 120.0f);
    p = p * r + (1.0f / 24.0f);
    p = p * r + (1.0f / 6.0f);
    p = p * r + 0.5f;
    p = p * r + 1.0f;
    p = p * r + 1.0f;
    const pint n1 = n >> 1, n2 = n - n1; /* each in [-75, 64]: a normal power of two */
    const pfloat e = (p * as_pfloat((n1 + 127) << 23)) * as_pfloat((n2 + 127) << 23);
    return x != x ? x : e; /* NaN stays NaN */
}

/* log(x) (free-flight distances, the Beckmann sampler's erfinv): x = 2^e m, m in [sqrt(1/2),
 * sqrt(2)), log m = 2 atanh(f) with f = (m - 1) / (m + 1), |f| < 0.172, by its series up to f^9
 * (the remainder below 0.05 ulp), plus e ln2 in two parts; denormals scaled by 2^23 first.
 * log(0) = -inf, log(x < 0) = NaN, log(+inf) = +inf. */
RT_INLINE pfloat plog(pfloat x)
{
    const pint tiny = x < 1.17549435e-38f;
    const pint bits = as_pint(tiny ? x * 8388608.0f : x);
    pint e = ((bits >> 23) & 0xff) - (tiny ? 150 : 127);
    pfloat m = as_pfloat((bits & 0x007fffff) | 0x3f800000);
    const pint high = m > 1.41421356f;
    m = high ? m * 0.5f : m;
    e = high ? e + 1 : e;
    const pfloat f = (m - 1.0f) / (m + 1.0f), f2 = f * f;
    pfloat s = PFLOAT(1.0f / 9.0f);
    s = s * f2 + (1.0f / 7.0f);
    s = s * f2 + 0.2f;
    s = s * f2 + (1.0f / 3.0f);
    const pfloat lm = 2.0f * f + (2.0f * f) * (f2 * s);
    const pfloat ef = convert_pfloat(e);
    pfloat r = ef * LM_LN2_A + (ef * LM_LN2_B + lm);
    r = x == 0.0f ? PFLOAT(-INFINITY) : r;
    r = x < 0.0f ? PFLOAT(NAN) : r;
    r = x == INFINITY ? x : r;
    return x != x ? x : r;
}

#endif
