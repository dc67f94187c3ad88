/* sampler_bounce.c - the six numbers of a bounce's three pairs at once.
 *
 * A bounce asks for three pairs of dimensions (the light point, the BSDF
 * direction, the lobe and roulette: integrator.c). Under the Sobol samplers
 * each pair is three Owen scrambles (sampler_lk_hash: a chain of four
 * multiplications) and reversals, independent of the other pairs': in the
 * lanes of SSE4.1 vectors (pmulld, pshufb) the three pairs cost about the
 * instructions of one. The numbers are those of sampler_get_2d bit for bit
 * (tests/test_sampler.c: sampler_bounce_matches_pairs): the same integer
 * steps lane by lane, and a float conversion that is exact either way.
 * AVX2 does both numbers of the three pairs in one 8-lane vector. Without
 * SSE4.1 (checked at run time, as accel_wide.c checks for its walks), under
 * SAMPLER_RANDOM, without a sampler_pixel and past the pairs it keeps, the
 * pairs are taken one by one.
 *
 * Measured (2026-11-26, EPYC Zen 5, against one sampler_get_2d call per
 * pair): callgrind, 64x64x8 spp, one thread, render_tile's instructions
 * -7.4% on ico5 (296.0M -> 274.0M) and -8.0% on cornell-spheres; the
 * render thread's CPU (bench accel-speed, the two binaries run side by side,
 * median of the paired ratios) -8% on ico5, -6% on ico7, -8% on the spheres
 * and the box. The SSE4.1 and AVX2 versions measured the same. Tried and
 * dropped: the camera's pair with the first bounce's in one 4-pair vector,
 * and sobol-global's table looked up a vector per nibble (-0.4%
 * instructions, no change in time). */
#include "sampler.h"

#include <stdlib.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>

#define SSE41 __attribute__((target("sse4.1")))

/* sampler_lk_hash in each lane. */
static inline SSE41 __m128i lk_hash4(__m128i x, __m128i seed) {
    x = _mm_add_epi32(x, seed);
    x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_set1_epi32((int)0x6c50b47cu)));
    x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_set1_epi32((int)0xb82f1e52u)));
    x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_set1_epi32((int)0xc7afe638u)));
    x = _mm_xor_si128(x, _mm_mullo_epi32(x, _mm_set1_epi32((int)0x8d22f6e6u)));
    return x;
}

/* sampler_reverse_bits in each lane: the bytes swapped by one shuffle, each
 * byte's nibbles reversed and swapped by two table look-ups. */
static inline SSE41 __m128i reverse4(__m128i x) {
    const __m128i bswap = _mm_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12);
    /* rev[n]: the 4 bits of n reversed; to_high: rev[n] << 4. */
    const __m128i rev = _mm_setr_epi8(0, 8, 4, 12, 2, 10, 6, 14, 1, 9, 5, 13, 3, 11, 7, 15);
    const __m128i to_high = _mm_slli_epi16(rev, 4); /* no byte carries into the next: rev < 16 */
    const __m128i low4 = _mm_set1_epi8(0x0f);
    x = _mm_shuffle_epi8(x, bswap);
    __m128i lo = _mm_and_si128(x, low4), hi = _mm_and_si128(_mm_srli_epi16(x, 4), low4);
    return _mm_or_si128(_mm_shuffle_epi8(to_high, lo), _mm_shuffle_epi8(rev, hi));
}

/* sampler_sobol1_rev in each lane. */
static inline SSE41 __m128i sobol1_rev4(__m128i x) {
    x = _mm_xor_si128(x, _mm_and_si128(_mm_srli_epi32(x, 1), _mm_set1_epi32(0x55555555)));
    x = _mm_xor_si128(x, _mm_and_si128(_mm_srli_epi32(x, 2), _mm_set1_epi32(0x33333333)));
    x = _mm_xor_si128(x, _mm_and_si128(_mm_srli_epi32(x, 4), _mm_set1_epi32(0x0f0f0f0f)));
    x = _mm_xor_si128(x, _mm_and_si128(_mm_srli_epi32(x, 8), _mm_set1_epi32(0x00ff00ff)));
    x = _mm_xor_si128(x, _mm_srli_epi32(x, 16));
    return x;
}

/* sampler_to_float in each lane: x >> 8 is below 2^24, so its conversion
 * as a signed integer is exact, as the scalar one is. */
