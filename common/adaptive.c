/* adaptive.c - the rounds, sums and decisions of adaptive sampling
 * (adaptive.h). Everything here is per pixel or per 3x3 neighbourhood of
 * the whole image, in a fixed order: nothing depends on tiles or threads. */
#include "adaptive.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

struct adaptive {
    int width, height, spp, min_spp;
    double threshold;
    double *sum;     /* 3 per pixel: all samples */
    double *sum_odd; /* 3 per pixel: odd sample indices */
    uint32_t *n;     /* samples taken */
    float *err;      /* estimated relative RMS error, after its last round */
    uint8_t *active; /* takes part in the next round */
    uint32_t next_first, next_count;
    uint64_t total;
};

adaptive *adaptive_new(int width, int height, int spp, int min_spp, double threshold) {
    adaptive *a = calloc(1, sizeof *a);
    size_t px = (size_t)width * (size_t)height;
    if (!a) return NULL;
    a->width = width;
    a->height = height;
    a->spp = spp;
    a->min_spp = min_spp < spp ? min_spp : spp;
    a->threshold = threshold;
    a->sum = calloc(3 * px, sizeof *a->sum);
    a->sum_odd = calloc(3 * px, sizeof *a->sum_odd);
    a->n = calloc(px, sizeof *a->n);
    a->err = calloc(px, sizeof *a->err);
    a->active = malloc(px);
    if (!a->sum || !a->sum_odd || !a->n || !a->err || !a->active) {
        adaptive_free(a);
        return NULL;
    }
    memset(a->active, 1, px);
    a->next_first = 0;
    a->next_count = (uint32_t)a->min_spp;
    return a;
}

void adaptive_free(adaptive *a) {
    if (!a) return;
    free(a->sum);
    free(a->sum_odd);
    free(a->n);
    free(a->err);
    free(a->active);
    free(a);
}

long adaptive_next_round(adaptive *a, uint32_t *first, uint32_t *count, uint8_t *mask) {
    size_t px = (size_t)a->width * (size_t)a->height;
    long active = 0;
    for (size_t i = 0; i < px; i++) active += mask[i] = a->active[i];
    *first = a->next_first;
    *count = a->next_count;
    return a->next_count ? active : 0;
}

/* Estimated relative RMS error of pixel i (see adaptive.h); infinite with
 * fewer than two samples, when there are no halves to compare. */
static float pixel_error(const adaptive *a, size_t i) {
    uint32_t n = a->n[i], n_odd = n / 2, n_even = n - n_odd;
    if (n_odd == 0) return INFINITY;
    double e2 = 0;
    for (int c = 0; c < 3; c++) {
        double s = a->sum[3 * i + c], odd = a->sum_odd[3 * i + c];
        double mean = s / n, d = (s - odd) / n_even - odd / n_odd;
        e2 += d * d / 4.0 / (mean * mean + 0.01);
    }
    return (float)sqrt(e2 / 3.0);
}

/* The largest error in the 3x3 neighbourhood of (x, y), clipped at the
 * image's border. */
static float neighbourhood_error(const adaptive *a, int x, int y) {
    float worst = 0.0f;
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int qx = x + dx, qy = y + dy;
            if (qx < 0 || qy < 0 || qx >= a->width || qy >= a->height) continue;
            float e = a->err[(size_t)qy * (size_t)a->width + (size_t)qx];
            if (!(e <= worst)) worst = e; /* NaN-proof: anything not <= worst wins */
        }
    return worst;
}

void adaptive_add_round(adaptive *a, const float *sums) {
    size_t px = (size_t)a->width * (size_t)a->height;
    uint32_t count = a->next_count;
    for (size_t i = 0; i < px; i++) {
        if (!a->active[i]) continue;
        for (int c = 0; c < 3; c++) {
            a->sum[3 * i + c] += sums[ADAPTIVE_CHANNELS * i + c];
            a->sum_odd[3 * i + c] += sums[ADAPTIVE_CHANNELS * i + 3 + c];
        }
        a->n[i] += count;
        a->total += count;
        a->err[i] = pixel_error(a, i);
    }
    uint32_t n = a->next_first + count; /* what every active pixel now has */
    uint32_t next = n * 2 < (uint32_t)a->spp ? n * 2 : (uint32_t)a->spp;
    a->next_first = n;
    a->next_count = next - n;
    /* A decision reads the errors and the pixel's own flag only, so
     * deciding in place is the same as deciding from a copy. */
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            size_t i = (size_t)y * (size_t)a->width + (size_t)x;
            if (a->next_count == 0 || neighbourhood_error(a, x, y) <= a->threshold) a->active[i] = 0;
        }
}

void adaptive_result(const adaptive *a, float *rgb, float *samples) {
    size_t px = (size_t)a->width * (size_t)a->height;
    for (size_t i = 0; i < px; i++) {
        double inv = a->n[i] ? 1.0 / a->n[i] : 0.0;
        for (int c = 0; c < 3; c++) rgb[3 * i + c] = (float)(a->sum[3 * i + c] * inv);
        if (samples) samples[i] = (float)a->n[i];
    }
}

uint64_t adaptive_total_samples(const adaptive *a) { return a->total; }
