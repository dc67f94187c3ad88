/* render.h - the tile renderer every process runs, and a threaded renderer
 * of whole frames built on it.
 *
 * render_tile() is the unit of work of the whole system: a rectangle of
 * pixels and a range of sample indices. Each pixel's sum is accumulated in
 * double, in sample-index order, starting from what the accumulator already
 * holds; so rendering samples [0, 64) in one call, or [0, 16) then [16, 64)
 * into the same accumulator, gives the same bits, and no pixel depends on
 * any other pixel, tile, thread or process.
 *
 * Layer render/ (README "Where things are"): scene, shapes, accel, materials,
 * lights, camera, samplers, integrator, tiles, film; includes only common/. */
#ifndef TESSERA_RENDER_H
#define TESSERA_RENDER_H

#include <stdatomic.h>
#include <stdint.h>

#include "integrator.h"
#include "scene.h"

typedef struct {
    int x0, y0, x1, y1; /* half-open pixel rectangle */
} tile_rect;

static inline int tile_width(const tile_rect *t) { return t->x1 - t->x0; }
static inline int tile_height(const tile_rect *t) { return t->y1 - t->y0; }

/* Add samples [first, first + count) of every pixel of tile to accum, which
 * holds 3 doubles (r, g, b sums) per pixel, row-major over the tile. Counts
 * go to stats. Can't fail. */
void render_tile(const scene *s, const integrator_options *opt, const tile_rect *tile, uint32_t first,
                 uint32_t count, double *accum, trace_stats *stats);

/* Render samples [0, spp) of every pixel of tile, in `passes` sequential
 * calls of render_tile (the bits don't depend on passes), and store each
 * pixel's mean, (float)(sum * (1.0 / spp)), as 3 floats row-major over the
 * tile into rgb. accum is the caller's scratch of 3 doubles per pixel. This
 * is the one place a pixel's final value is computed, for the threaded
 * renderer and for farm workers alike. Returns 0; or -1 if cancel is not
 * NULL and was set (it is checked between rows), leaving rgb partial. */
int render_tile_means(const scene *s, const integrator_options *opt, const tile_rect *tile, int spp, int passes,
                      double *accum, float *rgb, trace_stats *stats, const atomic_int *cancel);

/* One adaptive round (adaptive.h) of a tile: for each pixel whose byte in
 * mask (tile-local, row-major) is set, the sums of samples [first, first +
 * count), ADAPTIVE_CHANNELS floats per pixel into out (tile-local): r, g, b
 * over all of them, then over those from ADAPTIVE_SPLIT(first, count) on;
 * zeros elsewhere.
 * Each pixel is summed in double in sample order and rounded once, so the
 * floats do not depend on tiling. Returns 0; or -1 if cancel is not NULL
 * and was set (checked between rows), leaving out partial. */
int render_tile_sums(const scene *s, const integrator_options *opt, const tile_rect *tile, uint32_t first,
                     uint32_t count, const uint8_t *mask, float *out, trace_stats *stats, const atomic_int *cancel);

/* Whether any pixel of t is set in mask (one byte per pixel of an image
 * `width` wide). Can't fail. */
int render_tile_has_active(const tile_rect *t, int width, const uint8_t *mask);

/* Split a width x height image into tile_size squares (clipped at the
 * edges), row by row. Returns the number of tiles; writes at most max of
 * them to out (out may be NULL to count). */
int render_split_tiles(int width, int height, int tile_size, tile_rect *out, int max);

/* For an adaptive round: idle[t] = 1 for each tile t of render_split_tiles
 * (width, height, tile_size) with no pixel set in mask, else 0 (idle holds
 * one byte per tile). Returns 0, or -1 when out of memory (idle untouched). */
int render_mark_idle_tiles(int width, int height, int tile_size, const uint8_t *mask, uint8_t *idle);

/* Called from the rendering threads' coordinator (the calling thread) about
 * ten times a second with tiles done so far; may be NULL. */
typedef void (*render_progress_cb)(void *ctx, int tiles_done, int tiles_total, const trace_stats *so_far);

typedef struct {
    int threads;   /* >= 1 */
    int tile_size; /* >= 1 */
    int passes;    /* split each pixel's samples into this many sequential calls (>= 1) */
    integrator_options integrator;
    render_progress_cb progress;
    void *progress_ctx;
    double noise_threshold; /* > 0: adaptive sampling (adaptive.h) to this relative error */
    int min_spp;            /* adaptive: samples every pixel takes first */
    float *samples;         /* adaptive: per-pixel sample counts out (width * height), or NULL */
} render_options;

/* Render s->settings.spp samples of every pixel (with noise_threshold > 0,
 * between min_spp and spp, adaptively) with a pool of threads and write the
 * mean radiance, 3 floats per pixel, row 0 at the top, into rgb
 * (width * height * 3 floats, the caller's). Returns 0, or -1 if the threads
 * or their memory could not be had (then rgb is unspecified). */
int render_frame(const scene *s, const render_options *opt, float *rgb, trace_stats *stats);

#endif
