/* test_idle_exit.c - `tessera-worker --idle-exit S` end to end: a worker
 * leaves with status 0, saying why, after S seconds without a tile in hand:
 * when no coordinator answers, when a render's coordinator has finished and
 * gone, and when a job service has no job for it. It must not leave while
 * it renders tiles slower than S. (Batch schedulers rely on this to release
 * an allocation: docs/slurm.md.) And told to leave (SIGTERM) while its
 * connection is still being made, it leaves at once. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <arpa/inet.h>
#include <netinet/in.h>
#include <sys/socket.h>
#include <sys/wait.h>
#include <unistd.h>

#include "harness.h"
#include "util.h"

#define SCENE "tests/scenes/cornell-small.json"
#define LONG 120.0 /* seconds: only hit when something is broken */

/* A fresh path under the test folder (static storage per call site). */
static void temp_into(char *dst, size_t cap, const char *name) {
    snprintf(dst, cap, "%s", util_temp_path(name));
    unlink(dst);
}

/* Start a worker with --idle-exit idle at addr; throttle_ms slows each tile. */
static pid_t start_idle_worker(const char *log, const char *addr, const char *name, const char *idle,
                               const char *throttle_ms) {
    const char *argv[] = {util_bin("tessera-worker"), "--connect", addr, "--threads", "2", "--name", name,
                          "--retry-max", "1", "--throttle-ms", throttle_ms, "--idle-exit", idle, NULL};
    return util_spawn(argv, log);
}

static void check_no_sanitizer(const char *log) {
    CHECK(!util_file_count(log, "Sanitizer") && !util_file_count(log, "runtime error"), "sanitizer report in %s", log);
}

TEST(idle_exit_no_coordinator) {
    char log[256], addr[64];
    temp_into(log, sizeof log, "idle-none.log");
    snprintf(addr, sizeof addr, "127.0.0.1:%d", util_free_port()); /* nobody listens there */
    double t0 = util_now();
    pid_t w = start_idle_worker(log, addr, "lonely", "1", "0");
    int st = util_wait(w, LONG, NULL);
    double took = util_now() - t0;
    CHECK(st == 0, "worker exited with %d, want 0; log %s", st, log);
    CHECK(took >= 0.9 && took < 30, "worker left after %.2f s, want about 1 s", took);
    CHECK(util_file_count(log, "no coordinator reachable at 127.0.0.1:") == 1,
          "no reason logged for leaving; log %s", log);
    check_no_sanitizer(log);
}

TEST(idle_exit_after_render_not_during) {
    char clog[256], wlog[256], img[256], ref[256], cmd[1024], out[4096];
    temp_into(clog, sizeof clog, "idle-render-coord.log");
    temp_into(wlog, sizeof wlog, "idle-render-worker.log");
    temp_into(img, sizeof img, "idle-render.pfm");
    temp_into(ref, sizeof ref, "idle-render-ref.pfm");
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 --threads 2 -o %s", harness_tessera(), ref);
    CHECK(util_run(cmd, out, sizeof out) == 0, "reference render failed: %s", out);
    int port = util_free_port();
    char listen[64];
    snprintf(listen, sizeof listen, "127.0.0.1:%d", port);
    const char *cargv[] = {harness_tessera(), "render", SCENE, "--tile-size", "32", "--no-progress", "-v",
                           "-o", img, "--listen", listen, NULL};
    pid_t coord = util_spawn(cargv, clog);
    CHECK(util_wait_for_text(clog, "coordinator listening on", LONG) == 0, "coordinator did not start; log %s", clog);
    /* Each of the 4 tiles takes longer than --idle-exit: the worker must stay. */
    pid_t w = start_idle_worker(wlog, listen, "W", "2", "2500");
    int wst = -1;
    for (double t = 0; t < LONG && !util_file_count(clog, "rendered " SCENE) && wst < 0; t += 0.05) {
        int raw;
        if (waitpid(w, &raw, WNOHANG) == w) wst = WIFEXITED(raw) ? WEXITSTATUS(raw) : 128 + WTERMSIG(raw);
        else util_sleep(0.05);
    }
    CHECK(wst < 0, "the worker left during the render (status %d); logs %s %s", wst, clog, wlog);
    if (wst >= 0) kill(coord, SIGTERM); /* it has no worker left */
    int cst = util_wait(coord, LONG, NULL);
    double coord_end = util_now();
    CHECK(cst == 0, "coordinator exited with %d; log %s", cst, clog);
    CHECK(util_same_file(img, ref), "image differs from the single-process render; logs %s %s", clog, wlog);
    CHECK(util_file_count(clog, "left: worker left") == 0, "the worker said bye during the render; log %s", clog);
    if (wst < 0) wst = util_wait(w, LONG, NULL);
    double after = util_now() - coord_end;
    CHECK(wst == 0, "worker exited with %d after the render, want 0; log %s", wst, wlog);
    CHECK(after < 12, "worker left %.2f s after the render ended, want within about 2 s", after);
    CHECK(util_file_count(wlog, "(--idle-exit 2); leaving") == 1, "no reason logged for leaving; log %s", wlog);
    check_no_sanitizer(clog);
    check_no_sanitizer(wlog);
}

