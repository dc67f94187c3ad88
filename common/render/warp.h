/* warp.h - maps from uniform numbers in [0,1)^2 to directions and points,
 * each with the density it produces. No function here can fail. */
#ifndef TESSERA_WARP_H
#define TESSERA_WARP_H

#include "vec.h"

/* sin and cos of x for |x| <= pi/4, as *s and *c: Cephes' minimax
 * polynomials for that interval (sinf.c, cosf.c), no range reduction. Only
 * IEEE multiplications and additions, so the same bits on every CPU and
 * with any libm (glibc picks its sincosf by CPU at run time); within 2 ulp
 * of the true values (tests/test_bsdf.c: warp_sincos_quarter_is_accurate).
 * Can't fail. */
static inline void warp_sincos_quarter(float x, float *s, float *c) {
    float z = x * x;
    *s = x + x * z * ((-1.9515295891e-4f * z + 8.3321608736e-3f) * z - 1.6666654611e-1f);
    *c = 1.0f - 0.5f * z + z * z * ((2.443315711809948e-5f * z - 1.388731625493765e-3f) * z + 4.166664568298827e-2f);
}

/* Cosine-weighted hemisphere around +z (Malley's method on the concentric
 * disk). pdf(w) = cos(theta) / pi. */
static inline vec3 warp_cosine_hemisphere(float u1, float u2) {
    float a = 2.0f * u1 - 1.0f, b = 2.0f * u2 - 1.0f;
    if (a == 0.0f && b == 0.0f) return vec3_make(0, 0, 1);
    /* The wedge |a| > |b| has radius a and angle phi = (pi/4) (b/a); the
     * other radius b and phi = pi/2 - (pi/4) (a/b), whose cos and sin are
     * the sin and cos of (pi/4) (a/b). Either way one quotient q in
     * [-1, 1], and the picks are made without a branch (which wedge is a
     * coin toss per sample). */
    int a_major = a * a > b * b;
    float r = select_f(a_major, a, b), q = select_f(a_major, b, a) / r, sin_q, cos_q;
    warp_sincos_quarter((TS_PI / 4.0f) * q, &sin_q, &cos_q);
    float x = r * select_f(a_major, cos_q, sin_q), y = r * select_f(a_major, sin_q, cos_q);
    return vec3_make(x, y, sqrt_clamped(1.0f - x * x - y * y));
}
static inline float warp_cosine_hemisphere_pdf(float cos_theta) {
    return cos_theta > 0.0f ? cos_theta * TS_INV_PI : 0.0f;
}

/* Power-cosine lobe around +z: pdf(w) = (n + 1) / (2 pi) cos^n(theta). */
static inline vec3 warp_power_cosine(float u1, float u2, float n) {
    float cos_t = powf(1.0f - u1, 1.0f / (n + 1.0f)); /* 1-u1 in (0,1]: never 0^x */
    float sin_t = sqrt_clamped(1.0f - cos_t * cos_t);
    float phi = 2.0f * TS_PI * u2;
    return vec3_make(sin_t * cosf(phi), sin_t * sinf(phi), cos_t);
}
static inline float warp_power_cosine_pdf(float cos_t, float n) {
    return cos_t > 0.0f ? (n + 1.0f) * (0.5f * TS_INV_PI) * powf(cos_t, n) : 0.0f;
}

/* Uniform point on a triangle, as barycentrics (b1, b2) of v1 and v2 (the
 * square-to-triangle map of Heitz 2019, no sqrt). pdf = 1 / area. */
static inline void warp_uniform_triangle(float u1, float u2, float *b1, float *b2) {
    /* Both halves, picked without a branch (a coin toss per sample). */
    int upper = u2 > u1;
    float h1 = 0.5f * u1, h2 = 0.5f * u2;
    *b1 = select_f(upper, h1, u1 - h2);
    *b2 = select_f(upper, u2 - h1, h2);
}

/* Uniform direction in the cone of half-angle acos(cos_max) around +z.
 * pdf = 1 / (2 pi (1 - cos_max)). */
static inline vec3 warp_uniform_cone(float u1, float u2, float cos_max) {
    float cos_t = 1.0f - u1 * (1.0f - cos_max);
    float sin_t = sqrt_clamped(1.0f - cos_t * cos_t);
    float phi = 2.0f * TS_PI * u2;
    return vec3_make(sin_t * cosf(phi), sin_t * sinf(phi), cos_t);
}

/* Uniform direction on the unit sphere. pdf = 1 / (4 pi). */
static inline vec3 warp_uniform_sphere(float u1, float u2) {
    float z = 1.0f - 2.0f * u1;
    float r = sqrt_clamped(1.0f - z * z);
    float phi = 2.0f * TS_PI * u2;
    return vec3_make(r * cosf(phi), r * sinf(phi), z);
}

/* The power heuristic (beta = 2) weight of a strategy with density pa
 * against one with density pb. */
static inline float mis_power(float pa, float pb) {
    float a = pa * pa, b = pb * pb;
    return a > 0.0f ? a / (a + b) : 0.0f;
}

#endif