static inline SSE41 __m128 to_float4(__m128i x) {
    return _mm_mul_ps(_mm_cvtepi32_ps(_mm_srli_epi32(x, 8)), _mm_set1_ps(0x1p-24f));
}

/* The inputs of the output scrambles of pairs first to first + 2 in lanes
 * 0 to 2 (lane 3 is computed and dropped), for the first numbers into *xa
 * and the second into *xb: sampler_pair_bits' padded path, the index
 * shuffled; under SOBOL_GLOBAL, for a pair below SAMPLER_GLOBAL_PAIRS, the
 * global point instead. px's seeds for the three pairs must be set. */
static inline __attribute__((always_inline)) SSE41 void bounce_inputs(const sampler_stream *s, uint32_t first, __m128i *xa, __m128i *xb) {
    const sampler_pixel *px = s->pixel;
    int global = s->kind == SAMPLER_SOBOL_GLOBAL ? (int)SAMPLER_GLOBAL_PAIRS - (int)first : 0; /* lanes */
    __m128i a = _mm_setzero_si128(), b = a;
    if (global < 3) {
        __m128i seed_index = _mm_loadu_si128((const __m128i *)&px->index_seed[first]);
        a = reverse4(lk_hash4(_mm_set1_epi32((int)s->index_rev), seed_index));
        b = sobol1_rev4(a);
    }
    if (global > 0) {
        uint64_t r = sampler_global_point(first, s->global_index);
        a = _mm_insert_epi32(a, (int)(uint32_t)r, 0), b = _mm_insert_epi32(b, (int)(r >> 32), 0);
    }
    if (global > 1) {
        uint64_t r = sampler_global_point(first + 1, s->global_index);
        a = _mm_insert_epi32(a, (int)(uint32_t)r, 1), b = _mm_insert_epi32(b, (int)(r >> 32), 1);
    }
    if (global > 2) {
        uint64_t r = sampler_global_point(first + 2, s->global_index);
        a = _mm_insert_epi32(a, (int)(uint32_t)r, 2), b = _mm_insert_epi32(b, (int)(r >> 32), 2);
    }
    *xa = a;
    *xb = b;
}

/* The numbers of pairs first to first + 2 into u, from the outputs' lanes
 * (lane i: pair first + i): u[2 i] from fa, u[2 i + 1] from fb. */
static inline SSE41 void bounce_store(__m128 fa, __m128 fb, float *u) {
    _mm_storeu_ps(u, _mm_unpacklo_ps(fa, fb));
    _mm_storeu_ps(u + 4, _mm_unpackhi_ps(fa, fb));
}

/* sampler_get_bounce from pair `first` on, with px's seeds for the three
 * pairs set and first + 3 <= SAMPLER_PIXEL_PAIRS: 4 lanes. */
static SSE41 void bounce_sse41(const sampler_stream *s, uint32_t first, float *u) {
    const sampler_pixel *px = s->pixel;
    /* A pair's hash holds its first output's seed in its low half and its
     * second's in its high half. */
    __m128 h01 = _mm_castsi128_ps(_mm_loadu_si128((const __m128i *)&px->hash[first]));
    __m128 h23 = _mm_castsi128_ps(_mm_loadu_si128((const __m128i *)&px->hash[first + 2]));
    __m128i seed_a = _mm_castps_si128(_mm_shuffle_ps(h01, h23, _MM_SHUFFLE(2, 0, 2, 0)));
    __m128i seed_b = _mm_castps_si128(_mm_shuffle_ps(h01, h23, _MM_SHUFFLE(3, 1, 3, 1)));
    __m128i xa, xb;
    bounce_inputs(s, first, &xa, &xb);
    bounce_store(to_float4(reverse4(lk_hash4(xa, seed_a))), to_float4(reverse4(lk_hash4(xb, seed_b))), u);
}

#define AVX2 __attribute__((target("avx2")))

/* bounce_sse41 with both outputs' scrambles in the 8 lanes of one AVX2
 * vector (lanes 0-3 the first numbers, 4-7 the second). */
