/* tonemap.c - tone mapping operators and the sRGB encoding. */
#include "tonemap.h"

#include <math.h>
#include <string.h>

float tonemap_reinhard(float L) { return L > 0.0f ? L / (1.0f + L) : 0.0f; }

float tonemap_reinhard_extended(float L, float Lw) {
    if (!(L > 0.0f)) return 0.0f;
    if (!(Lw > 0.0f) || !isfinite(Lw)) return tonemap_reinhard(L);
    return L * (1.0f + L / (Lw * Lw)) / (1.0f + L);
}

float tonemap_aces(float x) {
    if (!(x > 0.0f)) return 0.0f;
    float y = (x * (2.51f * x + 0.03f)) / (x * (2.43f * x + 0.59f) + 0.14f);
    return y < 1.0f ? y : 1.0f;
}

float tonemap_srgb_encode(float c) {
    if (!(c > 0.0f)) return 0.0f;
    if (c >= 1.0f) return 1.0f;
    return c <= 0.0031308f ? 12.92f * c : 1.055f * powf(c, 1.0f / 2.4f) - 0.055f;
}

int tonemap_parse(const char *name, tonemap_kind *out) {
    static const char *const names[] = {"reinhard", "reinhard-extended", "photographic", "aces", "clamp"};
    for (int i = 0; i < 5; i++)
        if (strcmp(name, names[i]) == 0) {
            *out = (tonemap_kind)i;
            return 0;
        }
    return -1;
}

static float luminance(const float *c) { return 0.2126f * c[0] + 0.7152f * c[1] + 0.0722f * c[2]; }

static int finite3(const float *c) { return isfinite(c[0]) && isfinite(c[1]) && isfinite(c[2]); }

/* Image statistics the global operators need: maximum luminance and the
 * log-average luminance (exp of the mean of log(delta + L)), over finite
 * pixels, after the exposure gain. */
static void image_stats(const float *rgb, size_t count, float gain, float *max_L, float *log_avg) {
    double sum = 0, mx = 0;
    size_t n = 0;
    for (size_t i = 0; i < count; i++) {
        const float *c = rgb + 3 * i;
        if (!finite3(c)) continue;
        double L = fmax(0.0, (double)luminance(c) * gain);
        mx = fmax(mx, L);
        sum += log(1e-4 + L);
        n++;
    }
    *max_L = (float)mx;
    *log_avg = n ? (float)exp(sum / (double)n) : 1.0f;
}

/* Store a display value, sRGB encoded and rounded, as 8 or 16 bits. */
static void store(void *out, size_t i, int bits, float display) {
    float v = tonemap_srgb_encode(display);
    if (bits == 16)
        ((uint16_t *)out)[i] = (uint16_t)lrintf(v * 65535.0f);
    else
        ((uint8_t *)out)[i] = (uint8_t)lrintf(v * 255.0f);
}

size_t tonemap_to_8bit(const float *rgb, size_t count, const tonemap_options *opt, uint8_t *out) {
    return tonemap_encode(rgb, count, opt, 8, out);
}

size_t tonemap_encode(const float *rgb, size_t count, const tonemap_options *opt, int bits, void *out) {
    float gain = exp2f(opt->exposure_stops), max_L = 0, log_avg = 1;
    if (opt->kind == TONEMAP_REINHARD_EXTENDED || opt->kind == TONEMAP_PHOTOGRAPHIC)
        image_stats(rgb, count, gain, &max_L, &log_avg);
    float key_scale = opt->kind == TONEMAP_PHOTOGRAPHIC ? 0.18f / log_avg : 1.0f;
    float white = opt->white > 0.0f ? opt->white : max_L * key_scale;
    size_t bad = 0;
    for (size_t i = 0; i < count; i++) {
        float c[3] = {rgb[3 * i] * gain, rgb[3 * i + 1] * gain, rgb[3 * i + 2] * gain};
        if (!finite3(c)) {
            bad++;
            c[0] = c[1] = c[2] = 0.0f;
        }
        float L = luminance(c) * key_scale, Lout = L;
        switch (opt->kind) {
        case TONEMAP_REINHARD: Lout = tonemap_reinhard(L); break;
        case TONEMAP_REINHARD_EXTENDED:
        case TONEMAP_PHOTOGRAPHIC: Lout = tonemap_reinhard_extended(L, white); break;
        case TONEMAP_ACES:
            for (int k = 0; k < 3; k++) c[k] = tonemap_aces(c[k]);
            break;
        case TONEMAP_CLAMP: break;
        }
        if (opt->kind != TONEMAP_ACES && opt->kind != TONEMAP_CLAMP) {
            /* Rescale the colour by Lout / L (black where L <= 0). */
            float scale = L > 0.0f ? Lout / L * key_scale : 0.0f;
            for (int k = 0; k < 3; k++) c[k] *= scale;
        }
        for (int k = 0; k < 3; k++) store(out, 3 * i + (size_t)k, bits, c[k]);
    }
    return bad;
}
