/* Lanes: PACKET_WIDTH values of one kind (one per path) side by side, and the arithmetic the
 * integrator (cl/render/path.h), the materials, lights and samplers, and the packet traversal
 * (cl/accel/bvh_packet.h) do on them.  Portable OpenCL C: x86 builtins only where the compile's
 * macros (__AVX2__, __AVX512F__, ...) say they exist, each beside a portable spelling that any
 * OpenCL C compiler with vector types builds (Intel's CPU runtime defines none of those macros).  The integrator is written once over these types, as
 * Mitsuba 3 writes its integrators over DrJit arrays: PACKET_WIDTH 1 (the default: GPUs, the
 * wavefront stages, the one-path megakernel) makes them float, int and uint; 8 or 16 (x86 CPUs
 * under PoCL, pyopencl_rt/device/isa.py picks the width) makes them OpenCL vectors.
 *
 * Masks (pint): what comparisons give.  At width 1 that is 0 or 1, in vectors 0 or -1 per lane;
 * combine them with & and | and negate them with pnot() (never ~: ~1 is not false), test them
 * with pany(), and select with `m ? b : a` (psel, pv3_sel).  PTRUE is an all-true mask.
 *
 * Every function here gives, lane by lane, the bits the width-1 code gives for that lane with
 * cpu_builtins.h's builtins (sqrt correctly rounded; fmin/fmax as minnum/maxnum, so NaN operands
 * behave alike; dot, cross, length and normalize as defined, products summed left to right;
 * length and normalize of a lane whose squared length could over- or underflow fall back to the
 * scalar function, which rescales), so every width renders the same image.  sin, cos, atan2,
 * acos, exp and log are inline polynomials (render/lanes_math.h); library functions with no
 * inline form (pow, erf) are called lane by lane (PLIB1): a vector of 32 bytes or more never
 * crosses into PoCL's built-in library (issue 22).  FP_CONTRACT is off (common.h). */
#ifndef PYOPENCL_RT_LANES_H
#define PYOPENCL_RT_LANES_H

#include "common.h"

#ifndef PACKET_WIDTH
#define PACKET_WIDTH 1
#endif
/* mask_bits8 (vmovmskps) and any8, the 8-wide traversal's mask helpers, serve the lanes too (the
 * host expands each header once, where it first appears, whatever #if surrounds it: no header is
 * included under a condition) */
#include "accel/masks.h"
/* clang's element-wise builtins compile to one instruction (an LLVM intrinsic); elsewhere the
 * OpenCL built-ins of the same definition stand in (minnum/maxnum, floor, a vector conversion). */
#if defined(__has_builtin)
#if __has_builtin(__builtin_elementwise_minnum) && __has_builtin(__builtin_elementwise_floor)
#define RT_ELEMENTWISE 1 /* clang 21 on: min/max of floats are minnum/maxnum by name */
#define RT_EW_MIN __builtin_elementwise_minnum
#define RT_EW_MAX __builtin_elementwise_maxnum
#elif __has_builtin(__builtin_elementwise_min) && __has_builtin(__builtin_elementwise_floor)
#define RT_ELEMENTWISE 1
#define RT_EW_MIN __builtin_elementwise_min
#define RT_EW_MAX __builtin_elementwise_max
#endif
#if __has_builtin(__builtin_convertvector)
#define RT_CONVERTVECTOR 1
#endif
#if __has_builtin(__builtin_sqrtf)
#define RT_SQRTF __builtin_sqrtf
#endif
#endif
#ifndef RT_SQRTF
#define RT_SQRTF sqrt
#endif

