/* Inline versions of the OpenCL builtins the path tracer calls, for PoCL on x86 CPUs.
 *
 * PoCL 3.0 links its builtin library into each kernel as functions compiled for a generic x86 ABI,
 * and LLVM keeps them out of line: every fabs, dot, normalize or nextafter in shading is a call
 * with its arguments spilled to the stack and a vzeroupper (perf on the megakernel: 22% of the
 * time inside _cl_normalize, _cl_nextafter, _cl_dot, _cl_fabs, ... and more in the spills around
 * them).  Here each is spelled with operators or clang builtins that compile to one or a few
 * instructions, and a function-like macro of the builtin's name, defined after them, routes every later call in
 * cl/ to it (PoCL's own headers define these names as macros too; the functions here, written
 * before the redefinition, still reach PoCL's builtin for their slow paths).
 *
 * vload3/vstore3 of floats are plain loads and stores of the three components (the trace kernels'
 * packed origins and directions, materials' colours): perf on trace() found _cl_vload3 at 3.4%.
 *
 * Values: fabs, fmin, fmax, floor, sqrt, copysign, nextafter, isfinite, isinf, select, min, max and
 * clamp return the builtin's value bit for bit (sqrt is correctly rounded in both).  dot, cross,
 * length, normalize, mix and rsqrt are computed as their definitions read (products summed left
 * to right without fused multiply-adds, FP_CONTRACT is off; rsqrt as 1/sqrt, i.e. more accurate
 * than the builtin's 2 ulp); they may differ from PoCL's library in the last bit.  normalize and
 * length fall back to the builtin, which rescales, when the squared length could over- or
 * underflow.
 *
 * Only for clang on x86 (PoCL's CPU device) and clang compiling SPIR (Intel's CPU runtime: its
 * front end defines __SPIR__, not __x86_64__), where the calls were measured and where the packet
 * and wide traversals, which spell dot and cross with operators, must give the scalar code's
 * bits; other GPU compilers inline their builtins already and keep them.  -DRT_PORTABLE_BUILTINS switches it
 * off, to measure it (docs/BENCHMARKS.md) or to rule it out. */
#ifndef PYOPENCL_RT_CPU_BUILTINS_H
#define PYOPENCL_RT_CPU_BUILTINS_H

/* Squared lengths in [2^-100, 2^100] neither overflow nor lose bits to denormals; outside, the
 * builtin (which rescales) decides.  Defined for every compiler: the lanes (render/lanes.h) test
 * the same range on any OpenCL implementation. */
#define RT_LENGTH_SQ_MIN 7.88860905e-31f
#define RT_LENGTH_SQ_MAX 1.26765060e+30f

#if defined(__clang__) && (defined(__x86_64__) || defined(__SPIR__)) && !defined(RT_PORTABLE_BUILTINS)
#define RT_CPU_BUILTINS 1

#define RT_OVL inline __attribute__((always_inline, overloadable))

RT_OVL float rt_fabs(float x) { return as_float(as_uint(x) & 0x7fffffffu); }
RT_OVL float2 rt_fabs(float2 x) { return as_float2(as_uint2(x) & (uint2)(0x7fffffffu)); }
RT_OVL float3 rt_fabs(float3 x) { return as_float3(as_uint3(x) & (uint3)(0x7fffffffu)); }
RT_OVL float4 rt_fabs(float4 x) { return as_float4(as_uint4(x) & (uint4)(0x7fffffffu)); }

RT_OVL float rt_copysign(float x, float y)
{
    return as_float((as_uint(x) & 0x7fffffffu) | (as_uint(y) & 0x80000000u));
}

/* fmin/fmax: LLVM's minnum/maxnum are the C99/OpenCL functions (a NaN operand yields the other). */
RT_OVL float rt_fmin(float a, float b) { return __builtin_fminf(a, b); }
RT_OVL float rt_fmax(float a, float b) { return __builtin_fmaxf(a, b); }
RT_OVL float3 rt_fmin(float3 a, float3 b)
{
    return (float3)(__builtin_fminf(a.x, b.x), __builtin_fminf(a.y, b.y), __builtin_fminf(a.z, b.z));
}
RT_OVL float3 rt_fmax(float3 a, float3 b)
{
    return (float3)(__builtin_fmaxf(a.x, b.x), __builtin_fmaxf(a.y, b.y), __builtin_fmaxf(a.z, b.z));
}
RT_OVL float3 rt_fmin(float3 a, float b) { return rt_fmin(a, (float3)(b)); }
RT_OVL float3 rt_fmax(float3 a, float b) { return rt_fmax(a, (float3)(b)); }

