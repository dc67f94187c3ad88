/* adaptive.h - adaptive sampling: pixels stop taking samples once their
 * estimated error is below a threshold.
 *
 * A render proceeds in rounds over the whole image. Round 0 gives every
 * pixel samples [0, min_spp); each later round doubles the sample count of
 * the pixels still active, up to spp. After each round every pixel that
 * took part gets an error estimate from the two halves of its samples,
 * A = [0, n/2) and B = [n/2, n) (with the Sobol sampler each half is itself
 * a stratified set, so their difference measures the noise that is left):
 *
 *     I = S / n,   d = mean(A) - mean(B),
 *     err^2 = mean over r, g, b of d^2 |A||B| / n^2 / (I^2 + 0.01)
 *
 * d^2 |A||B| / n^2 estimates the variance of I, and the denominator is the
 * one of the benchmark's relative MSE, so err is the pixel's estimated
 * relative RMS error. A pixel has converged when the mean err^2 of its 3x3
 * neighbourhood is at most threshold^2 * n / spp (adaptive.c says why that
 * is the MSE-optimal rule; every early stop is below the threshold). A
 * pixel stays active while it or a neighbour has not converged: converged
 * regions have no hard edges. Decisions are made on the whole image between
 * rounds, from sums that do not depend on how the image was cut into tiles
 * or shared among threads and workers: the result is the same bytes for any
 * tiling, any worker count, any run.
 *
 * Who renders a round does not matter: the caller asks for the next round
 * (sample range and per-pixel mask), renders it with render_tile_sums()
 * (render.h) anywhere, and hands the sums back. */
#ifndef TESSERA_ADAPTIVE_H
#define TESSERA_ADAPTIVE_H

#include <stdint.h>

typedef struct adaptive adaptive;

/* Floats per pixel of a round's sums: r, g, b over all the round's samples
 * [first, first + count), then r, g, b over those with index >=
 * ADAPTIVE_SPLIT(first, count), the second half of [0, first + count). */
#define ADAPTIVE_CHANNELS 6
#define ADAPTIVE_SPLIT(first, count) (((first) + (count)) / 2)

/* Start an adaptive render of width x height pixels with at most spp and at
 * least min_spp samples per pixel (1 <= min_spp <= spp) and the relative
 * error threshold `threshold` (> 0). Returns NULL when out of memory. */
adaptive *adaptive_new(int width, int height, int spp, int min_spp, double threshold);

/* Free an adaptive render; NULL is allowed. */
void adaptive_free(adaptive *a);

/* The next round: sets *first and *count (its sample range) and mask (width
 * * height bytes, the caller's: 1 = render this pixel). Returns the number
 * of active pixels, 0 when the render is complete. */
long adaptive_next_round(adaptive *a, uint32_t *first, uint32_t *count, uint8_t *mask);

/* Add the round just handed out: sums holds ADAPTIVE_CHANNELS floats per
 * pixel for the whole image (ignored where the mask was 0). Updates the
 * counts, the error estimates and the next round's mask. Can't fail. */
void adaptive_add_round(adaptive *a, const float *sums);

/* The image so far: rgb gets width * height * 3 means; samples, if not
 * NULL, width * height sample counts. Can't fail. */
void adaptive_result(const adaptive *a, float *rgb, float *samples);

/* Samples taken so far over the whole image. Can't fail. */
uint64_t adaptive_total_samples(const adaptive *a);

#endif
