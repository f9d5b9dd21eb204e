/* Samplers: the random numbers of one sample (a pixel's pass) as 1D and 2D samples.
 *
 *   SampleKey k = sampler_key(seed, pixel, width, pass);
 *   float  u  = sample_1d(k, dim);    a 1D sample (light pick, lobe, Russian roulette)
 *   float2 uv = sample_2d(k, dim);    a 2D sample (pixel, lens, light point, BSDF direction)
 *
 * dim names the sample (cl/scene/scene.h lays them out); a 2D sample at dim takes the ids dim and
 * dim + 1.  SAMPLER (one of the generated SAMPLER_* values, chosen by kernel_features) selects:
 *
 * SAMPLER_INDEPENDENT  rng_uniform (cl/render/rng.h): every dimension an independent hash.
 * SAMPLER_SOBOL        Owen-scrambled Sobol in pbrt-v4's ZSobol arrangement.  Within a tile of
 *                      2^SOBOL_TILE_BITS x 2^SOBOL_TILE_BITS pixels, pixel (x, y) owns the indices
 *                      morton(x, y) * 2^SOBOL_LOG2_ROUND + [0, 2^SOBOL_LOG2_ROUND) of one Sobol
 *                      sequence, and its pass s takes the index of its block at s mod the block
 *                      size.  Each sample gets its own index shuffle and output scramble (padding:
 *                      every 2D sample is its own scrambled (0,2)-sequence, every 1D sample the
 *                      first dimension of one), both nested uniform scrambles in Burley's
 *                      hash-based form (JCGT 2020): a bit of the index, or of the coordinate,
 *                      flips as a hash of the bits above it, so aligned blocks of indices map to
 *                      aligned blocks and nets stay nets.  Hence the first 2^k passes of a pixel
 *                      (k <= SOBOL_LOG2_ROUND), and every aligned run of 2^k of them, are a
 *                      (0,k,2)-net in each 2D sample, and the 2^(k+2) samples of a 2x2 pixel group
 *                      at the end of a block are one too (the blue-noise arrangement).  The tile,
 *                      the round (s / block size) and the seed key the scrambles.
 * SAMPLER_STRATIFIED   progressive jittered stratification per pixel: pass s's base-4 digits,
 *                      after the same per-sample index shuffle and a nested scramble of the
 *                      quadtree, pick the cell at every level (the first 4^k passes fill a
 *                      2^k x 2^k grid, one sample a cell, each jittered on its own), and an Owen
 *                      scramble of each axis permutes rows and columns.
 *                      1D samples: a scrambled van der Corput sequence (2^k passes, one per
 *                      1/2^k interval).  Unlike Sobol, the 2D projections are not stratified
 *                      in 1D beyond sqrt(N) intervals.
 *
 * Everything is integer arithmetic keyed by (seed, pixel, pass, dim): any device and any split of
 * the work gives the same numbers.  tests/render/test_sampler.py checks a numpy copy bit for bit
 * and the (0,2)-net, uniformity and independence properties. */
#ifndef PYOPENCL_RT_SAMPLER_H
#define PYOPENCL_RT_SAMPLER_H

#include "render/rng.h"

#ifndef SAMPLER
#define SAMPLER SAMPLER_INDEPENDENT
#endif

/* The samples of a path: their dimension ids.  The pixel jitter (2D) takes
 * 0 and 1, then each bounce DIMS_PER_BOUNCE ids from 2 + DIMS_PER_BOUNCE * depth on: a 1D light
 * pick, a 2D light point, a 2D BSDF direction, 1D Russian roulette and a 1D BSDF lobe choice.
 * Every 1D or 2D sample is scrambled on its own, so the ids only need to differ. */
#define DIM_PIXEL 0
#define DIM_LENS 0xFFFFFFF0u /* and + 1: the thin lens, far from every bounce's dimensions */
#define DIMS_PER_BOUNCE 8
#define DIM_LIGHT_PICK 0
#define DIM_LIGHT_POINT 1 /* and 2 */
#define DIM_BSDF 3        /* and 4 */
#define DIM_RR 5
#define DIM_BSDF_LOBE 6