#if PACKET_WIDTH == 1
typedef float pfloat;
typedef int pint;
typedef uint puint;
#define PFLOAT(x) ((float)(x))
#define PINT(x) ((int)(x))
#define PUINT(x) ((uint)(x))
#define as_pfloat as_float
#define as_pint as_int
#define as_puint as_uint
#define convert_pfloat(x) ((float)(x))
#define convert_pint(x) ((int)(x))
#define convert_puint(x) ((uint)(x))
#define LANE_IDS 0
#elif PACKET_WIDTH == 16
typedef float16 pfloat;
typedef int16 pint;
typedef uint16 puint;
#define PFLOAT(x) ((float16)(x))
#define PINT(x) ((int16)(x))
#define PUINT(x) ((uint16)(x))
#define as_pfloat as_float16
#define as_pint as_int16
#define as_puint as_uint16
#define convert_pfloat convert_float16
#define convert_pint convert_int16
#define convert_puint convert_uint16
#define LANE_IDS ((int16)(0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15))
#elif PACKET_WIDTH == 8
typedef float8 pfloat;
typedef int8 pint;
typedef uint8 puint;
#define PFLOAT(x) ((float8)(x))
#define PINT(x) ((int8)(x))
#define PUINT(x) ((uint8)(x))
#define as_pfloat as_float8
#define as_pint as_int8
#define as_puint as_uint8
#define convert_pfloat convert_float8
#define convert_pint convert_int8
#define convert_puint convert_uint8
#define LANE_IDS ((int8)(0, 1, 2, 3, 4, 5, 6, 7))
#else
#error "PACKET_WIDTH must be 1, 8 or 16"
#endif

/* On a kernel that runs PACKET_WIDTH paths per work-item: the OpenCL C hint that it works on
 * vectors already, so Intel's CPU runtime does not also pack work-items into SIMD lanes (its
 * implicit vectoriser made a 16-lane megakernel 16 x 16 wide: builds of minutes, 256k
 * instructions); other compilers ignore it. */
#if PACKET_WIDTH == 16
#define LANE_KERNEL __attribute__((vec_type_hint(float16)))
#elif PACKET_WIDTH == 8
#define LANE_KERNEL __attribute__((vec_type_hint(float8)))
#else
#define LANE_KERNEL
#endif

/* lane k of a vector (in memory: used to gather and scatter one lane at a time) */
#define PLANE(v, k) (((float *)&(v))[k])
#define PLANE_I(v, k) (((int *)&(v))[k])
#define PLANE_U(v, k) (((uint *)&(v))[k])

/* the mask of the lanes set in bits (bit k: lane k), and back; with AVX-512 one instruction
 * each (vpmovm2d, vpmovd2m), which also lets a comparison's mask register be tested directly
 * instead of being widened to a vector and reduced with shuffles (pany) */
#if PACKET_WIDTH == 1
RT_INLINE pint pmask(int bits) { return bits & 1; }
RT_INLINE int pbits(pint m) { return m != 0; }
RT_INLINE int pany(pint m) { return m != 0; }
RT_INLINE pint pnot(pint m) { return !m; }
#elif PACKET_WIDTH == 16 && defined(__AVX512DQ__)
RT_INLINE pint pmask(int bits) { return __builtin_ia32_cvtmask2d512((ushort)bits); }
RT_INLINE int pbits(pint m) { return __builtin_ia32_cvtd2mask512(m); }
RT_INLINE int pany(pint m) { return pbits(m) != 0; }
#else
RT_INLINE pint pmask(int bits) { return -((PINT(bits) >> LANE_IDS) & 1); }
#if PACKET_WIDTH == 16
RT_INLINE int pbits(pint m) { return mask_bits8(m.lo) | (mask_bits8(m.hi) << 8); }
RT_INLINE int pany(pint m) { return any8(m.lo | m.hi); }
#else
RT_INLINE int pbits(pint m) { return mask_bits8(m); }
RT_INLINE int pany(pint m) { return any8(m); }
#endif
#endif
#if PACKET_WIDTH > 1
RT_INLINE pint pnot(pint m) { return ~m; }
#endif
#define PTRUE PINT(-1)
/* every lane of m set (of the lanes in `of`) */
RT_INLINE int pall(pint m) { return !pany(pnot(m)); }

/* base[index[k]] in lane k (every index valid): an AVX-512 gather, else lane by lane.  The
 * structure fields the lanes read are gathered this way (FIELD_INDEX: a field's index in floats).
 * AVX2's vgatherdps in place of the 8 loads made a cold build a quarter shorter at the same speed,
 * but under `qemu-x86_64 -cpu Haswell` (make isa-check) the 8-lane film then differs from one
 * path's, so it is not used (docs/BENCHMARKS.md, "Kernel builds"). */
