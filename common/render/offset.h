/* offset.h - where to start a ray that leaves a surface.
 *
 * Wächter and Binder, "A Fast and Robust Method for Avoiding
 * Self-Intersection" (Ray Tracing Gems, ch. 6): move the hit point a fixed
 * number of float ulps along the geometric normal, so the offset grows with
 * the point's magnitude exactly as its rounding error does; near the origin,
 * where ulps vanish, use a small fixed distance instead. The scene is in
 * internal units (about [-1, 1], see scene.h), so the constants suit every
 * scene whatever units it was modelled in. */
#ifndef TESSERA_OFFSET_H
#define TESSERA_OFFSET_H

#include <stdint.h>
#include <string.h>

#include "vec.h"

#define OFFSET_ORIGIN (1.0f / 32.0f)
#define OFFSET_FLOAT_SCALE (1.0f / 65536.0f)
#define OFFSET_INT_SCALE 256.0f

/* One coordinate: p moved by OFFSET_INT_SCALE n ulps away from zero's side
 * (or by OFFSET_FLOAT_SCALE n near the origin). offset_ray_origin does the
 * same to three at once. */
static inline float offset_one(float p, float n) {
    /* The integer step in unsigned arithmetic: it wraps (for p = -0, whose
     * bits are INT32_MIN, moved inward) where a signed sum would overflow;
     * the wrapped value is never picked, the near-origin one is. */
    uint32_t bits, of = (uint32_t)(int32_t)(OFFSET_INT_SCALE * n);
    memcpy(&bits, &p, sizeof bits);
    bits += p < 0.0f ? 0u - of : of;
    float moved;
    memcpy(&moved, &bits, sizeof moved);
    /* Picked without a branch: hit points near a coordinate plane through
     * the origin are common in scenes centred on it. */
    return select_f(fabsf(p) < OFFSET_ORIGIN, p + OFFSET_FLOAT_SCALE * n, moved);
}

typedef float offset_v4f __attribute__((vector_size(16)));
typedef uint32_t offset_v4u __attribute__((vector_size(16)));
typedef int32_t offset_v4i __attribute__((vector_size(16)));

/* p moved off its surface to the side n points to (n: unit geometric normal
 * on the side the new ray leaves by): offset_one on each coordinate, the
 * three in the lanes of one vector (the same IEEE operations, the
 * conversion truncating as the scalar cast does, the integer step
 * unsigned and wrapping as the scalar one). A few
 * vector instructions instead of some sixty scalar ones. Can't fail. */
static inline vec3 offset_ray_origin(vec3 p, vec3 n) {
    offset_v4f pv = {p.x, p.y, p.z, 0.0f}, nv = {n.x, n.y, n.z, 0.0f};
    offset_v4u of = (offset_v4u)__builtin_convertvector(OFFSET_INT_SCALE * nv, offset_v4i);
    offset_v4u neg = (offset_v4u)(pv < 0.0f); /* all ones where p < 0 */
    offset_v4u moved = (offset_v4u)pv + ((of ^ neg) - neg);
    offset_v4f abs_p = (offset_v4f)((offset_v4u)pv & 0x7fffffffu);
    offset_v4u near = (offset_v4u)(abs_p < OFFSET_ORIGIN);
    offset_v4u nudged = (offset_v4u)(pv + OFFSET_FLOAT_SCALE * nv);
    offset_v4f r = (offset_v4f)((nudged & near) | (moved & ~near));
    return vec3_make(r[0], r[1], r[2]);
}

#endif
