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

/* Column k (the index's bit k) of Sobol dimension dim's generator matrix,
 * bit-reversed, dim < 2 * SAMPLER_GLOBAL_PAIRS: Joe and Kuo's direction
 * numbers (new-joe-kuo-6.21201, dimensions 1 to 12), generated by their
 * recurrence; the definition sampler_tables.c's nibble tables were
 * generated from, kept here to check them. Can't fail. */
static inline uint32_t sobol_rev_col(uint32_t dim, uint32_t k) {
    static const uint32_t cols[2 * SAMPLER_GLOBAL_PAIRS][32] = {
        {0x00000001u, 0x00000002u, 0x00000004u, 0x00000008u, 0x00000010u, 0x00000020u, 0x00000040u, 0x00000080u, 0x00000100u, 0x00000200u, 0x00000400u, 0x00000800u, 0x00001000u, 0x00002000u, 0x00004000u, 0x00008000u, 0x00010000u, 0x00020000u, 0x00040000u, 0x00080000u, 0x00100000u, 0x00200000u, 0x00400000u, 0x00800000u, 0x01000000u, 0x02000000u, 0x04000000u, 0x08000000u, 0x10000000u, 0x20000000u, 0x40000000u, 0x80000000u},
        {0x00000001u, 0x00000003u, 0x00000005u, 0x0000000fu, 0x00000011u, 0x00000033u, 0x00000055u, 0x000000ffu, 0x00000101u, 0x00000303u, 0x00000505u, 0x00000f0fu, 0x00001111u, 0x00003333u, 0x00005555u, 0x0000ffffu, 0x00010001u, 0x00030003u, 0x00050005u, 0x000f000fu, 0x00110011u, 0x00330033u, 0x00550055u, 0x00ff00ffu, 0x01010101u, 0x03030303u, 0x05050505u, 0x0f0f0f0fu, 0x11111111u, 0x33333333u, 0x55555555u, 0xffffffffu},
        {0x00000001u, 0x00000003u, 0x00000006u, 0x00000009u, 0x00000017u, 0x0000003au, 0x00000071u, 0x000000a3u, 0x00000116u, 0x00000339u, 0x00000677u, 0x000009aau, 0x00001601u, 0x00003903u, 0x00007706u, 0x0000aa09u, 0x00010117u, 0x0003033au, 0x00060671u, 0x000909a3u, 0x00171616u, 0x003a3939u, 0x00717777u, 0x00a3aaaau, 0x01170001u, 0x033a0003u, 0x06710006u, 0x09a30009u, 0x16160017u, 0x3939003au, 0x77770071u, 0xaaaa00a3u},
        {0x00000001u, 0x00000003u, 0x00000004u, 0x0000000au, 0x0000001fu, 0x0000002eu, 0x00000045u, 0x000000c9u, 0x0000011bu, 0x000002a4u, 0x0000079au, 0x00000b67u, 0x0000101eu, 0x0000302du, 0x00004041u, 0x0000a0c3u, 0x0001f104u, 0x0002e28au, 0x000457dfu, 0x000c9baeu, 0x0011a105u, 0x002a7289u, 0x0079e7dbu, 0x00b6dba4u, 0x0100011au, 0x030002a7u, 0x0400079eu, 0x0a000b6du, 0x1f001001u, 0x2e003003u, 0x45004004u, 0xc900a00au},
        {0x00000001u, 0x00000002u, 0x00000004u, 0x0000000du, 0x0000001fu, 0x0000003bu, 0x0000005eu, 0x000000b9u, 0x0000015au, 0x000003f4u, 0x00000685u, 0x00000d0fu, 0x0000115bu, 0x000023f6u, 0x00004681u, 0x0000dd02u, 0x0001e144u, 0x000393cdu, 0x0005a6dfu, 0x000b4dbbu, 0x0014401eu, 0x003cd039u, 0x006df05au, 0x00dbb0b4u, 0x0101e145u, 0x020393cfu, 0x0405a6dbu, 0x0d0b4db6u, 0x1f144001u, 0x3b3cd002u, 0x5e6df004u, 0xb9dbb00du},
        {0x00000001u, 0x00000002u, 0x00000006u, 0x0000000cu, 0x00000013u, 0x00000024u, 0x0000006au, 0x000000dfu, 0x00000107u, 0x0000020eu, 0x00000615u, 0x00000c28u, 0x00001379u, 0x000024fbu, 0x00006b6du, 0x0000ddd1u, 0x00010012u, 0x00020026u, 0x0006006cu, 0x000c00d3u, 0x00130114u, 0x0024022au, 0x006a067fu, 0x00df0cf7u, 0x0107127eu, 0x020e26f5u, 0x06156d78u, 0x0c28d1f9u, 0x1378136bu, 0x24f924ddu, 0x6b6b6b01u, 0xdddddd02u},
        {0x00000001u, 0x00000003u, 0x00000005u, 0x0000000bu, 0x0000001au, 0x00000029u, 0x0000007cu, 0x000000c7u, 0x0000017du, 0x000003c4u, 0x00000478u, 0x000008cfu, 0x00001e62u, 0x000021e6u, 0x0000621eu, 0x0000e621u, 0x00011e63u, 0x000321e5u, 0x0005621bu, 0x000be62au, 0x001b1e79u, 0x002a21ccu, 0x00796267u, 0x00cce6edu, 0x01661f04u, 0x03ee2208u, 0x0401661fu, 0x0803ee22u, 0x1f040166u, 0x220803eeu, 0x661f0401u, 0xee220803u},
        {0x00000001u, 0x00000002u, 0x00000005u, 0x0000000au, 0x00000011u, 0x00000024u, 0x00000048u, 0x000000b4u, 0x0000016eu, 0x00000279u, 0x00000410u, 0x00000826u, 0x0000144du, 0x000028beu, 0x0000457fu, 0x0000925du, 0x00012458u, 0x0002d892u, 0x0005ad23u, 0x0009cec7u, 0x0010016fu, 0x0020027bu, 0x00500415u, 0x00a0082cu, 0x0110145cu, 0x0240289au, 0x04804537u, 0x0b4092e9u, 0x16e12536u, 0x2792daebu, 0x4105a933u, 0x8269c6e1u},
        {0x00000001u, 0x00000002u, 0x00000005u, 0x0000000au, 0x00000014u, 0x0000002bu, 0x00000056u, 0x0000008eu, 0x0000011cu, 0x0000021au, 0x00000457u, 0x0000088cu, 0x00001519u, 0x00002a10u, 0x00005443u, 0x0000a4a7u, 0x00014d4fu, 0x0002129eu, 0x0004255fu, 0x0008cebdu, 0x00101518u, 0x00202a12u, 0x00505446u, 0x00a0a4adu, 0x01414d5bu, 0x02b212b5u, 0x05642509u, 0x08e8ce33u, 0x11d01404u, 0x21802808u, 0x45205011u, 0x8860ac21u},
        {0x00000001u, 0x00000002u, 0x00000007u, 0x0000000du, 0x00000019u, 0x00000029u, 0x00000051u, 0x000000dau, 0x000001ccu, 0x0000039bu, 0x0000044eu, 0x000008fcu, 0x00001d83u, 0x00003765u, 0x000061cau, 0x0000af94u, 0x00015c50u, 0x000354d8u, 0x000749cbu, 0x000eff96u, 0x00101c57u, 0x002034d5u, 0x007065d2u, 0x00d0a7bfu, 0x01914006u, 0x0293600fu, 0x05172c1eu, 0x0dae5824u, 0x1cd15c48u, 0x399354f3u, 0x4497499du, 0x8f1eff41u},
        {0x00000001u, 0x00000002u, 0x00000005u, 0x00000008u, 0x00000010u, 0x00000036u, 0x00000079u, 0x000000c4u, 0x000001eau, 0x000003b5u, 0x000005feu, 0x00000b89u, 0x00001192u, 0x00002b73u, 0x00005011u, 0x0000f034u, 0x0001b07cu, 0x0003e8ccu, 0x00060dfau, 0x000d1f83u, 0x0011b187u, 0x0023eb4du, 0x00560878u, 0x008d14c6u, 0x0111a1efu, 0x0343c3bdu, 0x07c65deeu, 0x0ccdefbfu, 0x1fb001ebu, 0x381003b7u, 0x582005fbu, 0xb4500b81u},
        {0x00000001u, 0x00000002u, 0x00000004u, 0x0000000cu, 0x0000001au, 0x00000035u, 0x00000069u, 0x000000d4u, 0x0000012bu, 0x00000290u, 0x00000547u, 0x00000a4au, 0x00001472u, 0x000038e3u, 0x00007946u, 0x0000e648u, 0x0001c876u, 0x00038cefu, 0x0005195cu, 0x0009227du, 0x0011dc1fu, 0x0023b43bu, 0x00456077u, 0x00c9c4edu, 0x01b01558u, 0x03703a71u, 0x06d07c05u, 0x0d80ec0eu, 0x1311dc1eu, 0x2a53b439u, 0x52e56073u, 0xa9e9c4e1u},
    };
    return cols[dim][k];
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
        if (sh >> k & 1u) ra ^= sobol_rev_col(2 * pair, k), rb ^= sobol_rev_col(2 * pair + 1, k);
    *a = sampler_reverse_bits(sampler_lk_hash(ra, (uint32_t)h));
    *b = sampler_reverse_bits(sampler_lk_hash(rb, (uint32_t)(h >> 32)));
}

