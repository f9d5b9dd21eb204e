/* Masks of vector lanes (-1 set, 0 clear) and bits, for the wide traversals (bvh_wide.h,
 * bvh_wide8.h), the packet traversal (bvh_packet.h) and the lanes (cl/render/lanes.h). */
#ifndef PYOPENCL_RT_MASKS_H
#define PYOPENCL_RT_MASKS_H

#include "common.h"

/* PoCL links the OpenCL builtins select, any, fabs, clz and popcount as calls that LLVM leaves
 * out of line (objdump of the kernel: a call and a vzeroupper at every use, dozens per traversal
 * step), so the traversal spells them with operators and clang builtins, which compile to one or
 * two instructions.  SEL(a, b, m) is select(a, b, m) for a mask of -1 / 0 lanes (the vector ?:
 * of OpenCL C tests each lane's sign bit, as select does). */
#define SEL(a, b, m) ((m) ? (b) : (a))
#define VMIN(a, b) SEL((b), (a), (a) < (b)) /* any width; operands never NaN (see below) */
#define VMAX(a, b) SEL((b), (a), (a) > (b))
RT_INLINE float4 abs4(float4 x) { return as_float4(as_uint4(x) & (uint4)(0x7fffffffu)); }
RT_INLINE int any4(int4 m) { const int2 p = m.lo | m.hi; return (p.x | p.y) < 0; }
/* Bit i set where lane i's sign bit is (a mask's set lanes): movmskps where the compiler has it. */
#if defined(__SSE__) && defined(__clang__)
RT_INLINE int mask_bits4(int4 m) { return __builtin_ia32_movmskps(as_float4(m)); }
#else /* movmskps reads each lane's sign bit: so does this, for masks and for other ints alike
       * (a Tri8's slot ids: -1 where empty) */
RT_INLINE int mask_bits4(int4 m)
{
    const uint4 s = as_uint4(m) >> 31;
    return (int)(s.s0 | (s.s1 << 1) | (s.s2 << 2) | (s.s3 << 3));
}
#endif
#if defined(__has_builtin)
#if __has_builtin(__builtin_ctz) && __has_builtin(__builtin_popcount)
#define WIDE_CLANG_BITS
#endif
#endif
#ifdef WIDE_CLANG_BITS
RT_INLINE int lowest_bit(int bits) { return __builtin_ctz(bits); }
RT_INLINE int bit_count(int bits) { return __builtin_popcount(bits); }
#else
RT_INLINE int lowest_bit(int bits) { return 31 - clz(bits & -bits); }
RT_INLINE int bit_count(int bits) { return popcount(bits); }
#endif

/* Bit i set where lane i of the mask is set (-1), and whether any is: with AVX-512 (VL, DQ) one
 * vpmovd2m, so that a comparison's mask register is tested directly; with AVX vmovmskps; else
 * OR reductions. */
#if defined(__AVX512VL__) && defined(__AVX512DQ__) && defined(__clang__)
RT_INLINE int mask_bits8(int8 m) { return __builtin_ia32_cvtd2mask256(m); }
RT_INLINE int any8(int8 m) { return mask_bits8(m) != 0; }
#else
#if defined(__AVX__) && defined(__clang__)
RT_INLINE int mask_bits8(int8 m) { return __builtin_ia32_movmskps256(as_float8(m)); }
#else
RT_INLINE int mask_bits8(int8 m) { return mask_bits4(m.lo) | (mask_bits4(m.hi) << 4); }
#endif
RT_INLINE int any8(int8 m) { const int4 q = m.lo | m.hi; const int2 p = q.lo | q.hi; return (p.x | p.y) < 0; }
#endif
RT_INLINE float8 abs8(float8 x) { return as_float8(as_uint8(x) & (uint8)(0x7fffffffu)); }
RT_INLINE float lane4(float4 v, int k) { return k == 0 ? v.s0 : (k == 1 ? v.s1 : (k == 2 ? v.s2 : v.s3)); }
RT_INLINE float lane8(float8 v, int k) { return ((const float *)&v)[k]; }

#endif