static AVX2 void bounce_avx2(const sampler_stream *s, uint32_t first, float *u) {
    const sampler_pixel *px = s->pixel;
    __m256i h = _mm256_loadu_si256((const __m256i *)&px->hash[first]); /* the low halves, then the high */
    __m256i seed = _mm256_permutevar8x32_epi32(h, _mm256_setr_epi32(0, 2, 4, 6, 1, 3, 5, 7));
    __m128i xa, xb;
    bounce_inputs(s, first, &xa, &xb);
    __m256i x = _mm256_add_epi32(_mm256_set_m128i(xb, xa), seed);
    x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, _mm256_set1_epi32((int)0x6c50b47cu)));
    x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, _mm256_set1_epi32((int)0xb82f1e52u)));
    x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, _mm256_set1_epi32((int)0xc7afe638u)));
    x = _mm256_xor_si256(x, _mm256_mullo_epi32(x, _mm256_set1_epi32((int)0x8d22f6e6u)));
    /* reverse4 and to_float4 in both halves */
    const __m256i bswap = _mm256_setr_epi8(3, 2, 1, 0, 7, 6, 5, 4, 11, 10, 9, 8, 15, 14, 13, 12, 3, 2, 1, 0, 7, 6, 5,
                                           4, 11, 10, 9, 8, 15, 14, 13, 12);
    const __m256i rev = _mm256_setr_epi8(0, 8, 4, 12, 2, 10, 6, 14, 1, 9, 5, 13, 3, 11, 7, 15, 0, 8, 4, 12, 2, 10, 6,
                                         14, 1, 9, 5, 13, 3, 11, 7, 15);
    const __m256i to_high = _mm256_slli_epi16(rev, 4), low4 = _mm256_set1_epi8(0x0f);
    x = _mm256_shuffle_epi8(x, bswap);
    __m256i lo = _mm256_and_si256(x, low4), hi = _mm256_and_si256(_mm256_srli_epi16(x, 4), low4);
    x = _mm256_or_si256(_mm256_shuffle_epi8(to_high, lo), _mm256_shuffle_epi8(rev, hi));
    __m256 f = _mm256_mul_ps(_mm256_cvtepi32_ps(_mm256_srli_epi32(x, 8)), _mm256_set1_ps(0x1p-24f));
    bounce_store(_mm256_castps256_ps128(f), _mm256_extractf128_ps(f, 1), u);
}
#endif

/* Set px's seeds of pairs first to first + 2 that are not set yet, as
 * sampler_pair_seeds would on first use. Out of line, as is the pair by
 * pair path below: inlined, their registers made sampler_get_bounce save
 * six on every call. noipa, not just noinline: in a variant of this file
 * GCC 12.2 -O2 deleted the calls as if the function had no effect (the
 * cause was not pinned down; sampler_bounce_matches_pairs caught it). */
#if defined(__clang__)
#define NO_IPA __attribute__((noinline)) /* clang has no noipa (nor the analysis it stops) */
#else
#define NO_IPA __attribute__((noipa))
#endif
static NO_IPA void fill_seeds(const sampler_stream *s, uint32_t first) {
    for (uint32_t p = first; p < first + 3; p++) {
        uint32_t index_seed;
        sampler_pair_seeds(s, p, &index_seed);
    }
}

/* sampler_get_bounce pair by pair. */
static __attribute__((noinline)) void bounce_pairs(const sampler_stream *s, uint32_t dim, float u[8]) {
    for (uint32_t p = 0; p < 3; p++) sampler_get_2d(s, dim + 2 * p, &u[2 * p], &u[2 * p + 1]);
    u[6] = u[7] = 0.0f;
}

#if defined(__x86_64__) && defined(__GNUC__)
/* The widest bounce_* this CPU runs, or NULL: pair by pair. Chosen once,
 * before main; TESSERA_NO_AVX2 stops it at SSE4.1, as it stops the walks
 * at SSE (accel_wide.c), so that tests can run both on one machine. */
static void (*bounce_vector)(const sampler_stream *s, uint32_t first, float *u);

__attribute__((constructor)) static void choose_bounce(void) {
    __builtin_cpu_init(); /* constructors may run before libgcc's */
    if (!__builtin_cpu_supports("sse4.1")) return;
    bounce_vector = bounce_sse41;
    if (getenv("TESSERA_NO_AVX2") == NULL && __builtin_cpu_supports("avx2")) bounce_vector = bounce_avx2;
}
#endif

void sampler_get_bounce(const sampler_stream *s, uint32_t dim, float u[8]) {
    uint32_t first = dim >> 1;
#if defined(__x86_64__) && defined(__GNUC__)
    if (s->pixel && first + 3 <= SAMPLER_PIXEL_PAIRS && bounce_vector) {
        uint64_t want = 7ull << first;
        if ((s->pixel->filled & want) != want) fill_seeds(s, first);
        bounce_vector(s, first, u);
        return;
    }
#endif
    bounce_pairs(s, dim, u);
}