#define FIELD_INDEX(type, field) ((int)(__builtin_offsetof(type, field) / 4))
#define STRIDE_INDEX(type) ((int)(sizeof(type) / 4))
RT_INLINE pfloat pgather(__global const float *base, pint index)
{
#if PACKET_WIDTH == 1
    return base[index];
#elif PACKET_WIDTH == 16 && defined(__AVX512F__)
    return __builtin_ia32_gathersiv16sf(PFLOAT(0.0f), base, index, (ushort)0xffff, 4);
#else
    pfloat r;
    for (int k = 0; k < PACKET_WIDTH; ++k) PLANE(r, k) = base[PLANE_I(index, k)];
    return r;
#endif
}

/* the same for ints (the loads move bits only) */
RT_INLINE pint pgather_int(__global const int *base, pint index) { return as_pint(pgather((__global const float *)base, index)); }

#if PACKET_WIDTH > 1 /* the packet traversal's (cl/accel/bvh_packet.h) and the megakernel's */
/* v[index[k]] in lane k (index < PACKET_WIDTH): one vpermps / vpermd where the lanes are one register
 * (16 with AVX-512, 8 with AVX2: PERMUTE_IN_REGISTER), else lane by lane */
#if (PACKET_WIDTH == 16 && defined(__AVX512F__)) || (PACKET_WIDTH == 8 && defined(__AVX2__))
#define PERMUTE_IN_REGISTER 1
#else
#define PERMUTE_IN_REGISTER 0
#endif
RT_INLINE pfloat ppermute(pfloat v, pint index)
{
#if PACKET_WIDTH == 16 && defined(__AVX512F__)
    return __builtin_ia32_permvarsf512(v, index);
#elif PACKET_WIDTH == 8 && defined(__AVX2__)
    return __builtin_ia32_permvarsf256(v, index);
#else
    pfloat r;
    for (int k = 0; k < PACKET_WIDTH; ++k) PLANE(r, k) = PLANE(v, PLANE_I(index, k) & (PACKET_WIDTH - 1));
    return r;
#endif
}

RT_INLINE pint ppermute_int(pint v, pint index) { return as_pint(ppermute(as_pfloat(v), index)); }

/* the indices of the bits set in `bits`, ascending, packed into the first lanes (0 after them):
 * vpcompressd with AVX-512 */
RT_INLINE pint pcompress_ids(int bits)
{
#if PACKET_WIDTH == 16 && defined(__AVX512F__)
    return __builtin_ia32_compresssi512_mask(LANE_IDS, PINT(0), (ushort)bits);
#else
    pint r = PINT(0);
    for (int k = 0; bits; bits &= bits - 1) PLANE_I(r, k++) = lowest_bit(bits);
    return r;
#endif
}

#else /* one lane: index is 0 (the megakernel's ready samples, cl/megakernel/path.cl) */
RT_INLINE pfloat ppermute(pfloat v, pint index) { return v; }
RT_INLINE pint ppermute_int(pint v, pint index) { return v; }
#endif

RT_INLINE pfloat pabs(pfloat x) { return as_pfloat(as_puint(x) & PUINT(0x7fffffffu)); }
#if PACKET_WIDTH == 1
RT_INLINE pfloat pfmin(pfloat a, pfloat b) { return fmin(a, b); }
RT_INLINE pfloat pfmax(pfloat a, pfloat b) { return fmax(a, b); }
#elif defined(RT_ELEMENTWISE)
RT_INLINE pfloat pfmin(pfloat a, pfloat b) { return RT_EW_MIN(a, b); }
RT_INLINE pfloat pfmax(pfloat a, pfloat b) { return RT_EW_MAX(a, b); }
#else
RT_INLINE pfloat pfmin(pfloat a, pfloat b) { return fmin(a, b); }
RT_INLINE pfloat pfmax(pfloat a, pfloat b) { return fmax(a, b); }
#endif
RT_INLINE pfloat pclamp(pfloat x, float lo, float hi) { return pfmin(pfmax(x, PFLOAT(lo)), PFLOAT(hi)); }
RT_INLINE pfloat pcopysign(pfloat x, pfloat y)
{
    return as_pfloat((as_puint(x) & PUINT(0x7fffffffu)) | (as_puint(y) & PUINT(0x80000000u)));
}
RT_INLINE pint pisinf(pfloat x) { return (as_puint(x) & PUINT(0x7fffffffu)) == PUINT(0x7f800000u); }