#define SOBOL_TILE_BITS ((32 - SOBOL_LOG2_ROUND) / 2)
#define SAMPLER_KEY_SOBOL 0x50B01u     /* rng_hash dimension keys of the per-path key */
#define SAMPLER_KEY_STRATIFIED 0x57A7u

/* independent: (seed, pixel, pass); sobol: (index of the pass, key of tile and round, the index
 * bit-reversed); stratified: (pass, key of the pixel, the pass bit-reversed) */
typedef struct { uint a, b, c; } SampleKey;

/* The integer steps below are defined through macros for uint and for vectors of uint (one path's
 * samples of a bounce in sample_bounce, or one sample of many paths in sampler_lanes.h), so that
 * every version is the same code. */
#define RT_DEFINE_REVERSE_BITS32(T, name)                                  \
    RT_INLINE T name(T x)                                                  \
    {                                                                      \
        x = (x << 16) | (x >> 16);                                         \
        x = ((x & 0x00ff00ffu) << 8) | ((x >> 8) & 0x00ff00ffu);           \
        x = ((x & 0x0f0f0f0fu) << 4) | ((x >> 4) & 0x0f0f0f0fu);           \
        x = ((x & 0x33333333u) << 2) | ((x >> 2) & 0x33333333u);           \
        x = ((x & 0x55555555u) << 1) | ((x >> 1) & 0x55555555u);           \
        return x;                                                          \
    }
RT_DEFINE_REVERSE_BITS32(uint, reverse_bits32)

/* A seeded bijection of 32-bit words in which bit i depends on bits 0..i only (additions and
 * products by even constants carry upwards): Laine and Karras's permutation with Burley's
 * constants. */
#define RT_DEFINE_LK_PERMUTE(T, name)   \
    RT_INLINE T name(T x, T seed)       \
    {                                   \
        x += seed;                      \
        x ^= x * 0x6c50b47cu;           \
        x ^= x * 0xb82f1e52u;           \
        x ^= x * 0xc7afe638u;           \
        x ^= x * 0x8d22f6e6u;           \
        return x;                       \
    }
RT_DEFINE_LK_PERMUTE(uint, lk_permute)

/* Nested uniform (Owen) scramble: bit i flips as a function of the bits above it.  A coordinate
 * given bit-reversed (r = reverse_bits32(x)) is scrambled as reverse_bits32(lk_permute(r, seed)). */
RT_INLINE uint nested_scramble(uint x, uint seed) { return reverse_bits32(lk_permute(reverse_bits32(x), seed)); }

/* Sobol dimension 1, bit-reversed: reverse_bits32(SOBOL_MATRIX[1] * index).  Column k of that
 * matrix is row k of Pascal's triangle mod 2 (its primitive polynomial is x + 1), so digit r
 * (from the most significant) is the XOR of the index bits k with C(k, r) odd, that is with
 * r a bit subset of k (Lucas): a superset-sum transform over the 5 bits of the positions, in 5
 * steps instead of a 32-column loop.  tests/render/test_sampler.py checks it against the table. */
#define RT_DEFINE_SOBOL_DIM1(T, name)             \
    RT_INLINE T name(T index)                     \
    {                                             \
        index ^= (index >> 1) & 0x55555555u;      \
        index ^= (index >> 2) & 0x33333333u;      \
        index ^= (index >> 4) & 0x0f0f0f0fu;      \
        index ^= (index >> 8) & 0x00ff00ffu;      \
        index ^= (index >> 16) & 0x0000ffffu;     \
        return index;                             \
    }
RT_DEFINE_SOBOL_DIM1(uint, sobol_dim1_reversed)

/* Sobol dimension 1 from the generated table (the reference of the closed form above). */
RT_INLINE uint sobol_dim1_table(uint index)
{
    uint v = 0u;
    for (int k = 0; index; index >>= 1, ++k)
        if (index & 1u) v ^= SOBOL_MATRIX[1][k];
    return v;
}

/* The bits of x (16 used) spread to the even positions. */
RT_INLINE uint spread_bits(uint x)
{
    x &= 0xffffu;
    x = (x | (x << 8)) & 0x00ff00ffu;
    x = (x | (x << 4)) & 0x0f0f0f0fu;
    x = (x | (x << 2)) & 0x33333333u;
    x = (x | (x << 1)) & 0x55555555u;
    return x;
}

