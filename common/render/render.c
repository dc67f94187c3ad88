/* render.c - tiles of samples, and a thread pool that renders a frame.
 *
 * Threads take tiles from a shared atomic counter and write disjoint parts of
 * the output, so there is nothing to lock; their counters are summed after
 * they are joined. The calling thread reports progress meanwhile. */
#include "render.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "adaptive.h"
#include "camera.h"

/* Start px, the sampler's seeds shared by the samples of pixel (x, y). */
static inline void render_pixel_start(const scene *s, const integrator_options *opt, int x, int y,
                                      sampler_pixel *px) {
    const render_settings *rs = &s->settings;
    sampler_pixel_start(px, opt->sampler, rs->seed, (uint64_t)y * (uint64_t)rs->width + (uint64_t)x);
}

/* Sample i of pixel (x, y), whose sampler seeds px holds, ready to trace:
 * its sampler stream and the camera ray through its jittered position. */
typedef struct {
    sampler_stream rng;
    ray r;
} camera_sample;

static inline void render_camera_sample(const scene *s, const camera_raster *cr, int x, int y, uint32_t i,
                                        sampler_pixel *px, camera_sample *out) {
    out->rng = sampler_start_pixel(px, i);
    float u, v;
    sampler_get_2d(&out->rng, 0, &u, &v);
    out->r = (ray){s->cam.position, camera_raster_direction(cr, x, y, u, v), PRIM_NONE};
}

/* Add the radiances of samples first to first + count - 1 of pixel (x, y)
 * to sum[0..2], in order, and those from sample `split` on also to
 * late[0..2] when late is not NULL. Each sample's camera ray is made
 * before the sample ahead of it is traced, so that a path starts without
 * waiting on its ray's scramble, division and square root. */
static inline void render_pixel_samples(const scene *s, const integrator_options *opt, const camera_raster *cr,
                                        int x, int y, uint32_t first,
                                        uint32_t count, trace_stats *stats, double *sum, double *late,
                                        uint32_t split) {
    sampler_pixel px;
    render_pixel_start(s, opt, x, y, &px);
    camera_sample cam[2]; /* sample i's in cam[i & 1] */
    if (count) render_camera_sample(s, cr, x, y, first, &px, &cam[first & 1]);
    for (uint32_t i = first; i < first + count; i++) {
        if (i + 1 < first + count) render_camera_sample(s, cr, x, y, i + 1, &px, &cam[(i + 1) & 1]);
        vec3 L = integrator_radiance(s, opt, &cam[i & 1].r, &cam[i & 1].rng, stats);
        sum[0] += L.x;
        sum[1] += L.y;
        sum[2] += L.z;
        if (late && i >= split) {
            late[0] += L.x;
            late[1] += L.y;
            late[2] += L.z;
        }
    }
}

void render_tile(const scene *s, const integrator_options *opt, const tile_rect *tile, uint32_t first,
                 uint32_t count, double *accum, trace_stats *stats) {
    int tw = tile_width(tile);
    camera_raster cr;
    camera_raster_init(&cr, &s->cam, s->settings.width, s->settings.height);
    for (int y = tile->y0; y < tile->y1; y++) {
        for (int x = tile->x0; x < tile->x1; x++) {
            double *sum = accum + 3 * ((size_t)(y - tile->y0) * (size_t)tw + (size_t)(x - tile->x0));
            render_pixel_samples(s, opt, &cr, x, y, first, count, stats, sum, NULL, 0);
        }
    }
}

int render_tile_sums(const scene *s, const integrator_options *opt, const tile_rect *tile, uint32_t first,
                     uint32_t count, const uint8_t *mask, float *out, trace_stats *stats, const atomic_int *cancel) {
    int tw = tile_width(tile);
    camera_raster cr;
    camera_raster_init(&cr, &s->cam, s->settings.width, s->settings.height);
    for (int y = tile->y0; y < tile->y1; y++) {
        if (cancel && atomic_load_explicit(cancel, memory_order_relaxed)) return -1;
        for (int x = tile->x0; x < tile->x1; x++) {
            size_t k = (size_t)(y - tile->y0) * (size_t)tw + (size_t)(x - tile->x0);
            double sum[ADAPTIVE_CHANNELS] = {0};
            if (mask[k])
                render_pixel_samples(s, opt, &cr, x, y, first, count, stats, sum, sum + 3,
                                     ADAPTIVE_SPLIT(first, count));
            for (int c = 0; c < ADAPTIVE_CHANNELS; c++) out[ADAPTIVE_CHANNELS * k + (size_t)c] = (float)sum[c];
        }
    }
    return 0;
}

