/* test_adaptive.c - adaptive sampling: the round schedule, the stopping
 * rule and its neighbourhood, and, end to end, the same bytes for any
 * threads, tiles and workers, with fewer samples where the image is easy. */
#include <math.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "render/adaptive.h"
#include "fileio.h"
#include "image/image.h"
#include "harness.h"
#include "util.h"

/* Feed one round of synthetic sums: pixel i's samples are 1 - noise[i] in
 * the first half of [0, first + count) and 1 + noise[i] in the second, so
 * its halves differ by 2 noise[i]. */
static void feed_round(adaptive *a, int w, int h, uint32_t first, uint32_t count, const uint8_t *mask,
                       const float *noise) {
    float *sums = calloc((size_t)w * h * ADAPTIVE_CHANNELS, sizeof(float));
    for (int i = 0; i < w * h; i++) {
        if (!mask[i]) continue;
        uint32_t split = ADAPTIVE_SPLIT(first, count);
        for (uint32_t k = first; k < first + count; k++) {
            float v = 1.0f + (k >= split ? noise[i] : -noise[i]);
            for (int c = 0; c < 3; c++) {
                sums[ADAPTIVE_CHANNELS * i + c] += v;
                if (k >= split) sums[ADAPTIVE_CHANNELS * i + 3 + c] += v;
            }
        }
    }
    adaptive_add_round(a, sums);
    free(sums);
}

/* Rounds double the count from min_spp to spp; a noiseless image stops
 * after the first round; a noisy one runs to spp. */
TEST(adaptive_rounds_and_stopping) {
    const int w = 4, h = 3;
    float quiet[12] = {0}, loud[12];
    for (int i = 0; i < 12; i++) loud[i] = 0.5f;
    for (int pass = 0; pass < 2; pass++) {
        adaptive *a = adaptive_new(w, h, 100, 8, 0.01);
        uint8_t mask[12];
        uint32_t first, count, expect_first = 0, expect_count = 8;
        int rounds = 0;
        while (adaptive_next_round(a, &first, &count, mask) > 0) {
            CHECK(first == expect_first && count == expect_count, "round %d: [%u, +%u), expected [%u, +%u)", rounds,
                  first, count, expect_first, expect_count);
            feed_round(a, w, h, first, count, mask, pass ? loud : quiet);
            expect_first = first + count;
            expect_count = (expect_first * 2 < 100 ? expect_first * 2 : 100) - expect_first;
            rounds++;
        }
        float rgb[36], samples[12];
        adaptive_result(a, rgb, samples);
        if (pass == 0) CHECK(rounds == 1 && samples[5] == 8, "noiseless: %d rounds, %g samples", rounds, samples[5]);
        if (pass == 1)
            CHECK(rounds == 5 && samples[5] == 100 && adaptive_total_samples(a) == 1200,
                  "noisy: %d rounds (8, 16, 32, 64, 100 expected), %g samples", rounds, samples[5]);
        if (pass == 0) CHECK(fabsf(rgb[15] - 1.0f) < 1e-6f, "mean %g, expected 1", rgb[15]);
        adaptive_free(a);
    }
}

/* One noisy pixel keeps its neighbourhood going: its error, averaged over
 * each 3x3 window that holds it, leaves those windows unconverged, and each
 * unconverged pixel keeps its 8 neighbours going: a 5x5 block. Nobody else. */
TEST(adaptive_neighbours_of_noisy_pixels_keep_going) {
    const int w = 7, h = 7;
    float noise[49] = {0};
    noise[3 * 7 + 3] = 0.5f;
    adaptive *a = adaptive_new(w, h, 64, 4, 0.01);
    uint8_t mask[49];
    uint32_t first, count;
    while (adaptive_next_round(a, &first, &count, mask) > 0) feed_round(a, w, h, first, count, mask, noise);
    float rgb[147], samples[49];
    adaptive_result(a, rgb, samples);
    for (int y = 0; y < h; y++)
        for (int x = 0; x < w; x++) {
            int near = abs(x - 3) <= 2 && abs(y - 3) <= 2;
            CHECK(samples[y * w + x] == (near ? 64.0f : 4.0f), "pixel (%d,%d) took %g samples", x, y,
                  samples[y * w + x]);
        }
    adaptive_free(a);
}

