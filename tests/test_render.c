/* test_render.c - the integrator end to end: white furnace, determinism
 * across threads, tiles and passes, and the Cornell box against the
 * project's converged reference. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "elapsed.h"
#include "fileio.h"
#include "image/image.h"
#include "harness.h"
#include "util.h"

/* A closed sphere of albedo rho emitting Le on both sides, seen from its
 * centre: every pixel converges to Le / (1 - rho). */
static void furnace(double rho, double Le, int spp) {
    char json[1024];
    snprintf(json, sizeof json,
             "{\"render\": {\"width\": 4, \"height\": 2, \"spp\": %d, \"max_depth\": 1024, \"seed\": 3},"
             " \"camera\": {\"type\": \"environment\", \"position\": [0.1, 0.2, -0.1]},"
             " \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [%g, %g, %g]}},"
             " \"shapes\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"m\","
             " \"emission\": [%g, %g, %g], \"two_sided\": true}]}",
             spp, rho, rho, rho, Le, Le, Le);
    char err[512];
    scene *s = util_scene_from_text(json, err, sizeof err);
    CHECK(s != NULL, "furnace scene: %s", err);
    if (!s) return;
    trace_stats st;
    float *rgb = util_render(s, 2, 8, 1, &st);
    double want = Le / (1 - rho), worst = 0;
    for (int i = 0; i < 4 * 2 * 3; i++) worst = fmax(worst, fabs(rgb[i] - want) / want);
    CHECK(worst < 0.01, "rho %.2f: a pixel is %.2f%% off Le/(1-rho) = %g", rho, 100 * worst, want);
    CHECK(st.bad_samples == 0, "NaN/Inf samples: %llu", (unsigned long long)st.bad_samples);
    free(rgb);
    scene_free(s);
}

TEST(render_white_furnace) {
    furnace(0.5, 1.0, 16384);
    furnace(0.8, 0.25, 32768);
}

