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
 * two numbers to be stratified together must take them from one pair.
 *
 * The default, "sobol-global", differs in the first six pairs (the camera's
 * and the first two bounces'): they are dimensions 0 to 11 of one Sobol
 * point per sample, so they are also stratified jointly (see
 * SAMPLER_SOBOL_GLOBAL below). "sobol" is the padded sampler throughout. */
#ifndef TESSERA_SAMPLER_H
#define TESSERA_SAMPLER_H

#include <stdint.h>
#include <string.h>

#include "rng.h"

/* SAMPLER_SOBOL_GLOBAL is the default (0: what a zeroed options struct
 * holds), so `render`, `submit` and a job without a sampler field agree. */
typedef enum { SAMPLER_SOBOL_GLOBAL = 0, SAMPLER_RANDOM = 1, SAMPLER_SOBOL = 2 } sampler_kind;

/* "sobol", "random" or "sobol-global"; can't fail. */
static inline const char *sampler_name(sampler_kind k) {
    return k == SAMPLER_RANDOM ? "random" : k == SAMPLER_SOBOL_GLOBAL ? "sobol-global" : "sobol";
}

/* Parse a sampler name into *out. Returns 0, or -1 if the name is none of
 * those above. */
static inline int sampler_parse(const char *name, sampler_kind *out) {
    if (strcmp(name, "sobol") == 0) *out = SAMPLER_SOBOL;
    else if (strcmp(name, "random") == 0) *out = SAMPLER_RANDOM;
    else if (strcmp(name, "sobol-global") == 0) *out = SAMPLER_SOBOL_GLOBAL;
    else return -1;
    return 0;
}

/* SAMPLER_SOBOL_GLOBAL (the default since issue 15): the first
 * SAMPLER_GLOBAL_PAIRS pairs, dimensions 0 to 11 (the camera's and the
 * first two bounces' light and BSDF numbers), are Sobol dimensions 0 to 11
 * of one Sobol point per sample, its index shuffled once per pixel, each
 * dimension Owen-scrambled with its own seed: jointly stratified across
 * pairs, where padding stratifies each pair alone. Later pairs are padded as
 * with SAMPLER_SOBOL. Its pairs 1 to 5 are not all (0,m,2)-nets (t up to 2);
 * what it buys is the joint stratification (docs/performance.md). */
#define SAMPLER_GLOBAL_PAIRS 6u

/* sampler_global_nibbles[pair][j][v]: the XOR of the columns 4j to 4j + 3
 * of Sobol dimensions 2 pair (low 32 bits) and 2 pair + 1 (high 32 bits)
 * selected by the 4 bits of v (sampler_tables.c). */
extern const uint64_t sampler_global_nibbles[SAMPLER_GLOBAL_PAIRS][8][16];

/* Sobol dimensions 2 pair (low 32 bits) and 2 pair + 1 (high 32 bits) at
 * index x, both reversed: x times the generator matrices over GF(2), by
 * nibble tables. pair < SAMPLER_GLOBAL_PAIRS; can't fail. */
static inline uint64_t sampler_global_point(uint32_t pair, uint32_t x) {
    const uint64_t(*t)[16] = sampler_global_nibbles[pair];
    return t[0][x & 15u] ^ t[1][x >> 4 & 15u] ^ t[2][x >> 8 & 15u] ^ t[3][x >> 12 & 15u] ^ t[4][x >> 16 & 15u] ^
           t[5][x >> 20 & 15u] ^ t[6][x >> 24 & 15u] ^ t[7][x >> 28];
}

/* How many pairs' seeds a sampler_pixel keeps: the camera's and 21
 * bounces' (3 pairs each); later pairs hash theirs every time. */
#define SAMPLER_PIXEL_PAIRS 64u

/* What the samples of one pixel share under the Sobol samplers: its key,
 * sobol-global's index-shuffle seed, and each pair's hash and
 * index-scramble seed, filled in when a sample first asks for the pair.
 * Only a speed-up: the numbers are those sampler_start's streams give.
 * Plain struct, owned by the caller (one per pixel at a time). */
typedef struct {
    uint64_t key;         /* hash of (seed, pixel) */
    uint32_t global_seed; /* SOBOL_GLOBAL: the seed of the pixel's index shuffle */
    sampler_kind kind;
    uint64_t filled;      /* bit p: pair p's seeds below are set */
    /* One entry more than kept: sampler_get_bounce loads four pairs' seeds
     * for three (zeroed, never used). */
    uint64_t hash[SAMPLER_PIXEL_PAIRS + 1];
    uint32_t index_seed[SAMPLER_PIXEL_PAIRS + 1];
} sampler_pixel;

/* The numbers of one camera sample. Plain struct, owned by the caller,
 * usually on the stack. */
typedef struct {
    uint64_t key;       /* SOBOL: hash of (seed, pixel); RANDOM: of (seed, pixel, sample) */
    uint32_t index_rev; /* the sample index with its bits reversed */
    uint32_t global_index; /* SOBOL_GLOBAL: the index after the pixel's shuffle */
    sampler_kind kind;
    sampler_pixel *pixel; /* the pixel's shared seeds, or NULL: hash them every time */
} sampler_stream;

/* Reverse the 32 bits of x; can't fail. */
static inline uint32_t sampler_reverse_bits(uint32_t x) {
    x = __builtin_bswap32(x);
    x = ((x & 0x0f0f0f0fu) << 4) | ((x & 0xf0f0f0f0u) >> 4);
    x = ((x & 0x33333333u) << 2) | ((x & 0xccccccccu) >> 2);
    return ((x & 0x55555555u) << 1) | ((x & 0xaaaaaaaau) >> 1);
}

/* Reverse the 64 bits of x: the low half reversed becomes the high half and
 * the high half reversed the low one, so one call reverses two 32-bit
 * numbers in fewer instructions than two 32-bit reversals. Can't fail. */
static inline uint64_t sampler_reverse_bits64(uint64_t x) {
    x = __builtin_bswap64(x);
    x = ((x & 0x0f0f0f0f0f0f0f0full) << 4) | ((x >> 4) & 0x0f0f0f0f0f0f0f0full);
    x = ((x & 0x3333333333333333ull) << 2) | ((x >> 2) & 0x3333333333333333ull);
    return ((x & 0x5555555555555555ull) << 1) | ((x >> 1) & 0x5555555555555555ull);
}

/* sampler_reverse_bits of x and of y at once: *rx and *ry. Can't fail. */
static inline void sampler_reverse_bits2(uint32_t x, uint32_t y, uint32_t *rx, uint32_t *ry) {
    uint64_t r = sampler_reverse_bits64((uint64_t)y << 32 | x);
    *rx = (uint32_t)(r >> 32);
    *ry = (uint32_t)r;
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

/* 64 bits of a hash of (key, salt); can't fail. */
static inline uint64_t sampler_hash(uint64_t key, uint32_t salt) {
    return rng_mix64(key + (uint64_t)(salt + 1) * 0x9E3779B97F4A7C15ull);
}

/* Start the shared seeds of pixel `pixel` under `seed`; can't fail. */
static inline void sampler_pixel_start(sampler_pixel *px, sampler_kind kind, uint64_t seed, uint64_t pixel) {
    px->kind = kind;
    px->key = rng_mix64(rng_mix64(seed) ^ pixel);
    /* One index shuffle per pixel, shared by the first pairs. */
    px->global_seed = kind == SAMPLER_SOBOL_GLOBAL ? (uint32_t)rng_mix64(sampler_hash(px->key, 0xfffffffeu)) : 0;
    px->filled = 0;
    px->hash[SAMPLER_PIXEL_PAIRS] = 0;
    px->index_seed[SAMPLER_PIXEL_PAIRS] = 0;
}

/* Start the numbers of sample `sample` of the pixel px was started for.
 * px must outlive the stream; it is written to as pairs are first asked
 * for (under SAMPLER_RANDOM, whose keys are per sample, never). */
static inline sampler_stream sampler_start_pixel(sampler_pixel *px, uint32_t sample) {
    sampler_stream s;
    s.kind = px->kind;
    s.index_rev = sampler_reverse_bits(sample);
    s.key = px->key;
    s.pixel = px;
    s.global_index = 0;
    if (s.kind == SAMPLER_RANDOM) {
        s.key = rng_mix64(px->key ^ ((uint64_t)sample * 0x9E3779B97F4A7C15ull));
        s.pixel = NULL;
    } else if (s.kind == SAMPLER_SOBOL_GLOBAL) {
        s.global_index = sampler_reverse_bits(sampler_lk_hash(s.index_rev, px->global_seed));
    }
    return s;
}

/* Start the numbers of sample `sample` of pixel `pixel` under `seed`, with
 * nothing shared between samples: each pair's seeds are hashed when asked
 * for. */
static inline sampler_stream sampler_start(sampler_kind kind, uint64_t seed, uint64_t pixel, uint32_t sample) {
    sampler_pixel px;
    sampler_pixel_start(&px, kind, seed, pixel);
    sampler_stream s = sampler_start_pixel(&px, sample);
    s.pixel = NULL;
    return s;
}

/* Pair `pair`'s hash of the pixel key, and into *index_seed the seed of
 * its index scramble (padded pairs): from the pixel's shared seeds when
 * the stream has them, filling them in on first use. */
static inline uint64_t sampler_pair_seeds(const sampler_stream *s, uint32_t pair, uint32_t *index_seed) {
    sampler_pixel *px = s->pixel;
    if (px && pair < SAMPLER_PIXEL_PAIRS) {
        if (!(px->filled >> pair & 1u)) {
            px->hash[pair] = sampler_hash(s->key, pair);
            px->index_seed[pair] = (uint32_t)rng_mix64(px->hash[pair]);
            px->filled |= 1ull << pair;
        }
        *index_seed = px->index_seed[pair];
        return px->hash[pair];
    }
    uint64_t h = sampler_hash(s->key, pair);
    *index_seed = (uint32_t)rng_mix64(h);
    return h;
}

/* A 32-bit fixed-point number as a float in [0, 1): its top 24 bits, so the
 * result is exact and never rounds up to 1. */
static inline float sampler_to_float(uint32_t x) { return (float)(x >> 8) * 0x1p-24f; }

/* Both numbers of the pair of dimensions (2*pair, 2*pair + 1), as 32-bit
 * fixed point. One hash of (pixel key, pair) gives the pair's three seeds:
 * the index shuffle's and the two output scrambles'. */
static inline void sampler_pair_bits(const sampler_stream *s, uint32_t pair, uint32_t *a, uint32_t *b) {
    if (s->kind == SAMPLER_RANDOM) {
        uint64_t h = sampler_hash(s->key, pair);
        *a = (uint32_t)h;
        *b = (uint32_t)(h >> 32);
        return;
    }
    uint32_t seed_index;
    uint64_t h = sampler_pair_seeds(s, pair, &seed_index);
    if (s->kind == SAMPLER_SOBOL_GLOBAL && pair < SAMPLER_GLOBAL_PAIRS) {
        /* Dimensions 2 pair and 2 pair + 1 of the Sobol point at the
         * pixel's shuffled index, reversed (as dimension 0's index and
         * sampler_sobol1_rev below), Owen-scrambled. */
        uint64_t r = sampler_global_point(pair, s->global_index);
        sampler_reverse_bits2(sampler_lk_hash((uint32_t)r, (uint32_t)h),
                              sampler_lk_hash((uint32_t)(r >> 32), (uint32_t)(h >> 32)), a, b);
        return;
    }
    uint32_t seed_a = (uint32_t)h, seed_b = (uint32_t)(h >> 32);
    /* The index, Owen-scrambled as if it were a reversed fixed-point number
     * (Burley's nested uniform scramble): a permutation under which any 2^k
     * consecutive indices still cover every residue modulo 2^k, which is what
     * keeps power-of-two prefixes stratified. Below, dimension 0's own
     * reversal cancels the one inside Owen scrambling. */
    uint32_t shuffled = sampler_reverse_bits(sampler_lk_hash(s->index_rev, seed_index));
    sampler_reverse_bits2(sampler_lk_hash(shuffled, seed_a), sampler_lk_hash(sampler_sobol1_rev(shuffled), seed_b), a,
                          b);
}

/* The two numbers in [0, 1) of dimensions dim and dim + 1 (dim even),
 * stratified together. */
static inline void sampler_get_2d(const sampler_stream *s, uint32_t dim, float *u, float *v) {
    uint32_t a, b;
    sampler_pair_bits(s, dim >> 1, &a, &b);
    *u = sampler_to_float(a);
    *v = sampler_to_float(b);
}

/* The six numbers in [0, 1) of dimensions dim to dim + 5 (dim even), into
 * u[0] to u[5] (u[6] and u[7] are written and hold nothing): a bounce's
 * three pairs, equal bit for bit to three sampler_get_2d calls, in fewer
 * instructions (sampler_bounce.c). */
void sampler_get_bounce(const sampler_stream *s, uint32_t dim, float u[8]);

/* The number in [0, 1) of dimension dim. */
static inline float sampler_get_1d(const sampler_stream *s, uint32_t dim) {
    uint32_t a, b;
    sampler_pair_bits(s, dim >> 1, &a, &b);
    return sampler_to_float(dim & 1u ? b : a);
}

#endif
