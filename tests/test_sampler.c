/* test_sampler.c - the Owen-scrambled Sobol sampler: its Sobol points, its
 * stratification, its independence across pixels and dimensions, and the
 * error it buys against independent random numbers. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "render/sampler.h"
#include "harness.h"

/* Sobol dimension 1 by its definition: XOR of generator columns v_i for the
 * set bits i of the index, v_0 = 2^31, v_i = v_{i-1} ^ (v_{i-1} >> 1). */
static uint32_t sobol1_reference(uint32_t index) {
    uint32_t x = 0, v = 0x80000000u;
    for (; index; index >>= 1, v ^= v >> 1)
        if (index & 1u) x ^= v;
    return x;
}

TEST(sampler_sobol_dimension_1_matches_definition) {
    for (uint32_t i = 0; i < 70000; i++) {
        uint32_t j = i * 2654435761u; /* and spread over all 32 bits */
        CHECK(sampler_reverse_bits(sampler_sobol1_rev(i)) == sobol1_reference(i), "index %u", i);
        CHECK(sampler_reverse_bits(sampler_sobol1_rev(j)) == sobol1_reference(j), "index %u", j);
    }
    /* the first points, indexed directly (not in Gray-code order) */
    const double want[] = {0, 0.5, 0.75, 0.25, 0.625, 0.125, 0.375, 0.875};
    for (uint32_t i = 0; i < 8; i++)
        CHECK(sobol1_reference(i) * 0x1p-32 == want[i], "point %u is %g", i, sobol1_reference(i) * 0x1p-32);
}

/* Count the points of the first n samples of a pixel, for the pair of
 * dimensions starting at dim, in each cell of a 2^a x 2^b grid; every cell
 * must hold exactly n / 2^(a+b). */
static int pair_is_stratified(uint64_t seed, uint64_t pixel, uint32_t dim, int log_n, char *why, size_t why_len) {
    int n = 1 << log_n;
    for (int a = 0; a <= log_n; a++) {
        int b = log_n - a, cells[1 << 12] = {0};
        for (int i = 0; i < n; i++) {
            sampler_stream s = sampler_start(SAMPLER_SOBOL, seed, pixel, (uint32_t)i);
            float u, v;
            sampler_get_2d(&s, dim, &u, &v);
            int cx = (int)(u * (float)(1 << a)), cy = (int)(v * (float)(1 << b));
            cells[cy * (1 << a) + cx]++;
        }
        for (int c = 0; c < n; c++)
            if (cells[c] != 1) {
                snprintf(why, why_len, "%d points, %dx%d cells: cell %d holds %d", n, 1 << a, 1 << b, c, cells[c]);
                return 0;
            }
    }
    return 1;
}

/* Every power-of-two prefix of every pair of dimensions is a (0,m,2)-net:
 * one point in each elementary interval of every shape. */
TEST(sampler_pairs_are_stratified) {
    char why[128];
    const uint32_t dims[] = {0, 2, 4, 10, 12, 50};
    for (size_t d = 0; d < sizeof dims / sizeof dims[0]; d++)
        for (uint64_t pixel = 0; pixel < 5; pixel++)
            for (int log_n = 1; log_n <= 10; log_n += 3)
                CHECK(pair_is_stratified(1 + pixel, pixel * 977, dims[d], log_n, why, sizeof why),
                      "dims %u,%u pixel %llu: %s", dims[d], dims[d] + 1, (unsigned long long)pixel, why);
}

/* Values stay in [0, 1), the 1D and 2D forms agree, and a stream is a pure
 * function of its arguments. */
TEST(sampler_streams_are_pure_functions) {
    for (int kind = 0; kind < 3; kind++) {
        sampler_stream a = sampler_start((sampler_kind)kind, 9, 31, 77), b = sampler_start((sampler_kind)kind, 9, 31, 77);
        for (uint32_t d = 0; d < 64; d++) {
            float x = sampler_get_1d(&a, d), y = sampler_get_1d(&b, d), u, v;
            sampler_get_2d(&b, d & ~1u, &u, &v);
            CHECK(memcmp(&x, &y, sizeof x) == 0, "kind %d dimension %u differs", kind, d);
            CHECK(memcmp(&x, d & 1u ? &v : &u, sizeof x) == 0, "kind %d dimension %u: 1D and 2D differ", kind, d);
            CHECK(x >= 0.0f && x < 1.0f, "value %g out of [0,1)", x);
        }
    }
}

/* Neighbouring pixels, different seeds and different pairs of dimensions are
 * decorrelated by the scrambling: correlation of 16384 paired values within
 * 5 sigma of 0, and the means 1/2 within 5 sigma of a random sequence (the
 * Sobol means are much closer, which is allowed). */
