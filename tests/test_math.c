/* test_math.c - vectors, frames, ray offsets, the counter-based RNG, camera mappings. */
#include <math.h>
#include <stdint.h>
#include <string.h>

#include "render/camera.h"
#include "render/offset.h"
#include "render/rng.h"
#include "vec.h"
#include "render/warp.h"
#include "harness.h"

TEST(math_frame_is_orthonormal) {
    vec3 ns[] = {{0, 0, 1}, {0, 0, -1}, {1, 0, 0}, {0.6f, 0.0f, -0.8f}, {0.267261f, 0.534522f, 0.801784f}};
    for (size_t i = 0; i < sizeof ns / sizeof ns[0]; i++) {
        vec3 n = vec3_normalize(ns[i]);
        frame f = frame_from_normal(n);
        CHECK(fabsf(vec3_dot(f.s, f.t)) < 1e-6f && fabsf(vec3_dot(f.s, n)) < 1e-6f, "frame %zu not orthogonal", i);
        CHECK(fabsf(vec3_length(f.s) - 1) < 1e-6f && fabsf(vec3_length(f.t) - 1) < 1e-6f, "frame %zu not unit", i);
        vec3 v = vec3_make(0.3f, -0.2f, 0.9f), back = frame_to_world(&f, frame_to_local(&f, v));
        CHECK(vec3_length(vec3_sub(v, back)) < 1e-6f, "frame %zu round trip", i);
    }
}

TEST(rng_same_counter_same_value) {
    rng_stream a = rng_stream_start(7, 1234, 56), b = rng_stream_start(7, 1234, 56);
    for (int d = 0; d < 100; d++) {
        float x = rng_next(&a), y = rng_next(&b);
        CHECK(memcmp(&x, &y, sizeof x) == 0, "dimension %d differs", d);
        CHECK(x >= 0.0f && x < 1.0f, "value %g out of [0,1)", x);
    }
    rng_stream c = rng_stream_start(7, 1234, 56);
    CHECK(rng_bits_at(&c, 42) == rng_bits_at(&a, 42), "random access differs from sequential");
}

/* Streams that differ in one of seed, pixel or sample are uncorrelated:
 * the correlation of 20000 paired values stays within 5 sigma of 0, and each
 * stream's mean is 1/2 within 5 sigma. */
TEST(rng_streams_are_independent) {
    const int n = 20000;
    uint64_t variants[3][3] = {{1, 100, 5}, {2, 100, 5}, {1, 101, 5}};
    for (int v = 0; v < 3; v++) {
        double sxy = 0, sx = 0, sy = 0;
        for (int i = 0; i < n; i++) {
            rng_stream a = rng_stream_start(1, 100, (uint64_t)i);
            rng_stream b = rng_stream_start(variants[v][0], variants[v][1], (uint64_t)i + (v == 0 ? 1 : 0));
            if (v == 0) b = rng_stream_start(1, 100, (uint64_t)i + 1000000);
            double x = rng_next(&a) - 0.5, y = rng_next(&b) - 0.5;
            sxy += x * y;
            sx += x;
            sy += y;
        }
        double sigma_mean = sqrt(1.0 / 12.0 / n), sigma_cov = (1.0 / 12.0) / sqrt(n);
        CHECK(fabs(sx / n) < 5 * sigma_mean && fabs(sy / n) < 5 * sigma_mean, "variant %d: biased mean", v);
        CHECK(fabs(sxy / n) < 5 * sigma_cov, "variant %d: correlation %g", v, sxy / n);
    }
    /* consecutive dimensions of one stream */
    double sxy = 0;
    for (int i = 0; i < n; i++) {
        rng_stream a = rng_stream_start(3, 9, (uint64_t)i);
        double x = rng_next(&a) - 0.5, y = rng_next(&a) - 0.5;
        sxy += x * y;
    }
    CHECK(fabs(sxy / n) < 5 * (1.0 / 12.0) / sqrt(n), "dimensions correlated: %g", sxy / n);
}

