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

static inline float offset_one(float p, float n) {
    int32_t bits, of = (int32_t)(OFFSET_INT_SCALE * n);
    memcpy(&bits, &p, sizeof bits);
    bits += p < 0.0f ? -of : of;
    float moved;
    memcpy(&moved, &bits, sizeof moved);
    /* Picked without a branch: hit points near a coordinate plane through
     * the origin are common in scenes centred on it. */
    return select_f(fabsf(p) < OFFSET_ORIGIN, p + OFFSET_FLOAT_SCALE * n, moved);
}

/* p moved off its surface to the side n points to (n: unit geometric normal
 * on the side the new ray leaves by). Can't fail. */
static inline vec3 offset_ray_origin(vec3 p, vec3 n) {
    return vec3_make(offset_one(p.x, n.x), offset_one(p.y, n.y), offset_one(p.z, n.z));
}

#endif