TEST(idle_exit_service_without_jobs) {
    char dir[256], slog[256], wlog[256], addr[64];
    temp_into(dir, sizeof dir, "idle-service");
    temp_into(slog, sizeof slog, "idle-service.log");
    temp_into(wlog, sizeof wlog, "idle-service-worker.log");
    snprintf(addr, sizeof addr, "127.0.0.1:%d", util_free_port());
    char coord[4096];
    snprintf(coord, sizeof coord, "%s", util_bin("tessera-coordinator"));
    const char *sargv[] = {coord, "--listen", addr, "--data-dir", dir, "--heartbeat", "0.2", "--worker-timeout", "2",
                           NULL};
    pid_t svc = util_spawn(sargv, slog);
    CHECK(util_wait_for_text(slog, "listening on", LONG) == 0, "service did not start; log %s", slog);
    double t0 = util_now();
    pid_t w = start_idle_worker(wlog, addr, "pool-1", "2.5", "0");
    int st = util_wait(w, LONG, NULL);
    double took = util_now() - t0;
    CHECK(st == 0, "worker exited with %d, want 0; log %s", st, wlog);
    CHECK(took >= 2.4 && took < 30, "worker left after %.2f s, want about 2.5 s", took);
    CHECK(util_file_count(wlog, "no work from the coordinator at 127.0.0.1:") == 1, "wrong or no reason; log %s",
          wlog);
    CHECK(util_wait_for_text(slog, "worker pool-1", 10) == 0, "the service never saw the worker; log %s", slog);
    kill(svc, SIGTERM);
    CHECK(util_wait(svc, LONG, NULL) == 0, "service did not stop cleanly; log %s", slog);
    check_no_sanitizer(slog);
    check_no_sanitizer(wlog);
}

/* SIGTERM while the worker's connection is still being made (the
 * coordinator's accept queue is full, so its SYN goes unanswered): the
 * worker leaves at once with status 0. libuv accepted a shutdown of the
 * connecting socket and never completed it, and the worker hung until
 * killed (conn_close now shuts down only an established connection), as a
 * `docker stop` or `scancel` during a coordinator's overload would have. */
TEST(worker_told_to_leave_while_connecting_exits) {
    int port, ls = util_listen_loopback(0, &port);
    CHECK(ls >= 0, "no listening socket");
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port),
                            .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    int fill[3];
    for (int i = 0; i < 3; i++) { /* fill the accept queue: later SYNs are dropped, connects stay in progress */
        fill[i] = socket(AF_INET, SOCK_STREAM | SOCK_NONBLOCK, 0);
        (void)connect(fill[i], (struct sockaddr *)&a, sizeof a);
    }
    util_sleep(0.2);
    char addr[64], log[256];
    snprintf(addr, sizeof addr, "127.0.0.1:%d", port);
    temp_into(log, sizeof log, "leave-connecting.log");
    const char *argv[] = {util_bin("tessera-worker"), "--connect", addr, "--threads", "1", "--once", NULL};
    pid_t w = util_spawn(argv, log);
    util_sleep(0.5); /* resolved, connect() issued and waiting */
    kill(w, SIGTERM);
    double t0 = util_now();
    int st = util_wait(w, 10, NULL);
    double took = util_now() - t0;
    CHECK(st == 0, "the worker did not leave cleanly on SIGTERM while connecting (status %d after %.1f s); log %s", st,
          took, log);
    CHECK(took < 5, "the worker took %.1f s to leave", took);
    CHECK(util_file_count(log, "SIGTERM: leaving"), "no leaving line; log %s", log);
    for (int i = 0; i < 3; i++) close(fill[i]);
    close(ls);
}