int render_split_tiles(int width, int height, int tile_size, tile_rect *out, int max) {
    int n = 0;
    for (int y = 0; y < height; y += tile_size)
        for (int x = 0; x < width; x += tile_size, n++) {
            if (!out || n >= max) continue;
            tile_rect t = {x, y, x + tile_size < width ? x + tile_size : width,
                           y + tile_size < height ? y + tile_size : height};
            out[n] = t;
        }
    return n;
}

/* One pass of the thread pool over a list of tiles: the whole frame's
 * means, or one adaptive round's sums. */
typedef struct {
    const scene *s;
    const render_options *opt;
    const tile_rect *tiles;
    int tile_count;
    float *rgb;           /* means: 3 floats per pixel of the frame */
    float *sums;          /* adaptive round: ADAPTIVE_CHANNELS floats per pixel, or NULL */
    const uint8_t *mask;  /* adaptive round: pixels taking part */
    uint32_t first, count; /* adaptive round: its sample range */
    atomic_int next_tile;
    atomic_int tiles_done;
    pthread_mutex_t lock; /* with all_done: the last tile wakes the reporting thread */
    pthread_cond_t all_done;
    atomic_ullong samples_done;
} frame_job;

typedef struct {
    frame_job *job;
    pthread_t thread;
    trace_stats stats;
    double *accum;   /* one row's sums, reused */
    float *scratch;  /* one tile's means or sums, reused */
    uint8_t *mask;   /* one tile's mask, reused */
} frame_worker;

int render_tile_means(const scene *s, const integrator_options *opt, const tile_rect *tile, int spp, int passes,
                      double *accum, float *rgb, trace_stats *stats, const atomic_int *cancel) {
    int tw = tile_width(tile);
    double inv = 1.0 / spp;
    for (int y = tile->y0; y < tile->y1; y++) {
        if (cancel && atomic_load_explicit(cancel, memory_order_relaxed)) return -1;
        tile_rect row = {tile->x0, y, tile->x1, y + 1};
        memset(accum, 0, 3 * (size_t)tw * sizeof(double));
        for (int p = 0; p < passes; p++) {
            uint32_t first = (uint32_t)((int64_t)spp * p / passes), end = (uint32_t)((int64_t)spp * (p + 1) / passes);
            render_tile(s, opt, &row, first, end - first, accum, stats);
        }
        float *out = rgb + 3 * (size_t)(y - tile->y0) * (size_t)tw;
        for (int i = 0; i < 3 * tw; i++) out[i] = (float)(accum[i] * inv);
    }
    return 0;
}

/* Copy a tile's rows of `channels` floats per pixel into the frame. */
static void frame_put(const frame_job *job, const tile_rect *t, const float *src, int channels, float *dst) {
    size_t tw = (size_t)tile_width(t), fw = (size_t)job->s->settings.width, ch = (size_t)channels;
    for (int y = t->y0; y < t->y1; y++)
        memcpy(dst + ch * ((size_t)y * fw + (size_t)t->x0), src + ch * (size_t)(y - t->y0) * tw,
               ch * sizeof(float) * tw);
}