TEST(camera_environment_formula) {
    camera c = {.kind = CAMERA_ENVIRONMENT};
    int W = 64, H = 32;
    for (int y = 0; y < H; y += 5)
        for (int x = 0; x < W; x += 7) {
            float u = 0.25f, v = 0.75f;
            vec3 d = camera_direction(&c, W, H, x, y, u, v);
            double th = M_PI * (y + v) / H, ph = 2 * M_PI * (x + u) / W;
            CHECK(fabs(d.x - sin(th) * cos(ph)) < 1e-5 && fabs(d.y - cos(th)) < 1e-5 &&
                      fabs(d.z - sin(th) * sin(ph)) < 1e-5,
                  "pixel (%d,%d): got (%g,%g,%g)", x, y, d.x, d.y, d.z);
        }
    vec3 top = camera_direction(&c, W, H, 0, 0, 0, 0);
    CHECK(top.y > 0.999f, "row 0 must look up, got y=%g", top.y);
}

TEST(camera_perspective_mapping) {
    camera c = {.kind = CAMERA_PERSPECTIVE, .forward = {0, 0, 1}, .right = {-1, 0, 0}, .up = {0, 1, 0},
                .tan_half_fov = 1.0f}; /* 90 degrees */
    vec3 centre = camera_direction(&c, 100, 100, 50, 50, 0, 0);
    CHECK(vec3_length(vec3_sub(centre, c.forward)) < 1e-6f, "image centre is not the view direction");
    vec3 tl = camera_direction(&c, 100, 100, 0, 0, 0, 0);
    vec3 want = vec3_normalize(vec3_make(1, 1, 1)); /* left = -right = +x, top = +y */
    CHECK(vec3_length(vec3_sub(tl, want)) < 1e-5f, "top-left corner (%g,%g,%g)", tl.x, tl.y, tl.z);
    vec3 wide = camera_direction(&c, 200, 100, 200, 50, 0, 0);
    CHECK(fabsf(wide.x / wide.z + 2.0f) < 1e-5f, "aspect ratio not applied: %g", wide.x / wide.z);
}

/* offset_ray_origin moves the three coordinates exactly as offset_one
 * does each: bit for bit, on both sides of zero, near and far from the
 * origin, for signed zeros and for normals of every direction. */
TEST(offset_ray_origin_matches_offset_one) {
    const float special[] = {0.0f, -0.0f, 1e-30f, -1e-30f, 0.03125f, -0.03125f, 0.0312499f, -0.0312499f, 1.0f, -1.0f,
                             3.5e4f, -3.5e4f};
    int bad = 0, n_special = (int)(sizeof special / sizeof special[0]);
    rng_stream r = rng_stream_start(9, 0, 0);
    for (int i = 0; i < 200000; i++) {
        float c[3], m[3];
        for (int k = 0; k < 3; k++) {
            float u = rng_next(&r);
            c[k] = i % 4 == 0 ? special[(int)(u * (float)n_special) % n_special]
                              : (2.0f * rng_next(&r) - 1.0f) * (i % 4 == 1 ? 0.05f : 2.0f);
        }
        vec3 n = vec3_normalize(vec3_make(2.0f * rng_next(&r) - 1.0f, 2.0f * rng_next(&r) - 1.0f,
                                          2.0f * rng_next(&r) - 1.0f));
        m[0] = n.x, m[1] = n.y, m[2] = n.z;
        vec3 o = offset_ray_origin(vec3_make(c[0], c[1], c[2]), n);
        float got[3] = {o.x, o.y, o.z};
        for (int k = 0; k < 3; k++) {
            float want = offset_one(c[k], m[k]);
            bad += memcmp(&want, &got[k], sizeof want) != 0;
        }
    }
    CHECK(bad == 0, "%d coordinates differ from offset_one", bad);
}

TEST(warp_triangle_is_uniform) {
    /* The mean of uniform barycentrics is (1/3, 1/3); all stay inside. */
    double s1 = 0, s2 = 0;
    const int n = 40000;
    for (int i = 0; i < n; i++) {
        rng_stream r = rng_stream_start(5, 0, (uint64_t)i);
        float b1, b2, u1 = rng_next(&r), u2 = rng_next(&r);
        warp_uniform_triangle(u1, u2, &b1, &b2);
        CHECK(b1 >= 0 && b2 >= 0 && b1 + b2 <= 1.0f, "outside the triangle");
        s1 += b1;
        s2 += b2;
    }
    double sigma = sqrt(1.0 / 18.0 / n);
    CHECK(fabs(s1 / n - 1.0 / 3) < 5 * sigma && fabs(s2 / n - 1.0 / 3) < 5 * sigma, "means %g %g", s1 / n, s2 / n);
}
