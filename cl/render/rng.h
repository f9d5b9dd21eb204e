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

#include "render/lanes.h"

#define RNG_KEY_OFFSET 0x9E3779B9u

/* Chris Wellons' "lowbias32" integer finaliser (a bijection on 32 bits with low avalanche bias),
 * over the lanes (cl/render/lanes.h), like everything below. */
RT_INLINE puint hash_u32(puint x)
{
    x ^= x >> 16;
    x *= 0x7feb352du;
    x ^= x >> 15;
    x *= 0x846ca68bu;
    x ^= x >> 16;
    return x;
}

/* The top 24 bits as a float in [0, 1): exact (24 bits fit the mantissa), at most 1 - 2^-24. */
RT_INLINE pfloat u32_to_unit_float(puint h) { return convert_pfloat(h >> 8) * 0x1.0p-24f; }

RT_INLINE puint rng_hash(puint seed, puint pixel, puint sample, puint dim)
{
    puint h = hash_u32(dim + RNG_KEY_OFFSET);
    h = hash_u32(sample ^ h);
    h = hash_u32(pixel ^ h);
    return hash_u32(seed ^ h);
}

/* Uniform in [0, 1), strictly below 1. */
RT_INLINE pfloat rng_uniform(puint seed, puint pixel, puint sample, puint dim)
{
    return u32_to_unit_float(rng_hash(seed, pixel, sample, dim));
}

#endif