/* sqrt, correctly rounded (as sqrtss) */
RT_INLINE pfloat psqrt(pfloat x)
{
#if PACKET_WIDTH == 1
    return sqrt(x);
#elif PACKET_WIDTH == 16 && defined(__AVX512F__)
    return __builtin_ia32_sqrtps512(x, 4); /* _MM_FROUND_CUR_DIRECTION */
#elif defined(__AVX__)
#if PACKET_WIDTH == 16
    return (pfloat)(__builtin_ia32_sqrtps256(x.lo), __builtin_ia32_sqrtps256(x.hi));
#else
    return __builtin_ia32_sqrtps256(x);
#endif
#else
    pfloat r;
    for (int k = 0; k < PACKET_WIDTH; ++k) PLANE(r, k) = RT_SQRTF(PLANE(x, k));
    return r;
#endif
}

/* f(x) of a library function with no inline form, lane by lane (see the top) */
#if PACKET_WIDTH == 1
#define PLIB1(f, x) f(x)
#define PLIB2(f, x, y) f(x, y)
#else
/* the loop kept scalar: a compiler that vectorises it (Intel's, with its vector library) may
 * give some call sites other bits than the scalar function, and than one path per work-item */
#define PLIB1(f, x) ({ const pfloat x_ = (x); pfloat r_; _Pragma("clang loop vectorize(disable) interleave(disable)") for (int k_ = 0; k_ < PACKET_WIDTH; ++k_) PLANE(r_, k_) = f(PLANE(x_, k_)); r_; })
#define PLIB2(f, x, y) ({ const pfloat x_ = (x), y_ = (y); pfloat r_; _Pragma("clang loop vectorize(disable) interleave(disable)") for (int k_ = 0; k_ < PACKET_WIDTH; ++k_) PLANE(r_, k_) = f(PLANE(x_, k_), PLANE(y_, k_)); r_; })
#endif
/* psin, pcos, psincos, patan2, pacos, pexp, plog: inline polynomials, the same at every width */
#include "render/lanes_math.h"
#if PACKET_WIDTH == 1
RT_INLINE pfloat pfloor(pfloat x) { return floor(x); }
#elif defined(RT_ELEMENTWISE) /* exact, and an LLVM intrinsic (vrndscaleps, vroundps), not a call into the built-in library */
RT_INLINE pfloat pfloor(pfloat x) { return __builtin_elementwise_floor(x); }
#else
RT_INLINE pfloat pfloor(pfloat x) { return floor(x); }
#endif
/* erf rounded from double precision where the device has it: the library's float erf may be
 * several ulp off (Intel's CPU runtime: 4; PoCL: 0.7), and the Beckmann sampling's 1 - erf near 1
 * magnifies that into wrong slopes (and NaN at the clamps); from double every implementation
 * gives the correctly rounded value but for rare near-ties */
#ifdef cl_khr_fp64
RT_INLINE float erf_rounded(float x) { return (float)erf((double)x); }
#else
RT_INLINE float erf_rounded(float x) { return erf(x); }
#endif
RT_INLINE pfloat perf(pfloat x) { return PLIB1(erf_rounded, x); }
RT_INLINE pfloat ppow(pfloat x, pfloat y) { return PLIB2(pow, x, y); }
RT_INLINE pint pisfinite(pfloat x) { return (as_puint(x) & PUINT(0x7f800000u)) != PUINT(0x7f800000u); }

/* A 3-vector per lane. */
typedef struct { pfloat x, y, z; } pvec3;