TEST(sampler_scrambles_decorrelate) {
    const int n = 16384;
    /* a: (seed, pixel, dim) of the first value; b: of the second */
    const uint64_t cases[][6] = {{1, 100, 0, 1, 101, 0}, {1, 100, 0, 2, 100, 0}, {1, 100, 2, 1, 100, 4},
                                 {1, 100, 0, 1, 100, 2}, {1, 100, 3, 1, 100, 9}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        double sxy = 0, sx = 0, sy = 0;
        for (int p = 0; p < n / 64; p++) /* 64 samples in each of 256 pixels */
            for (uint32_t i = 0; i < 64; i++) {
                sampler_stream a = sampler_start(SAMPLER_SOBOL, cases[c][0], cases[c][1] + 1000u * (uint64_t)p, i);
                sampler_stream b = sampler_start(SAMPLER_SOBOL, cases[c][3], cases[c][4] + 1000u * (uint64_t)p, i);
                double x = sampler_get_1d(&a, (uint32_t)cases[c][2]) - 0.5;
                double y = sampler_get_1d(&b, (uint32_t)cases[c][5]) - 0.5;
                sxy += x * y;
                sx += x;
                sy += y;
            }
        double sigma_mean = sqrt(1.0 / 12.0 / n), sigma_cov = (1.0 / 12.0) / sqrt(n);
        CHECK(fabs(sx / n) < 5 * sigma_mean && fabs(sy / n) < 5 * sigma_mean, "case %zu: biased mean", c);
        CHECK(fabs(sxy / n) < 5 * sigma_cov, "case %zu: correlation %g", c, sxy / n);
    }
}

/* What the sampler is for: estimating a smooth 2D integral per pixel
 * (here of cos(3u + 2v) e^v, known in closed form) with 64 samples gives a
 * mean squared error at least 10 times below independent random numbers
 * (theory: O(n^-3) against O(n^-1)), and still unbiased. */
TEST(sampler_sobol_beats_random_on_smooth_integrand) {
    /* Integral over [0,1]^2 of cos(3u + 2v) e^v du dv. With
     * F(v) = (sin(3 + 2v) - sin(2v)) / 3 it is the integral of F(v) e^v dv,
     * done here by a fine midpoint rule. */
    double exact = 0;
    const int m = 200000;
    for (int k = 0; k < m; k++) {
        double v = (k + 0.5) / m;
        exact += (sin(3 + 2 * v) - sin(2 * v)) / 3 * exp(v) / m;
    }
    double mse[3] = {0, 0, 0}, bias[3] = {0, 0, 0};
    const int pixels = 2000, spp = 64;
    for (int kind = 0; kind < 3; kind++)
        for (int p = 0; p < pixels; p++) {
            double sum = 0;
            for (int i = 0; i < spp; i++) {
                sampler_stream s = sampler_start((sampler_kind)kind, 5, (uint64_t)p, (uint32_t)i);
                float u, v;
                sampler_get_2d(&s, 6, &u, &v);
                sum += cos(3 * u + 2 * v) * exp(v);
            }
            double err = sum / spp - exact;
            mse[kind] += err * err / pixels;
            bias[kind] += err / pixels;
        }
    CHECK(mse[SAMPLER_SOBOL] * 10 < mse[SAMPLER_RANDOM], "sobol mse %g, random %g", mse[SAMPLER_SOBOL],
          mse[SAMPLER_RANDOM]);
    CHECK(fabs(bias[SAMPLER_SOBOL]) < 5 * sqrt(mse[SAMPLER_SOBOL] / pixels) + 1e-12, "sobol bias %g",
          bias[SAMPLER_SOBOL]);
    CHECK(fabs(bias[SAMPLER_RANDOM]) < 5 * sqrt(mse[SAMPLER_RANDOM] / pixels), "random bias %g", bias[SAMPLER_RANDOM]);
    CHECK(mse[SAMPLER_SOBOL_GLOBAL] * 10 < mse[SAMPLER_RANDOM], "sobol-global mse %g, random %g",
          mse[SAMPLER_SOBOL_GLOBAL], mse[SAMPLER_RANDOM]);
    CHECK(fabs(bias[SAMPLER_SOBOL_GLOBAL]) < 5 * sqrt(mse[SAMPLER_SOBOL_GLOBAL] / pixels) + 1e-12, "sobol-global bias %g",
          bias[SAMPLER_SOBOL_GLOBAL]);
}

/* What sobol-global is for: an integrand across two pairs, here the
 * indicator of u + v < 1 with u the first number of pair 2 (the first
 * bounce's BSDF direction) and v that of pair 4 (the second vertex's light
 * sample). Padded pairs are independent, so 256 samples per pixel give
 * the 1/N of independent numbers; sobol-global's dimensions 4 and 8 are
 * stratified together, at least 4 times better, and unbiased. Each of its
 * dimensions stays stratified on its own (2^k samples: one per 1/2^k). */