/* Render the Cornell box adaptively with a command line; returns the output
 * path. */
static const char *render_adaptive(const char *name, const char *args) {
    static char path[8][256];
    static int next;
    char *p = path[next++ % 8], cmd[1024], out[8192];
    snprintf(p, 256, "%s", util_temp_path(name));
    snprintf(cmd, sizeof cmd,
             "%s render scenes/cornell-box.json --width 48 --height 40 --spp 128 --noise-threshold 0.05 "
             "--min-spp 8 --aov samples --no-progress %s -o %s",
             harness_tessera(), args, p);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "adaptive:"), "%s failed (%d): %s", cmd, st, out);
    CHECK(!strstr(out, "Sanitizer") && !strstr(out, "runtime error"), "sanitizer report: %s", out);
    return p;
}

static char *samples_path(const char *image) {
    static char p[300];
    snprintf(p, sizeof p, "%.*s.samples.pfm", (int)(strrchr(image, '.') - image), image);
    return p;
}

/* The same bytes, image and sample counts, whatever the threads, tiles or
 * workers; some pixels stop early, some run to the end. */
TEST(adaptive_same_bytes_any_threads_tiles_workers) {
    const char *ref = render_adaptive("ad-ref.pfm", "--workers 0 --threads 1 --tile-size 32");
    char ref_samples[300];
    snprintf(ref_samples, sizeof ref_samples, "%s", samples_path(ref));
    const char *runs[][2] = {{"ad-a.pfm", "--workers 0 --threads 3 --tile-size 7"},
                             {"ad-b.pfm", "--workers 2 --tile-size 13"},
                             {"ad-c.pfm", "--workers 3 --threads 2 --tile-size 5"}};
    for (size_t i = 0; i < 3; i++) {
        const char *img = render_adaptive(runs[i][0], runs[i][1]);
        CHECK(util_same_file(img, ref), "%s: image differs from the single-thread one", runs[i][1]);
        CHECK(util_same_file(samples_path(img), ref_samples), "%s: sample counts differ", runs[i][1]);
    }
    image counts;
    char err[512];
    CHECK(image_read(ref_samples, &counts, err, sizeof err) == 0, "%s", err);
    int at_min = 0, at_max = 0, n = counts.width * counts.height;
    for (int i = 0; i < n; i++) {
        float c = counts.rgb[3 * i];
        at_min += c == 8.0f;
        at_max += c == 128.0f;
        CHECK(c >= 8.0f && c <= 128.0f, "pixel %d took %g samples", i, c);
    }
    CHECK(at_min > 0 && at_max > 0 && at_min + at_max < n + 1,
          "expected some pixels to stop at 8 and some to run to 128: %d at min, %d at max of %d", at_min, at_max, n);
    image_free(&counts);
}

/* The port of the `tessera render --listen` whose log is at log, once it
 * says it listens; -1 when it never does. */
static int listening_port(const char *log) {
    int port = -1;
    if (util_wait_for_text(log, "coordinator listening on 127.0.0.1:", 120) != 0) return -1;
    FILE *f = fopen(log, "r");
    char line[512];
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "tessera: coordinator listening on 127.0.0.1:%d", &port) == 1) break;
    if (f) fclose(f);
    return port;
}

/* Start `tessera render` of the adaptive Cornell box with no workers of its
 * own (--workers 0 --listen 127.0.0.1:0) into img, its log in log; returns
 * its pid and its port in *port (-1 when it never listened). */
static pid_t render_listening(const char *img, const char *log, int *port) {
    const char *argv[] = {harness_tessera(), "render", "scenes/cornell-box.json", "--width", "48", "--height", "40",
                          "--spp", "128", "--noise-threshold", "0.05", "--min-spp", "8", "--no-progress", "-v",
                          "--tile-size", "8", "--workers", "0", "--listen", "127.0.0.1:0", "-o", img, NULL};
    pid_t coord = util_spawn(argv, log);
    *port = listening_port(log);
    return coord;
}

/* A worker killed in the middle of an adaptive render: its tiles of that
 * round go back to the queue and the image is still the same bytes. */
