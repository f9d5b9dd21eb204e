/* Counter-based random numbers: no state is stored or carried between kernels.
 *
 * The random number for (seed, pixel, sample index, dimension) is a pure function of those four
 * integers (integer hashing only, then an exact conversion to float), so any device, any order
 * of execution and any split of the work (tiles, sample batches, several devices, a resumed
 * render) gives bit-identical numbers.  tests/render/test_sampling.py checks the device against a numpy
 * reference of the same function.
 *
 * Keys are chained through the hash, h = hash(seed ^ hash(pixel ^ hash(sample ^ hash(dim + c)))),
 * so neighbouring pixels, samples and dimensions (which differ in a few low bits) feed inputs
 * that are decorrelated by a full avalanche.  The constant c keeps the all-zero key away from
 * the hash's fixed point hash(0) = 0. */
#ifndef PYOPENCL_RT_RNG_H
#define PYOPENCL_RT_RNG_H

#include "common.h"

#define RNG_KEY_OFFSET 0x9E3779B9u

/* Chris Wellons' "lowbias32" integer finaliser (a bijection on 32 bits with low avalanche bias).
 * Defined through a macro for uint and for vectors of uint (the samplers' lane versions,
 * cl/render/sampler.h and sampler_lanes.h), so that every version is the same code. */
#define RT_DEFINE_HASH_U32(T, name)   \
    RT_INLINE T name(T x)             \
    {                                 \
        x ^= x >> 16;                 \
        x *= 0x7feb352du;             \
        x ^= x >> 15;                 \
        x *= 0x846ca68bu;             \
        x ^= x >> 16;                 \
        return x;                     \
    }
RT_DEFINE_HASH_U32(uint, hash_u32)

/* The top 24 bits as a float in [0, 1): exact (24 bits fit the mantissa), at most 1 - 2^-24. */
RT_INLINE float u32_to_unit_float(uint h) { return (float)(h >> 8) * 0x1.0p-24f; }

RT_INLINE uint rng_hash(uint seed, uint pixel, uint sample, uint dim)
{
    uint h = hash_u32(dim + RNG_KEY_OFFSET);
    h = hash_u32(sample ^ h);
    h = hash_u32(pixel ^ h);
    return hash_u32(seed ^ h);
}

/* Uniform in [0, 1), strictly below 1. */
RT_INLINE float rng_uniform(uint seed, uint pixel, uint sample, uint dim)
{
    return u32_to_unit_float(rng_hash(seed, pixel, sample, dim));
}

/* Dimensions dim and dim + 1. */
RT_INLINE float2 rng_uniform2(uint seed, uint pixel, uint sample, uint dim)
{
    return (float2)(rng_uniform(seed, pixel, sample, dim), rng_uniform(seed, pixel, sample, dim + 1u));
}

#endif