RT_INLINE pvec3 pv3(pfloat x, pfloat y, pfloat z) { pvec3 v; v.x = x; v.y = y; v.z = z; return v; }
RT_INLINE pvec3 pv3_splat(float3 a) { return pv3(PFLOAT(a.x), PFLOAT(a.y), PFLOAT(a.z)); }
RT_INLINE pvec3 pv3_add(pvec3 a, pvec3 b) { return pv3(a.x + b.x, a.y + b.y, a.z + b.z); }
RT_INLINE pvec3 pv3_sub(pvec3 a, pvec3 b) { return pv3(a.x - b.x, a.y - b.y, a.z - b.z); }
RT_INLINE pvec3 pv3_mul(pvec3 a, pvec3 b) { return pv3(a.x * b.x, a.y * b.y, a.z * b.z); }
RT_INLINE pvec3 pv3_scale(pvec3 a, pfloat s) { return pv3(a.x * s, a.y * s, a.z * s); }
RT_INLINE pvec3 pv3_div(pvec3 a, pfloat s) { return pv3(a.x / s, a.y / s, a.z / s); }
RT_INLINE pvec3 pv3_neg(pvec3 a) { return pv3(-a.x, -a.y, -a.z); }
RT_INLINE pvec3 pv3_abs(pvec3 a) { return pv3(pabs(a.x), pabs(a.y), pabs(a.z)); }
/* m ? b : a, per lane */
RT_INLINE pvec3 pv3_sel(pvec3 a, pvec3 b, pint m) { return pv3(m ? b.x : a.x, m ? b.y : a.y, m ? b.z : a.z); }
RT_INLINE pfloat pv3_dot(pvec3 a, pvec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
RT_INLINE pvec3 pv3_cross(pvec3 a, pvec3 b)
{
    return pv3(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
RT_INLINE pfloat pv3_max3(pvec3 v) { return pfmax(v.x, pfmax(v.y, v.z)); }
/* base[index + 0..2] in lane k (a float3 stored as three floats: records, vertices, texels) */
RT_INLINE pvec3 pv3_gather(__global const float *base, pint index)
{
    return pv3(pgather(base, index), pgather(base, index + 1), pgather(base, index + 2));
}
RT_INLINE pvec3 pv3_from(float3 a) { return pv3_splat(a); } /* width 1: the same vector */
RT_INLINE pvec3 pv3_zero(void) { return pv3_splat((float3)(0.0f)); }
RT_INLINE float3 pv3_lane(pvec3 v, int k) { return (float3)(PLANE(v.x, k), PLANE(v.y, k), PLANE(v.z, k)); }
RT_INLINE void pv3_set_lane(pvec3 *v, int k, float3 a) { PLANE(v->x, k) = a.x; PLANE(v->y, k) = a.y; PLANE(v->z, k) = a.z; }

/* length and normalize as cpu_builtins.h computes them: sqrt of the dot product where it cannot
 * over- or underflow, else (rare lanes, only those in `live`) the scalar function. */
#define LANES_LENGTH_SQ_OK(d) (((d) >= RT_LENGTH_SQ_MIN) & ((d) <= RT_LENGTH_SQ_MAX))
RT_INLINE pfloat pv3_length(pvec3 v, pint live)
{
    const pfloat d = pv3_dot(v, v);
    pfloat r = psqrt(d);
    const pint slow = live & pnot(LANES_LENGTH_SQ_OK(d));
    if (pany(slow))
        for (int k = 0; k < PACKET_WIDTH; ++k)
            if (PLANE_I(slow, k)) PLANE(r, k) = length(pv3_lane(v, k));
    return r;
}

RT_INLINE pvec3 pv3_normalize(pvec3 v, pint live)
{
    const pfloat d = pv3_dot(v, v);
    pvec3 r = pv3_div(v, psqrt(d));
    const pint slow = live & pnot(LANES_LENGTH_SQ_OK(d));
    if (pany(slow))
        for (int k = 0; k < PACKET_WIDTH; ++k)
            if (PLANE_I(slow, k)) pv3_set_lane(&r, k, normalize(pv3_lane(v, k)));
    return r;
}

/* nextafter(x, +-infinity) as cpu_builtins.h's rt_nextafter, for up = the lanes going to +inf */
RT_INLINE pfloat pnextafter_inf(pfloat x, pint up)
{
    const pfloat y = up ? PFLOAT(INFINITY) : PFLOAT(-INFINITY);
    const pint away = (x < y) == (x > 0.0f); /* away from zero */
    pfloat r = as_pfloat(as_puint(x) + (away ? PUINT(1u) : PUINT(0xffffffffu)));
    r = x == 0.0f ? as_pfloat((as_puint(y) & PUINT(0x80000000u)) | PUINT(1u)) : r;
    r = x == y ? y : r;
    return x != x ? x + y : r;
}

#endif