/* Render one tile of the frame (all samples, or the round's) into it. */
static void frame_render_tile(frame_worker *w, const tile_rect *t) {
    frame_job *job = w->job;
    const scene *s = job->s;
    size_t n = (size_t)tile_width(t) * (size_t)tile_height(t), active = n;
    if (job->sums) {
        size_t fw = (size_t)s->settings.width, k = 0;
        active = 0;
        for (int y = t->y0; y < t->y1; y++)
            for (int x = t->x0; x < t->x1; x++, k++) active += w->mask[k] = job->mask[(size_t)y * fw + (size_t)x];
        render_tile_sums(s, &job->opt->integrator, t, job->first, job->count, w->mask, w->scratch, &w->stats, NULL);
        frame_put(job, t, w->scratch, ADAPTIVE_CHANNELS, job->sums);
    } else {
        render_tile_means(s, &job->opt->integrator, t, s->settings.spp, job->opt->passes, w->accum, w->scratch,
                          &w->stats, NULL);
        frame_put(job, t, w->scratch, 3, job->rgb);
    }
    uint64_t per_pixel = job->sums ? job->count : (uint64_t)s->settings.spp;
    atomic_fetch_add(&job->samples_done, (unsigned long long)(active * per_pixel));
}

static void *frame_thread(void *arg) {
    frame_worker *w = arg;
    frame_job *job = w->job;
    for (;;) {
        int i = atomic_fetch_add(&job->next_tile, 1);
        if (i >= job->tile_count) break;
        frame_render_tile(w, &job->tiles[i]);
        if (atomic_fetch_add(&job->tiles_done, 1) + 1 == job->tile_count) {
            pthread_mutex_lock(&job->lock);
            pthread_cond_signal(&job->all_done);
            pthread_mutex_unlock(&job->lock);
        }
    }
    return NULL;
}

/* Wait up to ms milliseconds for the frame's last tile (all_done). */
static void wait_done_ms(frame_job *job, long ms) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    ts.tv_sec += ms / 1000;
    ts.tv_nsec += (ms % 1000) * 1000000L;
    if (ts.tv_nsec >= 1000000000L) ts.tv_sec++, ts.tv_nsec -= 1000000000L;
    pthread_mutex_lock(&job->lock);
    while (atomic_load(&job->tiles_done) < job->tile_count)
        if (pthread_cond_timedwait(&job->all_done, &job->lock, &ts) != 0) break;
    pthread_mutex_unlock(&job->lock);
}

/* Run job's tiles on opt->threads threads; their counters are added to
 * stats. progress_done / progress_total: where this pass sits in the whole
 * render, for the progress callback. Returns 0, or -1 if the threads or
 * their memory could not be had. */
static int frame_run(frame_job *job, int tile_size, trace_stats *stats, int progress_base, int progress_total,
                     uint64_t samples_base) {
    const render_options *opt = job->opt;
    int threads = opt->threads > 0 ? opt->threads : 1;
    frame_worker *workers = calloc((size_t)threads, sizeof *workers);
    int started = 0, rc = workers ? 0 : -1;
    size_t px = (size_t)tile_size * (size_t)tile_size;
    atomic_init(&job->next_tile, 0);
    atomic_init(&job->tiles_done, 0);
    pthread_mutex_init(&job->lock, NULL);
    pthread_cond_init(&job->all_done, NULL);
    atomic_init(&job->samples_done, 0);
    for (int i = 0; i < threads && rc == 0; i++) {
        workers[i].job = job;
        workers[i].accum = malloc(3 * sizeof(double) * (size_t)tile_size);
        workers[i].scratch = malloc(ADAPTIVE_CHANNELS * sizeof(float) * px);
        workers[i].mask = malloc(px);
        if (!workers[i].accum || !workers[i].scratch || !workers[i].mask ||
            pthread_create(&workers[i].thread, NULL, frame_thread, &workers[i]) != 0) {
            free(workers[i].accum);
            free(workers[i].scratch);
            free(workers[i].mask);
            atomic_store(&job->next_tile, job->tile_count); /* stop the others */
            rc = -1;
            break;
        }
        started++;
    }
    while (rc == 0 && opt->progress && atomic_load(&job->tiles_done) < job->tile_count) {
        trace_stats so_far = {0};
        so_far.samples = samples_base + atomic_load(&job->samples_done);
        opt->progress(opt->progress_ctx, progress_base + atomic_load(&job->tiles_done), progress_total, &so_far);
        wait_done_ms(job, 100); /* not a plain sleep: the frame ends when its last tile does, not up to 100 ms later */
    }
    for (int i = 0; i < started; i++) {
        pthread_join(workers[i].thread, NULL);
        trace_stats_add(stats, &workers[i].stats);
        free(workers[i].accum);
        free(workers[i].scratch);
        free(workers[i].mask);
    }
    free(workers);
    pthread_cond_destroy(&job->all_done);
    pthread_mutex_destroy(&job->lock);
    return rc;
}