/* The even bits of x, packed into the low 16. */
#define RT_DEFINE_GATHER_EVEN_BITS(T, name)    \
    RT_INLINE T name(T x)                      \
    {                                          \
        x &= 0x55555555u;                      \
        x = (x | (x >> 1)) & 0x33333333u;      \
        x = (x | (x >> 2)) & 0x0f0f0f0fu;      \
        x = (x | (x >> 4)) & 0x00ff00ffu;      \
        x = (x | (x >> 8)) & 0x0000ffffu;      \
        return x;                              \
    }
RT_DEFINE_GATHER_EVEN_BITS(uint, gather_even_bits)

/* sampler_key of pixel (x, y) = (pixel % width, pixel / width), for a caller that has them
 * already (the lane megakernel steps through pixels without dividing) */
RT_INLINE SampleKey sampler_key_xy(uint seed, uint pixel, uint x, uint y, uint pass)
{
    SampleKey k;
#if SAMPLER == SAMPLER_SOBOL
    const uint tile_mask = (1u << SOBOL_TILE_BITS) - 1u;
    const uint morton = spread_bits(x & tile_mask) | (spread_bits(y & tile_mask) << 1);
    const uint round_mask = (1u << SOBOL_LOG2_ROUND) - 1u;
    k.a = (morton << SOBOL_LOG2_ROUND) | (pass & round_mask);
    const uint tile = (x >> SOBOL_TILE_BITS) | ((y >> SOBOL_TILE_BITS) << 16);
    k.b = rng_hash(seed, tile, pass >> SOBOL_LOG2_ROUND, SAMPLER_KEY_SOBOL);
#elif SAMPLER == SAMPLER_STRATIFIED
    k.a = pass;
    k.b = rng_hash(seed, pixel, 0u, SAMPLER_KEY_STRATIFIED);
#else
    k.a = seed; k.b = pixel; k.c = pass;
#endif
#if SAMPLER != SAMPLER_INDEPENDENT
    k.c = reverse_bits32(k.a);
#endif
    return k;
}

RT_INLINE SampleKey sampler_key(uint seed, uint pixel, uint width, uint pass)
{
    return sampler_key_xy(seed, pixel, pixel % width, pixel / width, pass);
}

#if SAMPLER != SAMPLER_INDEPENDENT
/* The first scramble seed of sample dim (the index shuffle); the others follow by hashing. */
RT_INLINE uint sample_seed(SampleKey k, uint dim)
{
    return hash_u32(k.b ^ hash_u32(dim + RNG_KEY_OFFSET));
}

/* The shuffled index of sample dim: nested_scramble(k.a, seed), computed from k.c = k.a reversed. */
RT_INLINE uint shuffled_index(SampleKey k, uint seed) { return reverse_bits32(lk_permute(k.c, seed)); }
#endif

RT_INLINE float sample_1d(SampleKey k, uint dim)
{
#if SAMPLER == SAMPLER_INDEPENDENT
    return rng_uniform(k.a, k.b, k.c, dim);
#else
    /* both: the first Sobol dimension (van der Corput: the index reversed) of the shuffled index,
     * scrambled */
    const uint s0 = sample_seed(k, dim);
    const uint index = shuffled_index(k, s0);
    return u32_to_unit_float(reverse_bits32(lk_permute(index, hash_u32(s0 ^ 1u))));
#endif
}

RT_INLINE float2 sample_2d(SampleKey k, uint dim)
{
#if SAMPLER == SAMPLER_INDEPENDENT
    return rng_uniform2(k.a, k.b, k.c, dim);
#else
    const uint s0 = sample_seed(k, dim);
    const uint index = shuffled_index(k, s0);
#if SAMPLER == SAMPLER_SOBOL
    /* both coordinates bit-reversed: dimension 0 is the index itself */
    const uint ru = index, rv = sobol_dim1_reversed(index);
#else
    /* the cell of each level from a base-4 digit: even bits to x, odd bits to y, coarsest first.
     * lk_permute flips each digit as a hash of the coarser ones (a nested scramble of the
     * quadtree), which also fills the digits below the first 4^k passes' cells with bits that
     * differ from sample to sample: the jitter inside a cell is not shared by a grid column. */
    const uint cells = lk_permute(index, hash_u32(s0 ^ 3u));
    const uint ru = gather_even_bits(cells), rv = gather_even_bits(cells >> 1);
#endif
    return (float2)(u32_to_unit_float(reverse_bits32(lk_permute(ru, hash_u32(s0 ^ 1u)))),
                    u32_to_unit_float(reverse_bits32(lk_permute(rv, hash_u32(s0 ^ 2u)))));
#endif
}