RT_OVL int rt_min(int a, int b) { return a < b ? a : b; }
RT_OVL int rt_max(int a, int b) { return a > b ? a : b; }
RT_OVL uint rt_min(uint a, uint b) { return a < b ? a : b; }
RT_OVL uint rt_max(uint a, uint b) { return a > b ? a : b; }
/* min/max of floats are undefined for NaN in OpenCL; as fmin/fmax here. */
RT_OVL float rt_min(float a, float b) { return __builtin_fminf(a, b); }
RT_OVL float rt_max(float a, float b) { return __builtin_fmaxf(a, b); }

/* clamp(x, lo, hi) = fmin(fmax(x, lo), hi), its definition. */
RT_OVL float rt_clamp(float x, float lo, float hi) { return __builtin_fminf(__builtin_fmaxf(x, lo), hi); }
RT_OVL float3 rt_clamp(float3 x, float lo, float hi) { return rt_fmin(rt_fmax(x, lo), hi); }
RT_OVL float3 rt_clamp(float3 x, float3 lo, float3 hi) { return rt_fmin(rt_fmax(x, lo), hi); }
RT_OVL int rt_clamp(int x, int lo, int hi) { return rt_min(rt_max(x, lo), hi); }

RT_OVL float rt_floor(float x) { return __builtin_floorf(x); }
RT_OVL float2 rt_floor(float2 x) { return (float2)(__builtin_floorf(x.x), __builtin_floorf(x.y)); }

RT_OVL float rt_sqrt(float x) { return __builtin_sqrtf(x); }
RT_OVL float3 rt_sqrt(float3 x) { return (float3)(__builtin_sqrtf(x.x), __builtin_sqrtf(x.y), __builtin_sqrtf(x.z)); }
RT_OVL float rt_rsqrt(float x) { return 1.0f / __builtin_sqrtf(x); }

RT_OVL int rt_isfinite(float x) { return (as_uint(x) & 0x7f800000u) != 0x7f800000u; }
RT_OVL int rt_isinf(float x) { return (as_uint(x) & 0x7fffffffu) == 0x7f800000u; }
RT_OVL int3 rt_isgreater(float3 a, float3 b) { return a > b; }

/* select(a, b, c): b where c is set (scalar: non-zero; vector: the lane's sign bit, which is what
 * OpenCL C's vector ?: tests). */
RT_OVL float rt_select(float a, float b, int c) { return c ? b : a; }
RT_OVL float3 rt_select(float3 a, float3 b, int3 c) { return c ? b : a; }
RT_OVL float8 rt_select(float8 a, float8 b, int8 c) { return c ? b : a; }

/* nextafter toward +-infinity for the finite, non-NaN offsets of spawn.h: one ulp away from or
 * toward zero by the integer representation; zero steps to the smallest denormal of the sign. */
RT_OVL float rt_nextafter(float x, float y)
{
    if (x != x || y != y) return x + y;
    if (x == y) return y;
    if (x == 0.0f) return as_float((as_uint(y) & 0x80000000u) | 1u);
    const int up = (x < y) == (x > 0.0f); /* away from zero */
    return as_float(as_uint(x) + (up ? 1u : 0xffffffffu));
}