TEST(adaptive_farm_survives_a_killed_worker) {
    const char *ref = render_adaptive("ad-kill-ref.pfm", "--workers 0");
    char img[256], log[256], wlog[256], slog[256], connect[64];
    snprintf(img, sizeof img, "%s", util_temp_path("ad-kill.pfm"));
    snprintf(log, sizeof log, "%s", util_temp_path("ad-kill.log"));
    snprintf(wlog, sizeof wlog, "%s", util_temp_path("ad-kill-w.log"));
    snprintf(slog, sizeof slog, "%s", util_temp_path("ad-kill-s.log"));
    int port;
    pid_t coord = render_listening(img, log, &port);
    CHECK(port > 0, "no coordinator; log %s", log);
    snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
    /* Both keep their finished tiles while the hold file exists (util.h), so
     * the kill lands mid-render whatever the machine's speed. */
    char hold[300];
    snprintf(hold, sizeof hold, "TESSERA_TEST_HOLD_FILE=%s", util_temp_path("ad-kill.hold"));
    util_touch(hold + strlen("TESSERA_TEST_HOLD_FILE="));
    const char *env[] = {hold, NULL};
    const char *vargv[] = {util_bin("tessera-worker"), "--connect", connect, "--threads", "1", "--name", "victim", NULL};
    const char *sargv[] = {util_bin("tessera-worker"), "--connect", connect, "--threads", "1", "--name", "survivor",
                           "--once", NULL};
    pid_t victim = util_spawn_env(vargv, wlog, env);
    CHECK(util_wait_for_text(wlog, UTIL_HOLDING, 120) == 0, "victim never held a tile; log %s", wlog);
    pid_t survivor = util_spawn_env(sargv, slog, env);
    CHECK(util_wait_for_text(slog, UTIL_HOLDING, 120) == 0, "survivor never held a tile; log %s", slog);
    kill(victim, SIGKILL);
    util_wait(victim, 120, NULL);
    CHECK(util_wait_for_text(log, "go back to the queue", 120) == 0, "the victim's death went unnoticed; log %s", log);
    unlink(hold + strlen("TESSERA_TEST_HOLD_FILE="));
    CHECK(util_wait(coord, 120, NULL) == 0, "coordinator failed; log %s", log);
    CHECK(util_file_count(log, "go back to the queue"), "the victim held no tiles when killed; log %s", log);
    CHECK(util_same_file(img, ref), "image differs after a worker was killed; log %s", log);
    CHECK(util_wait(survivor, 120, NULL) == 0, "the surviving worker did not exit cleanly; log %s", slog);
}

/* Each round of an adaptive render is a job of its own; a worker loads the
 * scene for the first and shares it with the others (worker/pool.c,
 * pool_scene), instead of loading it once per round: with 2.6M triangles
 * a 128x128 render took 14.9 s on the local farm against 7.7-8.1 s once
 * shared (docs/protocol.md). With --keep-scene 0 the scene goes with each round's job and is
 * loaded again: the count of loads is what the sharing changes. The image is
 * the same bytes either way. Two render threads, so that rounds overlap on
 * the worker; `make test-tsan` runs it under ThreadSanitizer (a report
 * makes the worker exit non-zero). */
TEST(adaptive_rounds_share_one_loaded_scene_on_a_worker) {
    const char *ref = render_adaptive("ad-share-ref.pfm", "--workers 0");
    for (int keep = 1; keep >= 0; keep--) {
        char img[256], log[256], wlog[256], connect[64];
        snprintf(img, sizeof img, "%s", util_temp_path(keep ? "ad-share.pfm" : "ad-share-0.pfm"));
        snprintf(log, sizeof log, "%s", util_temp_path(keep ? "ad-share.log" : "ad-share-0.log"));
        snprintf(wlog, sizeof wlog, "%s", util_temp_path(keep ? "ad-share-w.log" : "ad-share-w0.log"));
        int port;
        pid_t coord = render_listening(img, log, &port);
        CHECK(port > 0, "no coordinator; log %s", log);
        snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
        const char *wargv[] = {util_bin("tessera-worker"), "--connect", connect, "--threads", "2", "--once", "-v",
                               "--keep-scene", keep ? "30" : "0", NULL};
        pid_t worker = util_spawn(wargv, wlog);
        CHECK(util_wait(coord, 120, NULL) == 0, "coordinator failed; log %s", log);
        CHECK(util_wait(worker, 120, NULL) == 0, "worker failed; log %s", wlog);
        CHECK(util_same_file(img, ref), "image differs from the in-process render (keep %d); log %s", keep, wlog);
        int jobs = util_file_count(wlog, " spp"), loads = util_file_count(wlog, " loaded, "),
            shared = util_file_count(wlog, "shared, not loaded again");
        CHECK(jobs >= 3, "expected at least 3 rounds, the worker saw %d jobs; log %s", jobs, wlog);
        CHECK(loads + shared == jobs, "%d loads and %d shared for %d jobs; log %s", loads, shared, jobs, wlog);
        if (keep)
            CHECK(loads == 1, "the scene was loaded %d times for %d rounds; log %s", loads, jobs, wlog);
        else
            CHECK(loads >= 2, "with --keep-scene 0 the scene was loaded only %d times for %d rounds; log %s", loads,
                  jobs, wlog);
    }
}