/* ---------------------------------------------------------------------------------------------
 * All the samples of one bounce at once: lane j of the result is sample id dim + j of the
 * layout above (lane DIM_LIGHT_PICK = sample_1d(k, dim + DIM_LIGHT_PICK), lanes DIM_LIGHT_POINT
 * and + 1 = sample_2d(k, dim + DIM_LIGHT_POINT), and so on; lane 7, unused, is sample_1d of id
 * dim + 7), bit for bit the values of those calls (tests/render/test_sampler.py).
 *
 * Why: the samplers are integer hashing, permutations and bit reversals, 100-150 instructions a
 * sample; path_shade_hit draws seven values a bounce, a fifth of the megakernel's time outside
 * the traversal (perf, functions kept out of line).  The eight lanes do the same steps, so one
 * pass over uint8 vectors (one AVX2 register) computes them together.
 * --------------------------------------------------------------------------------------------- */
RT_DEFINE_HASH_U32(uint8, hash_u32x8)

RT_INLINE float8 u32_to_unit_float8(uint8 h) { return convert_float8(h >> 8) * 0x1.0p-24f; }

#if SAMPLER != SAMPLER_INDEPENDENT
RT_DEFINE_REVERSE_BITS32(uint8, reverse_bits32x8)
RT_DEFINE_LK_PERMUTE(uint8, lk_permute_x8)
RT_DEFINE_SOBOL_DIM1(uint8, sobol_dim1_reversed_x8)
RT_DEFINE_GATHER_EVEN_BITS(uint8, gather_even_bits_x8)
#endif

/* lane j: 1 where id dim + j is the second coordinate of a 2D sample (DIM_LIGHT_POINT + 1,
 * DIM_BSDF + 1), else 0 */
#define BOUNCE_SECOND ((uint8)(0u, 0u, 1u, 0u, 1u, 0u, 0u, 0u))
#define BOUNCE_IS_2D ((uint8)(0u, 1u, 1u, 1u, 1u, 0u, 0u, 0u))

RT_INLINE float8 sample_bounce(SampleKey k, uint dim)
{
    const uint8 ids = (uint8)(dim) + (uint8)(0u, 1u, 2u, 3u, 4u, 5u, 6u, 7u);
#if SAMPLER == SAMPLER_INDEPENDENT
    /* rng_uniform(k.a, k.b, k.c, id) per lane: a 2D sample is ids dim and dim + 1 */
    uint8 h = hash_u32x8(ids + RNG_KEY_OFFSET);
    h = hash_u32x8((uint8)(k.c) ^ h);
    h = hash_u32x8((uint8)(k.b) ^ h);
    return u32_to_unit_float8(hash_u32x8((uint8)(k.a) ^ h));
#else
    /* a 2D sample's second coordinate uses its first id's seed and index */
    const uint8 seed_ids = ids - BOUNCE_SECOND;
    const uint8 s0 = hash_u32x8((uint8)(k.b) ^ hash_u32x8(seed_ids + RNG_KEY_OFFSET));
    const uint8 index = reverse_bits32x8(lk_permute_x8((uint8)(k.c), s0));
#if SAMPLER == SAMPLER_SOBOL
    /* second coordinates: Sobol dimension 1 of the index */
    const uint8 r = BOUNCE_SECOND != 0u ? sobol_dim1_reversed_x8(index) : index;
#else
    /* 2D: the quadtree cells' even (first) or odd (second) bits, as gather_even_bits */
    const uint8 cells = gather_even_bits_x8(lk_permute_x8(index, hash_u32x8(s0 ^ 3u)) >> BOUNCE_SECOND);
    const uint8 r = BOUNCE_IS_2D != 0u ? cells : index;
#endif
    return u32_to_unit_float8(reverse_bits32x8(lk_permute_x8(r, hash_u32x8(s0 ^ (1u + BOUNCE_SECOND)))));
#endif
}

#endif