/* Geometric functions as defined (OpenCL C 1.2, 6.12.5), products summed left to right. */
RT_OVL float rt_dot(float3 a, float3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
RT_OVL float rt_dot(float2 a, float2 b) { return a.x * b.x + a.y * b.y; }
RT_OVL float rt_dot(float4 a, float4 b) { return a.x * b.x + a.y * b.y + a.z * b.z + a.w * b.w; }
RT_OVL float3 rt_cross(float3 a, float3 b)
{
    return (float3)(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
/* The double-precision fallbacks of intersect.h and spawn.h (devices with fp64). */
#ifdef cl_khr_fp64
RT_OVL double rt_dot(double3 a, double3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
RT_OVL double3 rt_cross(double3 a, double3 b)
{
    return (double3)(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
/* sqrt of the dot product where the square neither overflows nor loses bits to denormals (always,
 * for the cross products of float coordinates spawn.h takes it of), else of the vector scaled by
 * its largest component: no double3 is passed to the library (see the conversions below). */
RT_OVL double rt_length(double3 v)
{
    const double d = rt_dot(v, v);
    if (d >= 0x1.0p-1000 && d <= 0x1.0p1000)
        return __builtin_sqrt(d);
    const double m = __builtin_fmax(__builtin_fmax(__builtin_fabs(v.x), __builtin_fabs(v.y)), __builtin_fabs(v.z));
    if (!(m > 0.0) || m == (double)INFINITY)
        return m;  /* 0, +inf, NaN */
    const double3 u = v / m;
    return m * __builtin_sqrt(rt_dot(u, u));
}
#endif
RT_OVL float rt_length(float3 v)
{
    const float d = rt_dot(v, v);
    return (d >= RT_LENGTH_SQ_MIN && d <= RT_LENGTH_SQ_MAX) ? __builtin_sqrtf(d) : length(v);
}
/* the zero vector is returned as it is, as OpenCL C defines normalize's special case (PoCL does;
 * Intel's CPU runtime gives NaN) */
RT_OVL float3 rt_normalize(float3 v)
{
    const float d = rt_dot(v, v);
    if (d >= RT_LENGTH_SQ_MIN && d <= RT_LENGTH_SQ_MAX) return v / __builtin_sqrtf(d);
    return (v.x == 0.0f && v.y == 0.0f && v.z == 0.0f) ? v : normalize(v);
}

/* mix(a, b, t) = a + (b - a) * t, its definition. */
RT_OVL float3 rt_mix(float3 a, float3 b, float t) { return a + (b - a) * t; }
RT_OVL float4 rt_mix(float4 a, float4 b, float t) { return a + (b - a) * t; }
RT_OVL float rt_mix(float a, float b, float t) { return a + (b - a) * t; }

/* vload3(i, p) reads p[3i], p[3i + 1], p[3i + 2]; vstore3 writes them (OpenCL C 1.2, 6.12.7). */
RT_OVL float3 rt_vload3(size_t i, __global const float *p) { p += 3 * i; return (float3)(p[0], p[1], p[2]); }
RT_OVL float3 rt_vload3(size_t i, __constant float *p) { p += 3 * i; return (float3)(p[0], p[1], p[2]); }
RT_OVL float3 rt_vload3(size_t i, const float *p) { p += 3 * i; return (float3)(p[0], p[1], p[2]); }
RT_OVL void rt_vstore3(float3 v, size_t i, __global float *p) { p += 3 * i; p[0] = v.x; p[1] = v.y; p[2] = v.z; }
RT_OVL void rt_vstore3(float3 v, size_t i, float *p) { p += 3 * i; p[0] = v.x; p[1] = v.y; p[2] = v.z; }

/* Conversions of vectors of three components and more as clang's vector conversion (the same
 * arithmetic: round to nearest into floating point, truncation into integers), so that no vector
 * of 32 bytes or more (double3/4, float8, long4, the lanes' 16-wide ones) is passed to PoCL's
 * built-in library: where PoCL compiles for a CPU without the library's register width (Zen 4
 * under PoCL 3.0: no AVX-512 in the compile, the AVX-512 library linked), such a vector would
 * travel in a register on one side and in memory on the other (pyopencl_rt/device/isa.py). */
#undef convert_float3
#define convert_float3(a) __builtin_convertvector((a), float3)
#undef convert_float4
#define convert_float4(a) __builtin_convertvector((a), float4)
#undef convert_float8
#define convert_float8(a) __builtin_convertvector((a), float8)
#undef convert_float16
#define convert_float16(a) __builtin_convertvector((a), float16)
#undef convert_int3
#define convert_int3(a) __builtin_convertvector((a), int3)
#undef convert_int4
#define convert_int4(a) __builtin_convertvector((a), int4)
#undef convert_int8
#define convert_int8(a) __builtin_convertvector((a), int8)
#undef convert_int16
#define convert_int16(a) __builtin_convertvector((a), int16)
#undef convert_uint8
#define convert_uint8(a) __builtin_convertvector((a), uint8)
#undef convert_uint16
#define convert_uint16(a) __builtin_convertvector((a), uint16)
#ifdef cl_khr_fp64
#undef convert_double3
#define convert_double3(a) __builtin_convertvector((a), double3)
#undef convert_double4
#define convert_double4(a) __builtin_convertvector((a), double4)
#endif

#undef fabs
#define fabs(a) rt_fabs(a)
#undef copysign
#define copysign(a, b) rt_copysign(a, b)
#undef fmin
#define fmin(a, b) rt_fmin(a, b)
#undef fmax
#define fmax(a, b) rt_fmax(a, b)
#undef min
#define min(a, b) rt_min(a, b)
#undef max
#define max(a, b) rt_max(a, b)
#undef clamp
#define clamp(a, b, c) rt_clamp(a, b, c)
#undef floor
#define floor(a) rt_floor(a)
#undef sqrt
#define sqrt(a) rt_sqrt(a)
#undef rsqrt
#define rsqrt(a) rt_rsqrt(a)
#undef isfinite
#define isfinite(a) rt_isfinite(a)
#undef isinf
#define isinf(a) rt_isinf(a)
#undef isgreater
#define isgreater(a, b) rt_isgreater(a, b)
#undef select
#define select(a, b, c) rt_select(a, b, c)
#undef nextafter
#define nextafter(a, b) rt_nextafter(a, b)
#undef dot
#define dot(a, b) rt_dot(a, b)
#undef cross
#define cross(a, b) rt_cross(a, b)
#undef length
#define length(a) rt_length(a)
#undef normalize
#define normalize(a) rt_normalize(a)
#undef mix
#define mix(a, b, c) rt_mix(a, b, c)
#undef vload3
#define vload3(i, p) rt_vload3(i, p)
#undef vstore3
#define vstore3(v, i, p) rt_vstore3(v, i, p)

#endif /* x86 clang */
#endif