TEST(sampler_global_matches_definition) {
    for (uint32_t pair = 0; pair < SAMPLER_GLOBAL_PAIRS; pair++)
        for (uint32_t k = 0; k < 32; k++) {
            uint64_t r = sampler_global_point(pair, 1u << k);
            CHECK((uint32_t)r == sobol_rev_col(2 * pair, k) &&
                      (uint32_t)(r >> 32) == sobol_rev_col(2 * pair + 1, k),
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

/* The padded sampler's numbers by the definition, one 32-bit reversal at a
 * time (sampler.h reverses two at once). */
static void padded_pair_reference(const sampler_stream *s, uint32_t pair, uint32_t *a, uint32_t *b) {
    uint64_t h = sampler_hash(s->key, pair);
    uint32_t shuffled = sampler_reverse_bits(sampler_lk_hash(s->index_rev, (uint32_t)rng_mix64(h)));
    *a = sampler_reverse_bits(sampler_lk_hash(shuffled, (uint32_t)h));
    *b = sampler_reverse_bits(sampler_lk_hash(sampler_sobol1_rev(shuffled), (uint32_t)(h >> 32)));
}

TEST(sampler_paired_reversal_matches_single) {
    int bad = 0;
    uint64_t x = 1;
    for (int i = 0; i < 100000; i++) {
        x = rng_mix64(x + (uint64_t)i);
        uint32_t rx, ry;
        sampler_reverse_bits2((uint32_t)x, (uint32_t)(x >> 32), &rx, &ry);
        bad += rx != sampler_reverse_bits((uint32_t)x) || ry != sampler_reverse_bits((uint32_t)(x >> 32));
    }
    CHECK(bad == 0, "%d paired reversals differ", bad);
    for (uint64_t pixel = 0; pixel < 40; pixel++)
        for (uint32_t i = 0; i < 300; i += 7) {
            sampler_stream s = sampler_start(SAMPLER_SOBOL, 5, pixel * 977, i * 131u);
            sampler_stream g = sampler_start(SAMPLER_SOBOL_GLOBAL, 5, pixel * 977, i * 131u);
            for (uint32_t pair = 0; pair < 40; pair++) {
                uint32_t a, b, ra, rb;
                sampler_pair_bits(&s, pair, &a, &b);
                padded_pair_reference(&s, pair, &ra, &rb);
                bad += a != ra || b != rb;
                if (pair < SAMPLER_GLOBAL_PAIRS) continue; /* sobol-global pads the later pairs */
                sampler_pair_bits(&g, pair, &a, &b);
                padded_pair_reference(&g, pair, &ra, &rb);
                bad += a != ra || b != rb;
            }
        }
    CHECK(bad == 0, "%d padded pairs differ from the definition", bad);
}

/* A pixel's shared seeds change no number: streams started from a
 * sampler_pixel give the bits of sampler_start's, for every kind, for pairs
 * asked in any order, below and beyond the pairs it keeps. */
TEST(sampler_pixel_streams_match_plain_streams) {
    const sampler_kind kinds[] = {SAMPLER_SOBOL_GLOBAL, SAMPLER_SOBOL, SAMPLER_RANDOM};
    int bad = 0, checked = 0;
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++)
        for (uint64_t pixel = 0; pixel < 30; pixel++) {
            sampler_pixel px;
            sampler_pixel_start(&px, kinds[k], 7, pixel * 613);
            for (uint32_t i = 0; i < 40; i++) {
                sampler_stream c = sampler_start_pixel(&px, i), p = sampler_start(kinds[k], 7, pixel * 613, i);
                for (uint32_t j = 0; j < SAMPLER_PIXEL_PAIRS + 20; j++) {
                    uint32_t pair = (j * 37u + i) % (SAMPLER_PIXEL_PAIRS + 20), a, b, ra, rb;
                    sampler_pair_bits(&c, pair, &a, &b);
                    sampler_pair_bits(&p, pair, &ra, &rb);
                    bad += a != ra || b != rb;
                    checked++;
                }
            }
        }
    CHECK(bad == 0, "%d of %d pairs differ with the pixel's shared seeds", bad, checked);
}

/* sampler_get_bounce's six numbers are three sampler_get_2d calls' bit for
 * bit: every kind, pixel streams (the vector path where the CPU has one:
 * SSE4.1, or AVX2 unless TESSERA_NO_AVX2) and plain ones (pair by pair),
 * bounces whose seeds are kept or not yet, global and padded pairs mixed,
 * and dimensions past the pairs a sampler_pixel keeps. */
TEST(sampler_bounce_matches_pairs) {
    const sampler_kind kinds[] = {SAMPLER_SOBOL_GLOBAL, SAMPLER_SOBOL, SAMPLER_RANDOM};
    int bad = 0, checked = 0;
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++)
        for (uint64_t pixel = 0; pixel < 25; pixel++) {
            sampler_pixel px;
            sampler_pixel_start(&px, kinds[k], 11, pixel * 7919);
            for (uint32_t i = 0; i < 48; i++) {
                uint32_t sample = i * 2654435761u >> (i & 31);
                sampler_stream c = sampler_start_pixel(&px, sample), p = sampler_start(kinds[k], 11, pixel * 7919, sample);
                for (uint32_t j = 0; j < 80; j++) {
                    /* bounces in a shuffled order, every even dimension */
                    uint32_t dim = 2 * ((j * 29u + i) % 80u);
                    float u[8], w[8], want[6];
                    sampler_get_bounce(&c, dim, u);
                    sampler_get_bounce(&p, dim, w);
                    for (uint32_t d = 0; d < 6; d += 2) sampler_get_2d(&p, dim + d, &want[d], &want[d + 1]);
                    bad += memcmp(u, want, sizeof want) != 0 || memcmp(w, want, sizeof want) != 0;
                    checked++;
                }
            }
        }
    CHECK(bad == 0, "%d of %d bounces differ from their pairs", bad, checked);
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
