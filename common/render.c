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

#include "camera.h"

void render_tile(const scene *s, const integrator_options *opt, const tile_rect *tile, uint32_t first,
                 uint32_t count, double *accum, trace_stats *stats) {
    const render_settings *rs = &s->settings;
    int tw = tile_width(tile);
    for (int y = tile->y0; y < tile->y1; y++) {
        for (int x = tile->x0; x < tile->x1; x++) {
            double *sum = accum + 3 * ((size_t)(y - tile->y0) * (size_t)tw + (size_t)(x - tile->x0));
            uint64_t pixel = (uint64_t)y * (uint64_t)rs->width + (uint64_t)x;
            for (uint32_t i = first; i < first + count; i++) {
                sampler_stream rng = sampler_start(opt->sampler, rs->seed, pixel, i);
                float u, v;
                sampler_get_2d(&rng, 0, &u, &v);
                ray r = {s->cam.position, camera_direction(&s->cam, rs->width, rs->height, x, y, u, v), PRIM_NONE};
                vec3 L = integrator_radiance(s, opt, &r, &rng, stats);
                sum[0] += L.x;
                sum[1] += L.y;
                sum[2] += L.z;
            }
        }
    }
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

typedef struct {
    const scene *s;
    const render_options *opt;
    const tile_rect *tiles;
    int tile_count;
    float *rgb;
    atomic_int next_tile;
    atomic_int tiles_done;
    atomic_ullong samples_done;
} frame_job;

typedef struct {
    frame_job *job;
    pthread_t thread;
    trace_stats stats;
    double *accum; /* one row's sums, reused */
    float *means;  /* one tile's means, reused */
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

/* Render one tile of the frame and copy its means into the frame. */
static void frame_render_tile(frame_worker *w, const tile_rect *t) {
    const scene *s = w->job->s;
    int spp = s->settings.spp, tw = tile_width(t);
    render_tile_means(s, &w->job->opt->integrator, t, spp, w->job->opt->passes, w->accum, w->means, &w->stats,
                      NULL);
    for (int y = t->y0; y < t->y1; y++)
        memcpy(w->job->rgb + 3 * ((size_t)y * (size_t)s->settings.width + (size_t)t->x0),
               w->means + 3 * (size_t)(y - t->y0) * (size_t)tw, 3 * sizeof(float) * (size_t)tw);
    size_t n = (size_t)tw * (size_t)tile_height(t);
    atomic_fetch_add(&w->job->samples_done, (unsigned long long)n * (unsigned long long)spp);
}

static void *frame_thread(void *arg) {
    frame_worker *w = arg;
    frame_job *job = w->job;
    for (;;) {
        int i = atomic_fetch_add(&job->next_tile, 1);
        if (i >= job->tile_count) break;
        frame_render_tile(w, &job->tiles[i]);
        atomic_fetch_add(&job->tiles_done, 1);
    }
    return NULL;
}

static void sleep_ms(long ms) {
    struct timespec ts = {ms / 1000, (ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

static void sum_stats(trace_stats *a, const trace_stats *b) {
    a->samples += b->samples;
    a->rays += b->rays;
    a->shadow_rays += b->shadow_rays;
    a->bad_samples += b->bad_samples;
}

int render_frame(const scene *s, const render_options *opt, float *rgb, trace_stats *stats) {
    const render_settings *rs = &s->settings;
    int threads = opt->threads > 0 ? opt->threads : 1;
    int ts = opt->tile_size > 0 ? opt->tile_size : 32;
    frame_job job = {.s = s, .opt = opt, .rgb = rgb};
    job.tile_count = render_split_tiles(rs->width, rs->height, ts, NULL, 0);
    tile_rect *tiles = calloc((size_t)job.tile_count, sizeof *tiles);
    frame_worker *workers = calloc((size_t)threads, sizeof *workers);
    int started = 0, rc = 0;
    if (!tiles || !workers) rc = -1;
    if (rc == 0) render_split_tiles(rs->width, rs->height, ts, tiles, job.tile_count);
    job.tiles = tiles;
    atomic_init(&job.next_tile, 0);
    atomic_init(&job.tiles_done, 0);
    atomic_init(&job.samples_done, 0);
    for (int i = 0; i < threads && rc == 0; i++) {
        workers[i].job = &job;
        workers[i].accum = malloc(3 * sizeof(double) * (size_t)ts);
        workers[i].means = malloc(3 * sizeof(float) * (size_t)ts * (size_t)ts);
        if (!workers[i].accum || !workers[i].means ||
            pthread_create(&workers[i].thread, NULL, frame_thread, &workers[i]) != 0) {
            free(workers[i].accum);
            free(workers[i].means);
            atomic_store(&job.next_tile, job.tile_count); /* stop the others */
            rc = -1;
            break;
        }
        started++;
    }
    while (rc == 0 && opt->progress && atomic_load(&job.tiles_done) < job.tile_count) {
        trace_stats so_far = {0};
        so_far.samples = atomic_load(&job.samples_done);
        opt->progress(opt->progress_ctx, atomic_load(&job.tiles_done), job.tile_count, &so_far);
        sleep_ms(100);
    }
    memset(stats, 0, sizeof *stats);
    for (int i = 0; i < started; i++) {
        pthread_join(workers[i].thread, NULL);
        sum_stats(stats, &workers[i].stats);
        free(workers[i].accum);
        free(workers[i].means);
    }
    if (rc == 0 && opt->progress) opt->progress(opt->progress_ctx, job.tile_count, job.tile_count, stats);
    free(tiles);
    free(workers);
    return rc;
}
