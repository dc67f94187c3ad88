/* test_local_fork.c - the local farm's forked workers (cli/local_fork.c):
 * `tessera render` loads the scene and builds its intersector once, then
 * forks its local workers over them. The same bytes as spawned workers
 * (TESSERA_LOCAL_FORK=0) and as one process, for 1, 2 and 3 workers; the
 * scene's bundle is never sent to them (their hello claims it); a forked
 * worker killed mid-render is replaced by a spawned tessera-worker, and
 * the image is still the same; forked workers are let go when the farm
 * cannot start. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"
#include "util.h"

#define LONG 120.0 /* seconds: only hit when something is broken */

/* The "N out per tile" figure of a -v farm summary, or -1. */
static double bytes_out_per_tile(const char *out) {
    const char *p = strstr(out, "bytes in and ");
    return p ? atof(p + strlen("bytes in and ")) : -1.0;
}

/* Count the lines of out containing text. */
static int count_text(const char *out, const char *text) {
    int n = 0;
    for (const char *p = out; (p = strstr(p, text)) != NULL; p += strlen(text)) n++;
    return n;
}

TEST(local_fork_same_bytes_as_spawned_workers_and_one_process) {
    const char *scenes[] = {"tests/scenes/icospheres.json", "tests/scenes/cornell-small.json"};
    for (int si = 0; si < 2; si++) {
        char one[256], img[256], cmd[2048], out[32768];
        snprintf(one, sizeof one, "%s", util_temp_path("fork-one.pfm"));
        snprintf(img, sizeof img, "%s", util_temp_path("fork-farm.pfm"));
        snprintf(cmd, sizeof cmd, "%s render %s --workers 0 --threads 2 --spp 8 --no-progress -o %s",
                 harness_tessera(), scenes[si], one);
        CHECK(util_run(cmd, out, sizeof out) == 0, "%s: one process: %s", scenes[si], out);
        for (int workers = 1; workers <= 3; workers++) {
            snprintf(cmd, sizeof cmd, "%s render %s --workers %d --tile-size 16 --spp 8 -v --no-progress -o %s",
                     harness_tessera(), scenes[si], workers, img);
            int st = util_run(cmd, out, sizeof out);
            char want[64];
            snprintf(want, sizeof want, "local workers: %d forked", workers);
            CHECK(st == 0 && strstr(out, want), "%s, %d forked: status %d: %s", scenes[si], workers, st, out);
            /* Each worker took the scene it was forked with: none loaded it. */
            CHECK(count_text(out, "was loaded before this worker started") == workers &&
                      !strstr(out, "loaded, ") && !strstr(out, "built by each worker"),
                  "%s, %d forked: a worker loaded the scene itself: %s", scenes[si], workers, out);
            double forked_out = bytes_out_per_tile(out);
            CHECK(util_same_file(one, img), "%s: %d forked workers: the image differs from one process's", scenes[si],
                  workers);
            snprintf(cmd, sizeof cmd,
                     "TESSERA_LOCAL_FORK=0 %s render %s --workers %d --tile-size 16 --spp 8 -v --no-progress -o %s",
                     harness_tessera(), scenes[si], workers, img);
            st = util_run(cmd, out, sizeof out);
            CHECK(st == 0 && !strstr(out, "forked") && count_text(out, "loaded, ") == workers,
                  "%s, %d spawned: status %d: %s", scenes[si], workers, st, out);
            CHECK(util_same_file(one, img), "%s: %d spawned workers: the image differs from one process's",
                  scenes[si], workers);
            /* The bundle went to the spawned workers only: the forked ones
             * claimed it in their hello. */
            double spawned_out = bytes_out_per_tile(out);
            CHECK(forked_out >= 0 && spawned_out > 0 && forked_out * 2 < spawned_out,
                  "%s, %d workers: bytes out per tile forked %.0f, spawned %.0f", scenes[si], workers, forked_out,
                  spawned_out);
        }
    }
}

/* The pids of pid's children (from /proc), at most max; returns how many. */
static int children_of(pid_t pid, pid_t *kids, int max) {
    char path[64];
    snprintf(path, sizeof path, "/proc/%d/task/%d/children", (int)pid, (int)pid);
    FILE *f = fopen(path, "r");
    int n = 0, k;
    while (f && n < max && fscanf(f, "%d", &k) == 1) kids[n++] = k;
    if (f) fclose(f);
    return n;
}

TEST(local_fork_worker_killed_is_restarted_by_spawning) {
    char ref[256], img[256], log[256], hold[256], hold_env[300], cmd[1024], out[8192];
    snprintf(ref, sizeof ref, "%s", util_temp_path("fork-kill-ref.pfm"));
    snprintf(img, sizeof img, "%s", util_temp_path("fork-kill.pfm"));
    snprintf(log, sizeof log, "%s", util_temp_path("fork-kill.log"));
    snprintf(hold, sizeof hold, "%s", util_temp_path("fork-kill.hold"));
    unlink(log);
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/icospheres.json --workers 0 --spp 8 --no-progress -o %s",
             harness_tessera(), ref);
    CHECK(util_run(cmd, out, sizeof out) == 0, "reference: %s", out);
    util_touch(hold); /* every worker keeps its tiles: the render cannot end */
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold);
    const char *env[] = {hold_env, NULL};
    const char *argv[] = {harness_tessera(), "render", "tests/scenes/icospheres.json", "--workers", "2",
                          "--tile-size", "16", "--spp", "8", "--no-progress", "-v", "-o", img, NULL};
    pid_t coord = util_spawn_env(argv, log, env);
    CHECK(coord > 0 && util_wait_for_text(log, UTIL_HOLDING, LONG) == 0, "no worker held a tile; log %s", log);
    pid_t kids[8];
    int n = children_of(coord, kids, 8);
    CHECK(n == 2, "%d children of the coordinator (want its 2 forked workers); log %s", n, log);
    if (n >= 1) kill(kids[0], SIGKILL);
    CHECK(util_wait_for_text(log, "was killed by signal 9", LONG) == 0 &&
              util_wait_for_text(log, "again (restart 1 of 3)", LONG) == 0,
          "the killed forked worker was not started again; log %s", log);
    /* The one started again is tessera-worker, loading the scene itself. */
    CHECK(util_wait_for_text(log, "loaded, 2572 triangles", LONG) == 0,
          "the spawned replacement did not load the scene; log %s", log);
    unlink(hold);
    int st = util_wait(coord, LONG, NULL);
    CHECK(st == 0, "render status %d; log %s", st, log);
    CHECK(util_same_file(ref, img), "after a forked worker was killed: the image differs; log %s", log);
}

/* A farm that cannot start (its --listen port taken) after the workers
 * were forked: they are let go (end of file where the address would be)
 * and reaped, and the render fails at once with the reason; no worker
 * says a word, and nothing hangs (timeout would make it 124). */
TEST(local_fork_workers_let_go_when_the_farm_cannot_start) {
    int port, fd = util_listen_loopback(1, &port);
    CHECK(fd >= 0, "no port to take");
    char cmd[1024], out[8192];
    snprintf(cmd, sizeof cmd,
             "timeout 60 %s render tests/scenes/icospheres.json --workers 2 --listen 127.0.0.1:%d -v --no-progress "
             "-o %s",
             harness_tessera(), port, util_temp_path("let-go.pfm"));
    int st = util_run(cmd, out, sizeof out);
    close(fd);
    CHECK(st == 1 && strstr(out, "local workers: 2 forked") && strstr(out, "address already in use"),
          "status %d: %s", st, out);
    CHECK(!strstr(out, "tessera-worker"), "a forked worker said something: %s", out);
}
