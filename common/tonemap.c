/* tonemap.c - tone mapping operators and the sRGB encoding. */
#include "tonemap.h"

#include <math.h>

float tonemap_reinhard(float L) { return L > 0.0f ? L / (1.0f + L) : 0.0f; }

float tonemap_srgb_encode(float c) {
    if (!(c > 0.0f)) return 0.0f;
    if (c >= 1.0f) return 1.0f;
    return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1.0f / 2.4f) - 0.055f;
}

static uint8_t to_byte(float display) { return (uint8_t)lrintf(tonemap_srgb_encode(display) * 255.0f); }

size_t tonemap_to_8bit(const float *rgb, size_t count, const tonemap_options *opt, uint8_t *out) {
    float gain = exp2f(opt->exposure_stops);
    size_t bad = 0;
    for (size_t i = 0; i < count; i++) {
        float c[3] = {rgb[3 * i] * gain, rgb[3 * i + 1] * gain, rgb[3 * i + 2] * gain};
        if (!isfinite(c[0]) || !isfinite(c[1]) || !isfinite(c[2])) {
            bad++;
            c[0] = c[1] = c[2] = 0.0f;
        }
        if (opt->kind == TONEMAP_REINHARD) {
            float L = 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2];
            float scale = L > 0.0f ? tonemap_reinhard(L) / L : 0.0f;
            for (int k = 0; k < 3; k++) c[k] *= scale;
        }
        for (int k = 0; k < 3; k++) out[3 * i + k] = to_byte(c[k]);
    }
    return bad;
}