static scene *small_cornell(int spp) {
    char err[512];
    scene_overrides ov = {.width = 24, .height = 24, .spp = spp, .max_depth = -1};
    scene *s = scene_load("tests/scenes/cornell-small.json", &ov, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    return s;
}

TEST(render_thread_determinism) {
    scene *s = small_cornell(8);
    if (!s) return;
    trace_stats st;
    size_t n = 3 * 24 * 24 * sizeof(float);
    float *a = util_render(s, 1, 8, 1, &st);
    float *b = util_render(s, 2, 8, 1, &st);
    float *c = util_render(s, 2, 64, 1, &st);
    float *d = util_render(s, 2, 5, 4, &st); /* odd tiles, four passes */
    float *e = util_render(s, 3, 7, 3, &st);
    CHECK(memcmp(a, b, n) == 0, "1 vs 2 threads differ");
    CHECK(memcmp(a, c, n) == 0, "8 vs 64 pixel tiles differ");
    CHECK(memcmp(a, d, n) == 0, "one pass vs four passes differ");
    CHECK(memcmp(a, e, n) == 0, "3 threads, 7-pixel tiles, 3 passes differ");
    s->settings.seed++;
    float *f = util_render(s, 1, 8, 1, &st);
    CHECK(memcmp(a, f, n) != 0, "a different seed gave the same image");
    free(a), free(b), free(c), free(d), free(e), free(f);
    scene_free(s);
}

/* Relative MSE of x against y, weighted by the reference:
 * mean (x - y)^2 / (ref^2 + 0.01). */
static double rel_mse(const float *x, const float *y, const float *ref, size_t n) {
    double s = 0;
    for (size_t i = 0; i < n; i++) s += (x[i] - y[i]) * (double)(x[i] - y[i]) / (ref[i] * (double)ref[i] + 0.01);
    return s / (double)n;
}

static int load_reference(image *ref) {
    char out[256], cmd[1024], path[512];
    snprintf(path, sizeof path, "%s", util_temp_path("cornell-ref.pfm"));
    snprintf(cmd, sizeof cmd, "gzip -dc tests/data/cornell-ref-64.pfm.gz > %s", path);
    if (util_run(cmd, out, sizeof out) != 0) return -1;
    char err[256];
    return image_read(path, ref, err, sizeof err);
}

/* Error of a 64x64 render against the reference, relative to its own noise
 * (estimated from two renders with different seeds: E[(a-b)^2] = 2 var). */
static double excess_error(scene *s, const image *ref, double *mean_ratio) {
    trace_stats st;
    size_t n = 3 * 64 * 64;
    float *a = util_render(s, 2, 16, 1, &st);
    s->settings.seed += 1000;
    float *b = util_render(s, 2, 16, 1, &st);
    double noise = 0.5 * rel_mse(a, b, ref->rgb, n), err = rel_mse(a, ref->rgb, ref->rgb, n);
    double ma = 0, mr = 0;
    for (size_t i = 0; i < n; i++) ma += a[i], mr += ref->rgb[i];
    *mean_ratio = ma / mr;
    free(a), free(b);
    return err / noise;
}

/* The reference into *ref and the small box at 64 spp with `seed`, the
 * scene the reference was rendered from. Returns the scene (the caller
 * frees both), or NULL with a failed check and nothing to free. */
static scene *reference_and_scene(image *ref, uint64_t seed) {
    memset(ref, 0, sizeof *ref);
    CHECK(load_reference(ref) == 0, "cannot read tests/data/cornell-ref-64.pfm.gz (make reference)");
    if (!ref->rgb) return NULL;
    char err[512];
    scene_overrides ov = {.width = -1, .height = -1, .spp = 64, .max_depth = -1, .has_seed = 1, .seed = seed};
    scene *s = scene_load("tests/scenes/cornell-small.json", &ov, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) image_free(ref);
    return s;
}

TEST(render_cornell_matches_reference) {
    image ref;
    scene *s = reference_and_scene(&ref, 5);
    if (!s) return;
    double ratio, x = excess_error(s, &ref, &ratio), x_ok = x, ratio_ok = ratio;
    /* An unbiased render's error is its noise: x ~ 1 (plus the reference's
     * own small noise). */
    CHECK(x < 1.5, "error is %.2f times the noise: the render is biased", x);
    CHECK(fabs(ratio - 1) < 0.01, "mean brightness is %.4f of the reference", ratio);
    /* The same check must fail for a biased render: direct light only. */
    s->settings.max_depth = 1;
    x = excess_error(s, &ref, &ratio);
    CHECK(x > 2.0, "a render without indirect light passed the check (%.2f x noise)", x);
    printf("    error / noise: %.2f unbiased (mean ratio %.4f), %.2f direct light only\n", x_ok, ratio_ok, x);
    scene_free(s);
    image_free(&ref);
}

/* render.roulette_depth only trades rays for noise: from the camera ray's
 * hit (0), from Cycles' vertex (1), the default's (4) and late (16), the
 * box stays within its noise of the reference and as bright, and each
 * earlier start traces fewer rays per sample (the setting reaches the
 * integrator). */
TEST(render_roulette_depth_keeps_the_image) {
    image ref;
    scene *s = reference_and_scene(&ref, 7);
    if (!s) return;
    CHECK(s->settings.roulette_depth == SCENE_ROULETTE_DEPTH_DEFAULT, "default roulette depth %d",
          s->settings.roulette_depth);
    const int depths[] = {0, 1, SCENE_ROULETTE_DEPTH_DEFAULT, 16};
    double rays[4];
    for (int i = 0; i < 4; i++) {
        s->settings.roulette_depth = depths[i];
        double ratio, x = excess_error(s, &ref, &ratio);
        CHECK(x < 1.5, "roulette from vertex %d: error %.2f times the noise (biased)", depths[i], x);
        CHECK(fabs(ratio - 1) < 0.01, "roulette from vertex %d: mean brightness %.4f of the reference", depths[i],
              ratio);
        trace_stats st;
        free(util_render(s, 1, 16, 1, &st));
        rays[i] = (double)st.rays / (double)st.samples;
        printf("    roulette from vertex %d: %.3f rays per sample, error / noise %.2f, mean ratio %.4f\n", depths[i],
               rays[i], x, ratio);
        if (i > 0) CHECK(rays[i] > rays[i - 1], "roulette from vertex %d traced no more rays than from %d (%.3f, %.3f)",
                         depths[i], depths[i - 1], rays[i], rays[i - 1]);
    }
    scene_free(s);
    image_free(&ref);
}

/* Scale and translate every point of a scene's JSON tree (vertices,
 * positions, look-at points, centres, radii). */
static void transform_json(cJSON *node, double scale, double offset) {
    for (cJSON *c = node ? node->child : NULL; c; c = c->next) {
        const char *k = c->string ? c->string : "";
        int is_point = strcmp(k, "position") == 0 || strcmp(k, "look_at") == 0 || strcmp(k, "center") == 0;
        if (is_point)
            for (cJSON *e = c->child; e; e = e->next) cJSON_SetNumberValue(e, e->valuedouble * scale + offset);
        else if (strcmp(k, "radius") == 0)
            cJSON_SetNumberValue(c, c->valuedouble * scale);
        else if (strcmp(k, "vertices") == 0)
            for (cJSON *v = c->child; v; v = v->next)
                for (cJSON *e = v->child; e; e = e->next) cJSON_SetNumberValue(e, e->valuedouble * scale + offset);
        else
            transform_json(c, scale, offset);
    }
}

/* The Cornell box as given, scaled by 1e-4 and by 1e4, and moved 1e5 units
 * away renders the same picture: its error against the reference is its noise,
 * with no NaN/Inf samples. */
TEST(render_scale_invariance) {
    image ref;
    CHECK(load_reference(&ref) == 0, "cannot read the reference");
    if (!ref.rgb) return;
    const double cases[][2] = {{1, 0}, {1e-4, 0}, {1e4, 0}, {1, 1e5}};
    for (int i = 0; i < 4; i++) {
        char err[512];
        size_t len;
        char *text = file_read_all("tests/scenes/cornell-small.json", 1 << 20, &len, err, sizeof err);
        cJSON *root = text ? cJSON_Parse(text) : NULL;
        transform_json(root, cases[i][0], cases[i][1]);
        char *out = cJSON_Print(root);
        scene *s = out ? util_scene_from_text(out, err, sizeof err) : NULL;
        CHECK(s != NULL, "case %d: %s", i, err);
        if (s) {
            double ratio, x = excess_error(s, &ref, &ratio);
            CHECK(x < 1.5 && fabs(ratio - 1) < 0.01, "scale %g, offset %g: error %.2f x noise, brightness ratio %.4f",
                  cases[i][0], cases[i][1], x, ratio);
            printf("    scale %g, offset %g: error / noise %.2f, brightness ratio %.4f\n", cases[i][0], cases[i][1], x, ratio);
        }
        scene_free(s);
        free(out);
        cJSON_Delete(root);
        free(text);
    }
    image_free(&ref);
}

/* The variance across seeds of an 8x8 image's pixels at spp samples, under
 * sampler k: a diffuse floor seen from above, lit only through its BSDF
 * samples (no light sampling, one bounce) by a quad light covering part of
 * its hemisphere, so each pixel's noise is that of the first bounce's
 * direction. Mean over pixels of the red channel's variance; -1 on error. */
static double bounce_variance(sampler_kind k, int spp) {
    const char *json =
        "{\"render\": {\"width\": 8, \"height\": 8, \"spp\": 64, \"max_depth\": 1, \"seed\": 1},"
        " \"camera\": {\"type\": \"perspective\", \"position\": [0, 10, 0], \"look_at\": [0, 0, 0],"
        " \"up\": [0, 0, 1], \"fov\": 2},"
        " \"materials\": {\"white\": {\"type\": \"diffuse\", \"albedo\": [0.8, 0.8, 0.8]}},"
        " \"shapes\": [{\"type\": \"quad\", \"vertices\": [[-100, 0, -100], [-100, 0, 100], [100, 0, 100], [100, 0, -100]],"
        " \"material\": \"white\"},"
        " {\"type\": \"quad\", \"vertices\": [[0.3, 1, -1.5], [2.5, 1, -1.5], [2.5, 1, 0.7], [0.3, 1, 0.7]],"
        " \"material\": \"white\", \"emission\": [4, 4, 4]}]}";
    char err[512];
    scene *s = util_scene_from_text(json, err, sizeof err);
    CHECK(s != NULL, "bounce scene: %s", err);
    if (!s) return -1;
    s->settings.spp = spp;
    enum { SEEDS = 16, PIXELS = 64 };
    double sum[PIXELS] = {0}, sum2[PIXELS] = {0};
    float rgb[3 * PIXELS];
    render_options ro = {.threads = 2, .tile_size = 8, .passes = 1, .integrator = {.no_nee = 1, .sampler = k}};
    for (int seed = 0; seed < SEEDS; seed++) {
        s->settings.seed = 1000 + (uint64_t)seed;
        trace_stats st;
        if (render_frame(s, &ro, rgb, &st) != 0) {
            scene_free(s);
            return -1;
        }
        for (int p = 0; p < PIXELS; p++) sum[p] += rgb[3 * p], sum2[p] += (double)rgb[3 * p] * rgb[3 * p];
    }
    scene_free(s);
    double var = 0;
    for (int p = 0; p < PIXELS; p++) var += (sum2[p] - sum[p] * sum[p] / SEEDS) / (SEEDS - 1);
    return var / PIXELS;
}

/* The BSDF direction takes both numbers of one stratified pair: at 64 spp
 * the padded Sobol sampler's error on a one-bounce integrand must be far
 * below independent numbers' (a (0,2)-net against a discontinuous 2D
 * integrand). With the direction's numbers from two different pairs, as
 * before 2026-11-26, both ratios were above their bounds (figures below). */
TEST(render_bsdf_direction_is_stratified) {
    double sobol = bounce_variance(SAMPLER_SOBOL, 64), random = bounce_variance(SAMPLER_RANDOM, 64);
    double global = bounce_variance(SAMPLER_SOBOL_GLOBAL, 64);
    CHECK(sobol > 0 && random > 0 && global > 0, "variances %g %g %g", sobol, random, global);
    /* Measured (fixed seeds, so the same on every run and ISA): 0.131 and
     * 0.177; with the numbers crossed, 0.328 and 0.279. */
    CHECK(sobol < 0.20 * random, "sobol: variance %.3f of random's", sobol / random);
    CHECK(global < 0.23 * random, "sobol-global: variance %.3f of random's", global / random);
}

static void count_progress(void *ctx, int tiles_done, int tiles_total, const trace_stats *so_far) {
    (void)tiles_done, (void)tiles_total, (void)so_far;
    (*(int *)ctx)++;
}

/* With a progress callback, a frame returns when its last tile is done,
 * not at the reporting thread's next 100 ms tick (until 2026-11-27 it slept
 * 100 ms between reports, so every in-process render ended up to 100 ms
 * late): the fastest of 5 renders of an 8x8 box at 1 spp takes under 90 ms
 * (0.100 s before the fix). */
TEST(render_frame_threads_end_when_the_last_tile_is_done) {
    char err[512];
    scene_overrides ov = {.width = 8, .height = 8, .spp = 1, .max_depth = -1};
    scene *s = scene_load("scenes/cornell-box.json", &ov, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    float rgb[8 * 8 * 3];
    double best = 1e9;
    int reports = 0;
    for (int i = 0; i < 5; i++) {
        render_options ro = {.threads = 2, .tile_size = 4, .passes = 1, .progress = count_progress,
                             .progress_ctx = &reports};
        trace_stats st;
        struct timespec t0 = elapsed_mark();
        CHECK(render_frame(s, &ro, rgb, &st) == 0, "render failed");
        double t = elapsed_seconds(&t0);
        if (t < best) best = t;
    }
    CHECK(best < 0.09, "fastest of 5 tiny renders took %.3f s", best);
    CHECK(reports >= 1, "the progress callback was never called");
    scene_free(s);
}
