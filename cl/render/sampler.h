/* Samplers: the random numbers of one sample (a pixel's pass) as 1D and 2D samples, for the
 * lanes' paths (cl/render/lanes.h: at width 1 the types are uint and float).
 *
 *   SampleKey k = sampler_key(seed, pixel, width, pass);
 *   pfloat u = sample_1d(k, dim);       a 1D sample (light pick, lobe, Russian roulette)
 *   sample_2d(k, dim, &u, &v);          a 2D sample (pixel, lens, light point, BSDF direction)
 *
 * dim names the sample (cl/scene/scene.h lays them out); a 2D sample at dim takes the ids dim and
 * dim + 1.  The sampler (one of the generated SAMPLER_* values) is SAMPLER where kernel_features
 * compiles one in, else the kernels' run-time argument `sampler`, kept in the key (every sampler
 * compiled, one program for all: PYOPENCL_RT_KERNEL_FEATURES=all); the same numbers either way:
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

/* The sampler of key k: a constant where one is compiled in (the branches below fold away) */
#ifdef SAMPLER
#define SAMPLER_OF(k) SAMPLER
#else
#define SAMPLER_OF(k) ((k).kind)
#endif

/* The samples of a path: their dimension ids.  The pixel jitter (2D) takes
 * 0 and 1, then each bounce DIMS_PER_BOUNCE ids from 2 + DIMS_PER_BOUNCE * depth on: a 1D light
 * pick (with more than ALIAS_REUSE_MAX_LIGHTS lights, cl/render/path.h; else the light point's
 * first coordinate picks too), a 2D light point, a 2D BSDF direction, 1D Russian roulette, a 1D
 * BSDF lobe choice and a 1D choice of a mix's material (cl/materials/mix.h).
 * Every 1D or 2D sample is scrambled on its own, so the ids only need to differ. */
#define DIM_PIXEL 0
#define DIM_LENS 0xFFFFFFF0u /* and + 1: the thin lens, far from every bounce's dimensions */
#define DIM_TIME 0xFFFFFFF2u /* the path's time in the shutter (motion blur: cl/accel/instances.h) */
#define DIMS_PER_BOUNCE 8
#define DIM_LIGHT_PICK 0
#define DIM_LIGHT_POINT 1 /* and 2 */
#define DIM_BSDF 3        /* and 4 */
#define DIM_RR 5
#define DIM_BSDF_LOBE 6
#define DIM_MIX 7

#define SOBOL_TILE_BITS ((32 - SOBOL_LOG2_ROUND) / 2)
#define SAMPLER_KEY_SOBOL 0x50B01u     /* rng_hash dimension keys of the per-path key */
#define SAMPLER_KEY_STRATIFIED 0x57A7u

/* independent: (seed, pixel, pass); sobol: (index of the pass, key of tile and round, the index
 * bit-reversed); stratified: (pass, key of the pixel, the pass bit-reversed); per lane
 * (cl/render/lanes.h), like everything below: the lanes draw their own paths' samples. */
typedef struct {
    puint a, b, c;
#ifndef SAMPLER
    int kind; /* SAMPLER_*: the same for every lane */
#endif
} SampleKey;

RT_INLINE puint reverse_bits32(puint x)
{
    x = (x << 16) | (x >> 16);
    x = ((x & 0x00ff00ffu) << 8) | ((x >> 8) & 0x00ff00ffu);
    x = ((x & 0x0f0f0f0fu) << 4) | ((x >> 4) & 0x0f0f0f0fu);
    x = ((x & 0x33333333u) << 2) | ((x >> 2) & 0x33333333u);
    x = ((x & 0x55555555u) << 1) | ((x >> 1) & 0x55555555u);
    return x;
}

/* A seeded bijection of 32-bit words in which bit i depends on bits 0..i only (additions and
 * products by even constants carry upwards): Laine and Karras's permutation with Burley's
 * constants. */