/* Adaptive sampling (adaptive.h): rounds over the tiles that still have
 * active pixels, until none is left. */
static int render_frame_adaptive(const scene *s, const render_options *opt, const tile_rect *tiles, int tile_count,
                                 int tile_size, float *rgb, trace_stats *stats) {
    const render_settings *rs = &s->settings;
    size_t px = (size_t)rs->width * (size_t)rs->height;
    adaptive *ad = adaptive_new(rs->width, rs->height, rs->spp, opt->min_spp, opt->noise_threshold);
    uint8_t *mask = malloc(px);
    float *sums = calloc(px * ADAPTIVE_CHANNELS, sizeof(float));
    tile_rect *round_tiles = malloc((size_t)tile_count * sizeof *round_tiles);
    int rc = ad && mask && sums && round_tiles ? 0 : -1;
    uint32_t first, count;
    while (rc == 0 && adaptive_next_round(ad, &first, &count, mask) > 0) {
        frame_job job = {.s = s, .opt = opt, .tiles = round_tiles, .sums = sums, .mask = mask,
                         .first = first, .count = count};
        for (int t = 0; t < tile_count; t++)
            if (render_tile_has_active(&tiles[t], rs->width, mask)) round_tiles[job.tile_count++] = tiles[t];
        rc = frame_run(&job, tile_size, stats, 0, job.tile_count, adaptive_total_samples(ad));
        if (rc == 0) adaptive_add_round(ad, sums);
    }
    if (rc == 0) adaptive_result(ad, rgb, opt->samples);
    adaptive_free(ad);
    free(mask);
    free(sums);
    free(round_tiles);
    return rc;
}

int render_tile_has_active(const tile_rect *t, int width, const uint8_t *mask) {
    for (int y = t->y0; y < t->y1; y++)
        for (int x = t->x0; x < t->x1; x++)
            if (mask[(size_t)y * (size_t)width + (size_t)x]) return 1;
    return 0;
}

int render_mark_idle_tiles(int width, int height, int tile_size, const uint8_t *mask, uint8_t *idle) {
    int n = render_split_tiles(width, height, tile_size, NULL, 0);
    tile_rect *tiles = malloc((size_t)n * sizeof *tiles);
    if (!tiles) return -1;
    render_split_tiles(width, height, tile_size, tiles, n);
    for (int t = 0; t < n; t++) idle[t] = !render_tile_has_active(&tiles[t], width, mask);
    free(tiles);
    return 0;
}

int render_frame(const scene *s, const render_options *opt, float *rgb, trace_stats *stats) {
    const render_settings *rs = &s->settings;
    int ts = opt->tile_size > 0 ? opt->tile_size : 32;
    int tile_count = render_split_tiles(rs->width, rs->height, ts, NULL, 0);
    tile_rect *tiles = calloc((size_t)tile_count, sizeof *tiles);
    memset(stats, 0, sizeof *stats);
    if (!tiles) return -1;
    render_split_tiles(rs->width, rs->height, ts, tiles, tile_count);
    int rc;
    if (opt->noise_threshold > 0) {
        rc = render_frame_adaptive(s, opt, tiles, tile_count, ts, rgb, stats);
    } else {
        frame_job job = {.s = s, .opt = opt, .tiles = tiles, .tile_count = tile_count, .rgb = rgb};
        rc = frame_run(&job, ts, stats, 0, tile_count, 0);
    }
    if (rc == 0 && opt->progress) opt->progress(opt->progress_ctx, tile_count, tile_count, stats);
    free(tiles);
    return rc;
}
