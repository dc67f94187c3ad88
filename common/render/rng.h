/* rng.h - counter-based random numbers: every value is a pure function of
 * (seed, pixel, sample index, dimension).
 *
 * There is no generator state to share, seed from the clock, or advance in a
 * particular order: a worker on another machine that renders pixel p, sample
 * i gets the same numbers as a thread here. The key for one camera sample is
 * hashed once from (seed, pixel, sample); each dimension then costs one 64-bit
 * finaliser (SplitMix64's, a bijection with full avalanche). */
#ifndef TESSERA_RNG_H
#define TESSERA_RNG_H

#include <stdint.h>

/* The random-number stream of one camera sample. Plain struct, owned by the
 * caller, usually on the stack. */
typedef struct {
    uint64_t key; /* hash of (seed, pixel, sample) */
    uint32_t dim; /* next dimension to hand out */
} rng_stream;

/* SplitMix64's finaliser: a bijection on 64 bits; can't fail. */
static inline uint64_t rng_mix64(uint64_t z) {
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ull;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBull;
    return z ^ (z >> 31);
}

/* Start the stream of sample `sample` of pixel `pixel` under `seed`. */
static inline rng_stream rng_stream_start(uint64_t seed, uint64_t pixel, uint64_t sample) {
    rng_stream s;
    s.key = rng_mix64(rng_mix64(rng_mix64(seed) ^ pixel) ^ (sample * 0x9E3779B97F4A7C15ull));
    s.dim = 0;
    return s;
}

/* The 64 random bits of dimension `dim` of this stream, without advancing. */
static inline uint64_t rng_bits_at(const rng_stream *s, uint32_t dim) {
    return rng_mix64(s->key + (uint64_t)(dim + 1) * 0x9E3779B97F4A7C15ull);
}

/* Next uniform number in [0, 1): 24 random bits, so the result is exactly
 * representable and never rounds up to 1. */
static inline float rng_next(rng_stream *s) {
    return (float)(rng_bits_at(s, s->dim++) >> 40) * 0x1p-24f;
}

#endif