/* A kept scene outlives its connection (it is named by its bundle's hash)
 * and goes after --keep-scene seconds without a job (pool_trim): one
 * worker, three renders of one scene, each from a coordinator of its own;
 * the second, right after the first and at another spp (a preview, then the
 * final), shares its scene and gives the bytes of an in-process render at
 * its spp; the third, after the keep time, loads it again. */
TEST(worker_keeps_a_scene_across_renders_until_the_keep_time) {
    static const char *const spp[3] = {"4", "8", "4"};
    char wlog[256], ref[256], cmd[1024], out[4096];
    snprintf(wlog, sizeof wlog, "%s", util_temp_path("keep-w.log"));
    snprintf(ref, sizeof ref, "%s", util_temp_path("keep-ref8.pfm"));
    snprintf(cmd, sizeof cmd, "%s render scenes/cornell-box.json --width 24 --height 20 --spp 8 --no-progress "
             "--workers 0 -o %s", harness_tessera(), ref);
    CHECK(util_run(cmd, out, sizeof out) == 0, "in-process render failed: %s", out);
    int port = -1;
    pid_t worker = -1;
    for (int run = 0; run < 3; run++) {
        char img[256], log[256], connect[64];
        snprintf(img, sizeof img, "%s", util_temp_path(run == 0 ? "keep-a.pfm" : run == 1 ? "keep-b.pfm" : "keep-c.pfm"));
        snprintf(log, sizeof log, "%s", util_temp_path(run == 0 ? "keep-0.log" : run == 1 ? "keep-1.log" : "keep-2.log"));
        if (port > 0) snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
        const char *argv[] = {harness_tessera(), "render", "scenes/cornell-box.json", "--width", "24", "--height", "20",
                              "--spp", spp[run], "--no-progress", "--workers", "0", "--listen",
                              port > 0 ? connect : "127.0.0.1:0", "-o", img, NULL};
        pid_t coord = util_spawn(argv, log);
        int listening = listening_port(log);
        CHECK(listening > 0, "no coordinator; log %s", log);
        if (port < 0) {
            port = listening;
            snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
            const char *wargv[] = {util_bin("tessera-worker"), "--connect", connect, "--threads", "1", "-v",
                                   "--retry-max", "1", "--keep-scene", "1.5", NULL};
            worker = util_spawn(wargv, wlog);
        }
        CHECK(util_wait(coord, 120, NULL) == 0, "render %d failed; log %s", run, log);
        if (run == 1) util_sleep(3.0); /* past the keep time */
    }
    int loads = util_file_count(wlog, " loaded, "), shared = util_file_count(wlog, "shared, not loaded again");
    kill(worker, SIGTERM);
    CHECK(util_wait(worker, 30, NULL) == 0, "the worker did not leave cleanly; log %s", wlog);
    CHECK(loads == 2 && shared == 1, "want 2 loads (first render, after the keep time) and 1 shared (second render), "
          "got %d and %d; log %s", loads, shared, wlog);
    CHECK(util_same_file(util_temp_path("keep-b.pfm"), ref), "the render at 8 spp on a shared scene differs from the "
          "in-process one");
    CHECK(util_same_file(util_temp_path("keep-a.pfm"), util_temp_path("keep-c.pfm")), "renders at 4 spp differ");
}