TEST(sampler_global_stratifies_across_pairs) {
    double mse[3] = {0, 0, 0}, bias[3] = {0, 0, 0};
    const int pixels = 1000, spp = 256;
    for (int kind = 0; kind < 3; kind++)
        for (int p = 0; p < pixels; p++) {
            double sum = 0;
            for (int i = 0; i < spp; i++) {
                sampler_stream s = sampler_start((sampler_kind)kind, 9, (uint64_t)p, (uint32_t)i);
                sum += sampler_get_1d(&s, 4) + sampler_get_1d(&s, 8) < 1.0f;
            }
            double err = sum / spp - 0.5;
            mse[kind] += err * err / pixels;
            bias[kind] += err / pixels;
        }
    printf("    u + v < 1 over pairs 2 and 4, %d spp: MSE sobol %.3g, sobol-global %.3g\n", spp, mse[SAMPLER_SOBOL],
           mse[SAMPLER_SOBOL_GLOBAL]);
    CHECK(mse[SAMPLER_SOBOL_GLOBAL] * 4 < mse[SAMPLER_SOBOL], "sobol-global mse %g, sobol %g",
          mse[SAMPLER_SOBOL_GLOBAL], mse[SAMPLER_SOBOL]);
    CHECK(fabs(bias[SAMPLER_SOBOL_GLOBAL]) < 5 * sqrt(mse[SAMPLER_SOBOL_GLOBAL] / pixels), "sobol-global bias %g",
          bias[SAMPLER_SOBOL_GLOBAL]);
    for (uint32_t dim = 0; dim < 2 * SAMPLER_GLOBAL_PAIRS; dim++) {
        int seen[64] = {0}, ok = 1;
        for (uint32_t i = 0; i < 64; i++) {
            sampler_stream s = sampler_start(SAMPLER_SOBOL_GLOBAL, 3, 77, i);
            int cell = (int)(sampler_get_1d(&s, dim) * 64);
            ok &= cell >= 0 && cell < 64 && !seen[cell]++;
        }
        CHECK(ok, "sobol-global dimension %u: 64 samples do not fill the 64 intervals", dim);
    }
}

/* Sobol-global's numbers by the definition: the pixel's index shuffle, the
 * index times each dimension's generator matrix one bit at a time, then the
 * dimension's Owen scramble. The sampler's nibble tables must agree. */
static void global_pair_reference(uint64_t seed, uint64_t pixel, uint32_t sample, uint32_t pair, uint32_t *a,
                                  uint32_t *b) {
    uint64_t key = rng_mix64(rng_mix64(seed) ^ pixel), h = sampler_hash(key, pair);
    uint32_t si = (uint32_t)rng_mix64(sampler_hash(key, 0xfffffffeu));
    uint32_t sh = sampler_reverse_bits(sampler_lk_hash(sampler_reverse_bits(sample), si)), ra = 0, rb = 0;
    for (uint32_t k = 0; k < 32; k++)
        if (sh >> k & 1u) ra ^= sampler_sobol_rev_col(2 * pair, k), rb ^= sampler_sobol_rev_col(2 * pair + 1, k);
    *a = sampler_reverse_bits(sampler_lk_hash(ra, (uint32_t)h));
    *b = sampler_reverse_bits(sampler_lk_hash(rb, (uint32_t)(h >> 32)));
}

TEST(sampler_global_matches_definition) {
    for (uint32_t pair = 0; pair < SAMPLER_GLOBAL_PAIRS; pair++)
        for (uint32_t k = 0; k < 32; k++) {
            uint64_t r = sampler_global_point(pair, 1u << k);
            CHECK((uint32_t)r == sampler_sobol_rev_col(2 * pair, k) &&
                      (uint32_t)(r >> 32) == sampler_sobol_rev_col(2 * pair + 1, k),
                  "pair %u, bit %u: table gives %016llx", pair, k, (unsigned long long)r);
        }
    int bad = 0;
    for (uint64_t seed = 0; seed < 3; seed++)
        for (uint64_t pixel = 0; pixel < 40; pixel++)
            for (uint32_t i = 0; i < 300; i += 7) {
                sampler_stream s = sampler_start(SAMPLER_SOBOL_GLOBAL, seed, pixel * 977, i * 131u + (uint32_t)seed);
                for (uint32_t pair = 0; pair < SAMPLER_GLOBAL_PAIRS; pair++) {
                    uint32_t a, b, ra, rb;
                    sampler_pair_bits(&s, pair, &a, &b);
                    global_pair_reference(seed, pixel * 977, i * 131u + (uint32_t)seed, pair, &ra, &rb);
                    bad += a != ra || b != rb;
                }
            }
    CHECK(bad == 0, "%d sobol-global pairs differ from the definition", bad);
}

TEST(sampler_names_parse) {
    sampler_kind k;
    CHECK(sampler_parse("sobol", &k) == 0 && k == SAMPLER_SOBOL, "sobol");
    CHECK(sampler_parse("random", &k) == 0 && k == SAMPLER_RANDOM, "random");
    CHECK(sampler_parse("sobol-global", &k) == 0 && k == SAMPLER_SOBOL_GLOBAL, "sobol-global");
    CHECK(sampler_parse("halton", &k) == -1, "halton accepted");
    CHECK(strcmp(sampler_name(SAMPLER_RANDOM), "random") == 0 && strcmp(sampler_name(SAMPLER_SOBOL), "sobol") == 0,
          "names");
}
