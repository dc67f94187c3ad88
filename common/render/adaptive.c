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
    double *sum;      /* 3 per pixel: all samples */
    double *sum_late; /* 3 per pixel: samples [n/2, n), from the last round taken */
    uint32_t *n;      /* samples taken */
    float *err2;      /* estimated squared relative error, after its last round */
    uint8_t *active;  /* takes part in the next round */
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
    a->sum_late = calloc(3 * px, sizeof *a->sum_late);
    a->n = calloc(px, sizeof *a->n);
    a->err2 = calloc(px, sizeof *a->err2);
    a->active = malloc(px);
    if (!a->sum || !a->sum_late || !a->n || !a->err2 || !a->active) {
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
    free(a->sum_late);
    free(a->n);
    free(a->err2);
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

/* Estimated squared relative error of pixel i's mean (see adaptive.h):
 * from the halves A = [0, n/2) and B = [n/2, n), whose means differ by d,
 * Var(I) = sigma^2 / n is estimated by d^2 nA nB / n^2 (d^2 / 4 for equal
 * halves). Infinite with fewer than two samples. */
static float pixel_error2(const adaptive *a, size_t i) {
    uint32_t n = a->n[i], n_a = n / 2, n_b = n - n_a;
    if (n_a == 0) return INFINITY;
    double e2 = 0, halves = (double)n_a * n_b / ((double)n * n);
    for (int c = 0; c < 3; c++) {
        double s = a->sum[3 * i + c], late = a->sum_late[3 * i + c];
        double mean = s / n, d = (s - late) / n_a - late / n_b;
        e2 += d * d * halves / (mean * mean + 0.01);
    }
    return (float)(e2 / 3.0);
}

/* Whether pixel (x, y) has not converged: the mean of the squared error
 * estimates over its 3x3 neighbourhood (one estimate alone is too noisy to
 * act on) above threshold^2 * n / spp. The factor n / spp makes the rule
 * spend samples where they lower the image's MSE most: a pixel stops once
 * sigma^2 / (n w) <= t^2 n / spp, at n proportional to sigma / sqrt(w)
 * (w = I^2 + 0.01), the allocation that minimises the relative MSE for a
 * given budget; stopping at an equal error everywhere (n proportional to
 * sigma^2 / w) buys nothing over uniform sampling in MSE. A pixel that
 * stops early has error below threshold * sqrt(n / spp) < threshold. */
static int unconverged(const adaptive *a, int x, int y) {
    double sum = 0;
    int count = 0;
    for (int dy = -1; dy <= 1; dy++)
        for (int dx = -1; dx <= 1; dx++) {
            int qx = x + dx, qy = y + dy;
            if (qx < 0 || qy < 0 || qx >= a->width || qy >= a->height) continue;
            sum += a->err2[(size_t)qy * (size_t)a->width + (size_t)qx];
            count++;
        }
    size_t i = (size_t)y * (size_t)a->width + (size_t)x;
    double bound = a->threshold * a->threshold * a->n[i] / a->spp;
    return !(sum / count <= bound); /* NaN or infinity: not converged */
}

void adaptive_add_round(adaptive *a, const float *sums) {
    size_t px = (size_t)a->width * (size_t)a->height;
    uint32_t count = a->next_count;
    for (size_t i = 0; i < px; i++) {
        if (!a->active[i]) continue;
        for (int c = 0; c < 3; c++) {
            a->sum[3 * i + c] += sums[ADAPTIVE_CHANNELS * i + c];
            a->sum_late[3 * i + c] = sums[ADAPTIVE_CHANNELS * i + 3 + c];
        }
        a->n[i] += count;
        a->total += count;
    }
    for (size_t i = 0; i < px; i++)
        if (a->active[i]) a->err2[i] = pixel_error2(a, i);
    uint32_t n = a->next_first + count; /* what every active pixel now has */
    uint32_t next = n * 2 < (uint32_t)a->spp ? n * 2 : (uint32_t)a->spp;
    a->next_first = n;
    a->next_count = next - n;
    if (a->next_count == 0) {
        memset(a->active, 0, px);
        return;
    }
    /* A pixel goes on while it or a neighbour has not converged; stopped
     * pixels stay stopped (their estimates still count for neighbours).
     * Decisions read a->err2 and a->n only, never each other. */
    uint8_t *go = calloc(px, 1);
    for (int y = 0; y < a->height; y++)
        for (int x = 0; x < a->width; x++) {
            size_t i = (size_t)y * (size_t)a->width + (size_t)x;
            if (!a->active[i] || !unconverged(a, x, y)) continue;
            for (int dy = -1; dy <= 1; dy++)
                for (int dx = -1; dx <= 1; dx++) {
                    int qx = x + dx, qy = y + dy;
                    if (qx < 0 || qy < 0 || qx >= a->width || qy >= a->height) continue;
                    size_t q = (size_t)qy * (size_t)a->width + (size_t)qx;
                    if (go) go[q] = 1;
                }
        }
    for (size_t i = 0; i < px; i++) a->active[i] = a->active[i] && (!go || go[i]);
    free(go);
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
