/* vec.h - 3-vectors and the small amount of linear algebra the renderer needs.
 *
 * Everything is static inline and single precision: the hot loops (ray
 * traversal, shading) live on these. No function here can fail. Division by
 * zero is the caller's business: vec3_normalize() of the zero vector returns
 * NaNs, so callers that may see one check vec3_length() first. */
#ifndef TESSERA_VEC_H
#define TESSERA_VEC_H

#include <math.h>
#include <stdint.h>
#include <string.h>

#define TS_PI 3.14159265358979323846f
#define TS_INV_PI 0.31830988618379067154f

typedef struct {
    float x, y, z;
} vec3;

static inline vec3 vec3_make(float x, float y, float z) {
    vec3 v = {x, y, z};
    return v;
}
static inline vec3 vec3_splat(float s) { return vec3_make(s, s, s); }
static inline vec3 vec3_add(vec3 a, vec3 b) { return vec3_make(a.x + b.x, a.y + b.y, a.z + b.z); }
static inline vec3 vec3_sub(vec3 a, vec3 b) { return vec3_make(a.x - b.x, a.y - b.y, a.z - b.z); }
static inline vec3 vec3_mul(vec3 a, vec3 b) { return vec3_make(a.x * b.x, a.y * b.y, a.z * b.z); }
static inline vec3 vec3_scale(vec3 a, float s) { return vec3_make(a.x * s, a.y * s, a.z * s); }
static inline vec3 vec3_neg(vec3 a) { return vec3_make(-a.x, -a.y, -a.z); }
static inline float vec3_dot(vec3 a, vec3 b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
static inline vec3 vec3_cross(vec3 a, vec3 b) {
    return vec3_make(a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x);
}
static inline float vec3_length(vec3 a) { return sqrtf(vec3_dot(a, a)); }
static inline vec3 vec3_normalize(vec3 a) { return vec3_scale(a, 1.0f / vec3_length(a)); }
/* min/max as single instructions: without -ffast-math, fminf and fmaxf are
 * library calls (for their NaN rules), far too slow for ray traversal. These
 * return b when either argument is NaN. */
static inline float min_f(float a, float b) { return a < b ? a : b; }
static inline float max_f(float a, float b) { return a > b ? a : b; }
static inline vec3 vec3_min(vec3 a, vec3 b) { return vec3_make(min_f(a.x, b.x), min_f(a.y, b.y), min_f(a.z, b.z)); }
static inline vec3 vec3_max(vec3 a, vec3 b) { return vec3_make(max_f(a.x, b.x), max_f(a.y, b.y), max_f(a.z, b.z)); }
/* sqrt of x clamped at 0 (x < 0, -0 or NaN give +0): exactly
 * sqrtf(fmaxf(0.0f, x)) with glibc's fmaxf, without its library call. */
static inline float sqrt_clamped(float x) { return sqrtf(max_f(x, 0.0f)); }
/* c ? a : b without a branch: both a and b are computed anyway, and the
 * pick is a bit mask. For the picks that depend on random numbers (which
 * half of a warp, which side of zero), where a branch is mispredicted half
 * the time. The result is a or b bit for bit. */
static inline float select_f(int c, float a, float b) {
    uint32_t ia, ib, m = 0u - (uint32_t)(c != 0);
    memcpy(&ia, &a, sizeof ia);
    memcpy(&ib, &b, sizeof ib);
    uint32_t r = (ia & m) | (ib & ~m);
    float out;
    memcpy(&out, &r, sizeof out);
    return out;
}
static inline float vec3_max_comp(vec3 a) { return max_f(a.x, max_f(a.y, a.z)); }
static inline float vec3_comp(vec3 a, int axis) { return axis == 0 ? a.x : axis == 1 ? a.y : a.z; }
static inline int vec3_is_zero(vec3 a) { return a.x == 0.0f && a.y == 0.0f && a.z == 0.0f; }
static inline int vec3_is_finite(vec3 a) { return isfinite(a.x) && isfinite(a.y) && isfinite(a.z); }
/* Rec. 709 luminance, the weights the Reinhard operator uses. */
static inline float vec3_luminance(vec3 a) { return 0.2126f * a.x + 0.7152f * a.y + 0.0722f * a.z; }

/* An orthonormal basis around a unit normal n (Duff et al. 2017, "Building an
 * orthonormal basis, revisited"): branch-free apart from the sign and exact
 * for every unit n, including the poles. */
typedef struct {
    vec3 s, t, n;
} frame;

static inline frame frame_from_normal(vec3 n) {
    float sign = copysignf(1.0f, n.z);
    float a = -1.0f / (sign + n.z);
    float b = n.x * n.y * a;
    frame f;
    f.s = vec3_make(1.0f + sign * n.x * n.x * a, sign * b, -sign * n.x);
    f.t = vec3_make(b, sign + n.y * n.y * a, -n.y);
    f.n = n;
    return f;
}
static inline vec3 frame_to_local(const frame *f, vec3 v) {
    return vec3_make(vec3_dot(v, f->s), vec3_dot(v, f->t), vec3_dot(v, f->n));
}
static inline vec3 frame_to_world(const frame *f, vec3 v) {
    return vec3_add(vec3_add(vec3_scale(f->s, v.x), vec3_scale(f->t, v.y)), vec3_scale(f->n, v.z));
}

#endif
