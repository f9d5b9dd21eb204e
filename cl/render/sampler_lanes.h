/* sample_1d and sample_2d (cl/render/sampler.h) for one sample id of PACKET_WIDTH paths at once:
 * lane k gets the value the scalar call gives for path k's SampleKey (ka, kb, kc lane k) and id
 * (dim lane k), bit for bit (tests/render/test_path_lanes.py).  The integer steps are the
 * scalar ones, generated for the lane type by the same macros. */
#ifndef PYOPENCL_RT_SAMPLER_LANES_H
#define PYOPENCL_RT_SAMPLER_LANES_H

#include "render/sampler.h"
#include "render/lanes.h"

RT_DEFINE_HASH_U32(puint, hash_u32_lanes)
#if SAMPLER != SAMPLER_INDEPENDENT
RT_DEFINE_REVERSE_BITS32(puint, reverse_bits32_lanes)
RT_DEFINE_LK_PERMUTE(puint, lk_permute_lanes)
RT_DEFINE_SOBOL_DIM1(puint, sobol_dim1_reversed_lanes)
RT_DEFINE_GATHER_EVEN_BITS(puint, gather_even_bits_lanes)
#endif

/* The SampleKeys of the lanes. */
typedef struct { puint a, b, c; } SampleKeyLanes;

RT_INLINE pfloat u32_to_unit_float_lanes(puint h) { return convert_pfloat(h >> 8) * 0x1.0p-24f; }

#if SAMPLER == SAMPLER_INDEPENDENT
RT_INLINE pfloat rng_uniform_lanes(SampleKeyLanes k, puint dim)
{
    puint h = hash_u32_lanes(dim + RNG_KEY_OFFSET);
    h = hash_u32_lanes(k.c ^ h);
    h = hash_u32_lanes(k.b ^ h);
    return u32_to_unit_float_lanes(hash_u32_lanes(k.a ^ h));
}
#else
/* sample_seed and shuffled_index of sampler.h */
RT_INLINE puint sample_seed_lanes(SampleKeyLanes k, puint dim)
{
    return hash_u32_lanes(k.b ^ hash_u32_lanes(dim + RNG_KEY_OFFSET));
}
RT_INLINE puint shuffled_index_lanes(SampleKeyLanes k, puint seed) { return reverse_bits32_lanes(lk_permute_lanes(k.c, seed)); }
#endif

RT_INLINE pfloat sample_1d_lanes(SampleKeyLanes k, puint dim)
{
#if SAMPLER == SAMPLER_INDEPENDENT
    return rng_uniform_lanes(k, dim);
#else
    const puint s0 = sample_seed_lanes(k, dim);
    const puint index = shuffled_index_lanes(k, s0);
    return u32_to_unit_float_lanes(reverse_bits32_lanes(lk_permute_lanes(index, hash_u32_lanes(s0 ^ 1u))));
#endif
}

RT_INLINE void sample_2d_lanes(SampleKeyLanes k, puint dim, pfloat *u, pfloat *v)
{
#if SAMPLER == SAMPLER_INDEPENDENT
    *u = rng_uniform_lanes(k, dim);
    *v = rng_uniform_lanes(k, dim + 1u);
#else
    const puint s0 = sample_seed_lanes(k, dim);
    const puint index = shuffled_index_lanes(k, s0);
#if SAMPLER == SAMPLER_SOBOL
    const puint ru = index, rv = sobol_dim1_reversed_lanes(index);
#else
    const puint cells = lk_permute_lanes(index, hash_u32_lanes(s0 ^ 3u));
    const puint ru = gather_even_bits_lanes(cells), rv = gather_even_bits_lanes(cells >> 1);
#endif
    *u = u32_to_unit_float_lanes(reverse_bits32_lanes(lk_permute_lanes(ru, hash_u32_lanes(s0 ^ 1u))));
    *v = u32_to_unit_float_lanes(reverse_bits32_lanes(lk_permute_lanes(rv, hash_u32_lanes(s0 ^ 2u))));
#endif
}

#endif
