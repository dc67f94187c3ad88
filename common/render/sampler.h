/* sampler.h - the numbers a camera sample consumes: Owen-scrambled Sobol
 * points by default, independent random numbers on request.
 *
 * Both are pure functions of (seed, pixel, sample index, dimension), so a
 * pixel's samples never depend on which thread, tile or process made them.
 *
 * The Sobol sampler is "padded" 2D Sobol (pbrt-v4's PaddedSobolSampler):
 * dimensions are used in pairs (0,1), (2,3), ...; each pair is the first two
 * Sobol dimensions at a sample index that is itself Owen-scrambled with a
 * seed of its own, and each coordinate is Owen-scrambled again with the
 * dimension's seed (Burley 2020, "Practical Hash-based Owen Scrambling").
 * Within a pixel, every pair of dimensions is then a (0,2)-sequence in base
 * 2: the first 2^k samples put exactly one point in each of the 2^k
 * elementary intervals of any shape. Pairs are decorrelated from each other
 * and pixels from their neighbours by the scrambling seeds. Callers that want
 * two numbers to be stratified together must take them from one pair. */
#ifndef TESSERA_SAMPLER_H
#define TESSERA_SAMPLER_H

#include <stdint.h>
#include <string.h>

#include "rng.h"

typedef enum { SAMPLER_SOBOL = 0, SAMPLER_RANDOM = 1 } sampler_kind;

/* "sobol" or "random"; can't fail. */
static inline const char *sampler_name(sampler_kind k) { return k == SAMPLER_RANDOM ? "random" : "sobol"; }

/* Parse a sampler name into *out. Returns 0, or -1 if the name is neither. */
static inline int sampler_parse(const char *name, sampler_kind *out) {
    if (strcmp(name, "sobol") == 0) *out = SAMPLER_SOBOL;
    else if (strcmp(name, "random") == 0) *out = SAMPLER_RANDOM;
    else return -1;
    return 0;
}

/* The numbers of one camera sample. Plain struct, owned by the caller,
 * usually on the stack. */
typedef struct {
    uint64_t key;       /* SOBOL: hash of (seed, pixel); RANDOM: of (seed, pixel, sample) */
    uint32_t index_rev; /* the sample index with its bits reversed */
    sampler_kind kind;
} sampler_stream;

/* Reverse the 32 bits of x; can't fail. */
static inline uint32_t sampler_reverse_bits(uint32_t x) {
    x = __builtin_bswap32(x);
    x = ((x & 0x0f0f0f0fu) << 4) | ((x & 0xf0f0f0f0u) >> 4);
    x = ((x & 0x33333333u) << 2) | ((x & 0xccccccccu) >> 2);
    return ((x & 0x55555555u) << 1) | ((x & 0xaaaaaaaau) >> 1);
}

/* Burley's Laine-Karras-style hash: each output bit is the input bit
 * flipped by a function of the seed and the bits below it (even multipliers
 * and addition only carry upwards). Applied to bit-reversed fixed-point
 * numbers, "below" means "more significant": that is Owen scrambling.
 * A bijection; can't fail. */
static inline uint32_t sampler_lk_hash(uint32_t x, uint32_t seed) {
    x += seed;
    x ^= x * 0x6c50b47cu;
    x ^= x * 0xb82f1e52u;
    x ^= x * 0xc7afe638u;
    x ^= x * 0x8d22f6e6u;
    return x;
}

/* Dimension 1 of the Sobol sequence at `index`, bit-reversed. Its
 * generator columns, reversed, are w_0 = 1 and w_i = w_{i-1} ^ (w_{i-1} << 1)
 * = (1 + z)^i as polynomials over GF(2), so the result is the index's
 * polynomial X evaluated at 1 + z. Splitting X into halves, X(1 + z) =
 * L(1 + z) + (1 + z^h) H(1 + z) with h a power of two: in place, each low
 * half takes the XOR of the transformed high half, from 1-bit halves up.
 * (Dimension 0, van der Corput, is the index itself once reversed.) */
static inline uint32_t sampler_sobol1_rev(uint32_t x) {
    x ^= (x >> 1) & 0x55555555u;
    x ^= (x >> 2) & 0x33333333u;
    x ^= (x >> 4) & 0x0f0f0f0fu;
    x ^= (x >> 8) & 0x00ff00ffu;
    x ^= (x >> 16) & 0x0000ffffu;
    return x;
}

/* Start the numbers of sample `sample` of pixel `pixel` under `seed`. */
static inline sampler_stream sampler_start(sampler_kind kind, uint64_t seed, uint64_t pixel, uint32_t sample) {
    sampler_stream s;
    s.kind = kind;
    s.index_rev = sampler_reverse_bits(sample);
    uint64_t pixel_key = rng_mix64(rng_mix64(seed) ^ pixel);
    s.key = kind == SAMPLER_SOBOL ? pixel_key : rng_mix64(pixel_key ^ ((uint64_t)sample * 0x9E3779B97F4A7C15ull));
    return s;
}

/* 64 bits of a hash of (key, salt); can't fail. */
static inline uint64_t sampler_hash(uint64_t key, uint32_t salt) {
    return rng_mix64(key + (uint64_t)(salt + 1) * 0x9E3779B97F4A7C15ull);
}

/* A 32-bit fixed-point number as a float in [0, 1): its top 24 bits, so the
 * result is exact and never rounds up to 1. */
static inline float sampler_to_float(uint32_t x) { return (float)(x >> 8) * 0x1p-24f; }

/* Both numbers of the pair of dimensions (2*pair, 2*pair + 1), as 32-bit
 * fixed point. One hash of (pixel key, pair) gives the pair's three seeds:
 * the index shuffle's and the two output scrambles'. */
static inline void sampler_pair_bits(const sampler_stream *s, uint32_t pair, uint32_t *a, uint32_t *b) {
    uint64_t h = sampler_hash(s->key, pair);
    if (s->kind == SAMPLER_RANDOM) {
        *a = (uint32_t)h;
        *b = (uint32_t)(h >> 32);
        return;
    }
    uint32_t seed_index = (uint32_t)rng_mix64(h), seed_a = (uint32_t)h, seed_b = (uint32_t)(h >> 32);
    /* The index, Owen-scrambled as if it were a reversed fixed-point number
     * (Burley's nested uniform scramble): a permutation under which any 2^k
     * consecutive indices still cover every residue modulo 2^k, which is what
     * keeps power-of-two prefixes stratified. Below, dimension 0's own
     * reversal cancels the one inside Owen scrambling. */
    uint32_t shuffled = sampler_reverse_bits(sampler_lk_hash(s->index_rev, seed_index));
    *a = sampler_reverse_bits(sampler_lk_hash(shuffled, seed_a));
    *b = sampler_reverse_bits(sampler_lk_hash(sampler_sobol1_rev(shuffled), seed_b));
}

/* The two numbers in [0, 1) of dimensions dim and dim + 1 (dim even),
 * stratified together. */
static inline void sampler_get_2d(const sampler_stream *s, uint32_t dim, float *u, float *v) {
    uint32_t a, b;
    sampler_pair_bits(s, dim >> 1, &a, &b);
    *u = sampler_to_float(a);
    *v = sampler_to_float(b);
}

/* The number in [0, 1) of dimension dim. */
static inline float sampler_get_1d(const sampler_stream *s, uint32_t dim) {
    uint32_t a, b;
    sampler_pair_bits(s, dim >> 1, &a, &b);
    return sampler_to_float(dim & 1u ? b : a);
}

#endif