RT_INLINE puint lk_permute(puint x, puint seed)
{
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

/* Nested uniform (Owen) scramble: bit i flips as a function of the bits above it.  A coordinate
 * given bit-reversed (r = reverse_bits32(x)) is scrambled as reverse_bits32(lk_permute(r, seed)). */
RT_INLINE puint nested_scramble(puint x, puint seed) { return reverse_bits32(lk_permute(reverse_bits32(x), seed)); }

/* Sobol dimension 1, bit-reversed: reverse_bits32(SOBOL_MATRIX[1] * index).  Column k of that
 * matrix is row k of Pascal's triangle mod 2 (its primitive polynomial is x + 1), so digit r
 * (from the most significant) is the XOR of the index bits k with C(k, r) odd, that is with
 * r a bit subset of k (Lucas): a superset-sum transform over the 5 bits of the positions, in 5
 * steps instead of a 32-column loop.  tests/render/test_sampler.py checks it against the table. */
RT_INLINE puint sobol_dim1_reversed(puint index)
{
    index ^= (index >> 1) & 0x55555555u;
    index ^= (index >> 2) & 0x33333333u;
    index ^= (index >> 4) & 0x0f0f0f0fu;
    index ^= (index >> 8) & 0x00ff00ffu;
    index ^= (index >> 16) & 0x0000ffffu;
    return index;
}

/* Sobol dimension 1 from the generated table (the reference of the closed form above). */
RT_INLINE uint sobol_dim1_table(uint index)
{
    uint v = 0u;
    for (int k = 0; index; index >>= 1, ++k)
        if (index & 1u) v ^= SOBOL_MATRIX[1][k];
    return v;
}

/* The bits of x (16 used) spread to the even positions. */
RT_INLINE puint spread_bits(puint x)
{
    x &= 0xffffu;
    x = (x | (x << 8)) & 0x00ff00ffu;
    x = (x | (x << 4)) & 0x0f0f0f0fu;
    x = (x | (x << 2)) & 0x33333333u;
    x = (x | (x << 1)) & 0x55555555u;
    return x;
}

/* The even bits of x, packed into the low 16. */
RT_INLINE puint gather_even_bits(puint x)
{
    x &= 0x55555555u;
    x = (x | (x >> 1)) & 0x33333333u;
    x = (x | (x >> 2)) & 0x0f0f0f0fu;
    x = (x | (x >> 4)) & 0x00ff00ffu;
    x = (x | (x >> 8)) & 0x0000ffffu;
    return x;
}

/* sampler_key of pixel (x, y) = (pixel % width, pixel / width), for a caller that has them
 * already (the megakernel steps through pixels without dividing) */
RT_INLINE SampleKey sampler_key_xy(int sampler, uint seed, puint pixel, puint x, puint y, puint pass)
{
    SampleKey k;
#ifndef SAMPLER
    k.kind = sampler;
#endif
    if (SAMPLER_OF(k) == SAMPLER_SOBOL) {
        const uint tile_mask = (1u << SOBOL_TILE_BITS) - 1u;
        const puint morton = spread_bits(x & tile_mask) | (spread_bits(y & tile_mask) << 1);
        const uint round_mask = (1u << SOBOL_LOG2_ROUND) - 1u;
        k.a = (morton << SOBOL_LOG2_ROUND) | (pass & round_mask);
        const puint tile = (x >> SOBOL_TILE_BITS) | ((y >> SOBOL_TILE_BITS) << 16);
        k.b = rng_hash(PUINT(seed), tile, pass >> SOBOL_LOG2_ROUND, PUINT(SAMPLER_KEY_SOBOL));
    } else if (SAMPLER_OF(k) == SAMPLER_STRATIFIED) {
        k.a = pass;
        k.b = rng_hash(PUINT(seed), pixel, PUINT(0u), PUINT(SAMPLER_KEY_STRATIFIED));
    } else {
        k.a = PUINT(seed); k.b = pixel; k.c = pass;
    }
    if (SAMPLER_OF(k) != SAMPLER_INDEPENDENT) k.c = reverse_bits32(k.a);
    return k;
}

/* `sampler`: SAMPLER_*, read where SAMPLER is not compiled in */
RT_INLINE SampleKey sampler_key(int sampler, uint seed, puint pixel, uint width, puint pass)
{
    return sampler_key_xy(sampler, seed, pixel, pixel % width, pixel / width, pass);
}

/* The first scramble seed of sample dim (the index shuffle); the others follow by hashing. */
RT_INLINE puint sample_seed(SampleKey k, puint dim)
{
    return hash_u32(k.b ^ hash_u32(dim + RNG_KEY_OFFSET));
}

/* The shuffled index of sample dim: nested_scramble(k.a, seed), computed from k.c = k.a reversed. */
RT_INLINE puint shuffled_index(SampleKey k, puint seed) { return reverse_bits32(lk_permute(k.c, seed)); }

RT_INLINE pfloat sample_1d(SampleKey k, puint dim)
{
    if (SAMPLER_OF(k) == SAMPLER_INDEPENDENT) return rng_uniform(k.a, k.b, k.c, dim);
    /* both: the first Sobol dimension (van der Corput: the index reversed) of the shuffled index,
     * scrambled */
    const puint s0 = sample_seed(k, dim);
    const puint index = shuffled_index(k, s0);
    return u32_to_unit_float(reverse_bits32(lk_permute(index, hash_u32(s0 ^ 1u))));
}

/* The path's time sample u in [0, 1): every ray of the path is traced at it (motion blur) */
RT_INLINE pfloat time_sample(SampleKey k) { return sample_1d(k, PUINT(DIM_TIME)); }

/* The 2D sample dim (ids dim and dim + 1) */
RT_INLINE void sample_2d(SampleKey k, puint dim, pfloat *u, pfloat *v)
{
    if (SAMPLER_OF(k) == SAMPLER_INDEPENDENT) {
        *u = rng_uniform(k.a, k.b, k.c, dim);
        *v = rng_uniform(k.a, k.b, k.c, dim + 1u);
        return;
    }
    const puint s0 = sample_seed(k, dim);
    const puint index = shuffled_index(k, s0);
    puint ru, rv;
    if (SAMPLER_OF(k) == SAMPLER_SOBOL) {
        /* both coordinates bit-reversed: dimension 0 is the index itself */
        ru = index;
        rv = sobol_dim1_reversed(index);
    } else {
        /* the cell of each level from a base-4 digit: even bits to x, odd bits to y, coarsest
         * first.  lk_permute flips each digit as a hash of the coarser ones (a nested scramble of
         * the quadtree), which also fills the digits below the first 4^k passes' cells with bits
         * that differ from sample to sample: the jitter inside a cell is not shared by a grid column. */
        const puint cells = lk_permute(index, hash_u32(s0 ^ 3u));
        ru = gather_even_bits(cells);
        rv = gather_even_bits(cells >> 1);
    }
    *u = u32_to_unit_float(reverse_bits32(lk_permute(ru, hash_u32(s0 ^ 1u))));
    *v = u32_to_unit_float(reverse_bits32(lk_permute(rv, hash_u32(s0 ^ 2u))));
}

#endif
