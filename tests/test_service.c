/* test_service.c - the job service end to end: a real tessera-coordinator,
 * real workers and the real CLI on loopback. Each test checks what a user
 * would see: exit statuses, messages, and the fetched image compared byte
 * for byte with a single-process render. */
#include <arpa/inet.h>
#include <netinet/in.h>
#include <fcntl.h>
#include <signal.h>
#include <sys/resource.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "fileio.h"
#include "image/image.h"
#include "version.h"
#include "harness.h"
#include "util.h"

#define SCENE "tests/scenes/cornell-small.json"
#define LONG 120.0

typedef struct {
    char dir[256], log[256], addr[64];
    const char *token; /* --token-file for the coordinator, or NULL */
    const char *extra[8]; /* more options for the coordinator, NULL-terminated */
    int port;
    pid_t pid;
} service;

/* Start tessera-coordinator on a free port with a data dir under the test
 * folder (kept between a kill and a restart when dir is reused). */
/* Give s a free port on host (an IPv6 one in brackets), and its data
 * folder and log under the test folder by name. */
static void service_place(service *s, const char *name, const char *host) {
    s->port = util_free_port();
    snprintf(s->dir, sizeof s->dir, "%s", util_temp_path(name));
    char logname[128];
    snprintf(logname, sizeof logname, "%s.log", name);
    snprintf(s->log, sizeof s->log, "%s", util_temp_path(logname));
    snprintf(s->addr, sizeof s->addr, strchr(host, ':') ? "[%s]:%d" : "%s:%d", host, s->port);
}

static void service_start(service *s, const char *name) {
    if (!s->port) service_place(s, name, "127.0.0.1");
    char coord[4096];
    snprintf(coord, sizeof coord, "%s", util_bin("tessera-coordinator"));
    const char *argv[24] = {coord, "--listen", s->addr, "--data-dir", s->dir, "--heartbeat", "0.2",
                            "--worker-timeout", "2"};
    int n = 9;
    if (s->token) argv[n++] = "--token-file", argv[n++] = s->token;
    for (int i = 0; i < 8 && s->extra[i]; i++) argv[n++] = s->extra[i];
    argv[n] = NULL;
    int before = util_file_count(s->log, "listening on");
    s->pid = util_spawn(argv, s->log);
    for (int i = 0; i < (int)(LONG * 100) && util_file_count(s->log, "listening on") == before; i++) util_sleep(0.01);
}

static pid_t worker_start_token(const service *s, const char *name, const char *throttle_ms, const char *token) {
    char path[4096], log[256], lname[64];
    snprintf(path, sizeof path, "%s", util_bin("tessera-worker"));
    snprintf(lname, sizeof lname, "%s.log", name);
    snprintf(log, sizeof log, "%s", util_temp_path(lname));
    const char *argv[] = {path, "--connect", s->addr, "--threads", "1", "--name", name, "--retry-max", "1",
                          "--throttle-ms", throttle_ms, token ? "--token-file" : NULL, token, NULL};
    return util_spawn(argv, log);
}

static pid_t worker_start(const service *s, const char *name, const char *throttle_ms) {
    return worker_start_token(s, name, throttle_ms, NULL);
}

/* A worker that keeps its finished tiles, after the first `after`, while the
 * file hold exists (util.h); its log is NAME.log under the test folder. */
static pid_t worker_start_held(const service *s, const char *name, const char *hold, int after) {
    char path[4096], log[256], lname[64], hold_env[300], after_env[64];
    snprintf(path, sizeof path, "%s", util_bin("tessera-worker"));
    snprintf(lname, sizeof lname, "%s.log", name);
    snprintf(log, sizeof log, "%s", util_temp_path(lname));
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold);
    snprintf(after_env, sizeof after_env, "TESSERA_TEST_HOLD_AFTER=%d", after);
    const char *argv[] = {path, "--connect", s->addr, "--threads", "1", "--name", name, "--retry-max", "1", NULL};
    const char *env[] = {hold_env, after_env, NULL};
    return util_spawn_env(argv, log, env);
}

/* Run `tessera ARGS` against the service; output in out. */
static int cli(const service *s, char *out, size_t cap, const char *fmt, ...) __attribute__((format(printf, 4, 5)));
static int cli(const service *s, char *out, size_t cap, const char *fmt, ...) {
    char args[2048];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(args, sizeof args, fmt, ap);
    va_end(ap);
    return util_cli(s->addr, out, cap, args);
}

static void service_stop(service *s) {
    kill(s->pid, SIGTERM);
    int st = util_wait(s->pid, LONG, NULL);
    CHECK(st == 0, "coordinator exited with %d on SIGTERM; log %s", st, s->log);
    CHECK(!util_file_count(s->log, "Sanitizer") && !util_file_count(s->log, "runtime error"),
          "sanitizer report in %s", s->log);
}

static void worker_stop(pid_t pid) {
    kill(pid, SIGTERM);
    CHECK(util_wait(pid, LONG, NULL) == 0, "worker did not exit cleanly");
}

static const char *reference(void) {
    static char path[256];
    if (path[0]) return path;
    snprintf(path, sizeof path, "%s", util_temp_path("service-ref.pfm"));
    char cmd[1024], out[4096];
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 -o %s", harness_tessera(), path);
    if (util_run(cmd, out, sizeof out) != 0) fprintf(stderr, "reference failed: %s\n", out);
    return path;
}

/* Job id printed by `tessera submit` ("job N"), or -1. */
static int job_id(const char *out) {
    int id = -1;
    const char *p = strstr(out, "job ");
    if (p) sscanf(p, "job %d", &id);
    return id;
}

TEST(service_submit_wait_fetch_status_workers) {
    service s = {0};
    service_start(&s, "svc-basic");
    pid_t w1 = worker_start(&s, "w1", "0"), w2 = worker_start(&s, "w2", "0");
    char out[8192], img[256], png[256];
    snprintf(img, sizeof img, "%s", util_temp_path("svc-basic.pfm"));
    snprintf(png, sizeof png, "%s", util_temp_path("svc-basic.png"));
    int st = cli(&s, out, sizeof out, "submit " SCENE " --wait -o %s", img);
    CHECK(st == 0 && strstr(out, "job 1 done, image: "), "submit --wait failed (%d): %s", st, out);
    CHECK(util_same_file(img, reference()), "the fetched image differs from the single-process render");
    st = cli(&s, out, sizeof out, "fetch 1 -o %s", png);
    CHECK(st == 0 && access(png, F_OK) == 0, "fetch after the fact failed (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "status");
    CHECK(st == 0 && strstr(out, "done") && strstr(out, "4/4") && strstr(out, SCENE),
          "status table: %s", out);
    st = cli(&s, out, sizeof out, "status 1 --json");
    CHECK(st == 0 && strstr(out, "\"state\":\t\"done\"") && strstr(out, "\"tiles_total\""), "status --json: %s", out);
    st = cli(&s, out, sizeof out, "workers");
    CHECK(st == 0 && strstr(out, "w1") && strstr(out, "w2") && strstr(out, "127.0.0.1:"), "workers: %s", out);
    st = cli(&s, out, sizeof out, "fetch 7 -o %s", png);
    CHECK(st == 1 && strstr(out, "job 7: unknown job"), "fetch of an unknown job (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "cancel 1");
    CHECK(st == 1 && strstr(out, "job 1 is already done"), "cancel of a finished job (%d): %s", st, out);
    /* An image with nowhere to go: refused before the upload (no job 2);
     * one that cannot be written at the end is left to fetch. */
    st = cli(&s, out, sizeof out, "submit " SCENE " --wait -o %s/missing/x.png", util_temp_path("svc-basic-none"));
    CHECK(st == 1 && strstr(out, "missing/x.png: cannot write: No such file or directory (nothing submitted)"),
          "submit --wait to a folder that does not exist (%d): %s", st, out);
    mkdir(util_temp_path("svc-basic-folder.png"), 0755);
    st = cli(&s, out, sizeof out, "submit " SCENE " --wait -o %s", util_temp_path("svc-basic-folder.png"));
    CHECK(st == 1 && strstr(out, "job 2: the image stays on the coordinator: tessera fetch 2 -o OUT"),
          "submit --wait to a folder's path (%d): %s", st, out);
    worker_stop(w1);
    worker_stop(w2);
    service_stop(&s);
}

TEST(service_queue_priority_and_cancel) {
    service s = {0};
    service_start(&s, "svc-queue");
    char hold[256];
    snprintf(hold, sizeof hold, "%s", util_temp_path("svc-queue.hold"));
    util_touch(hold); /* nothing finishes until every job is queued */
    pid_t w = worker_start_held(&s, "slow", hold, 0);
    char out[8192];
    int a = job_id((cli(&s, out, sizeof out, "submit " SCENE " --tile-size 8"), out));
    int b = job_id((cli(&s, out, sizeof out, "submit " SCENE " --seed 7 --tile-size 8"), out));
    int c = job_id((cli(&s, out, sizeof out, "submit " SCENE " --seed 9 --tile-size 16 --priority 5"), out));
    CHECK(a == 1 && b == 2 && c == 3, "job ids %d %d %d", a, b, c);
    int st = cli(&s, out, sizeof out, "cancel 2");
    CHECK(st == 0 && strstr(out, "job 2 cancelled"), "cancel (%d): %s", st, out);
    unlink(hold);
    CHECK(util_wait_for_text(s.log, "job 1 done", LONG) == 0 && util_wait_for_text(s.log, "job 3 done", LONG) == 0,
          "jobs did not finish; log %s", s.log);
    CHECK(util_file_count(s.log, "job 2 cancelled (0 tiles from the journal"), "cancel not logged; log %s", s.log);
    /* priority 5 overtakes job 1, which was submitted first */
    FILE *f = fopen(s.log, "r");
    char line[512];
    int order = 0, first_done = 0;
    while (f && fgets(line, sizeof line, f))
        if (strstr(line, " done (")) {
            order++;
            if (order == 1 && strstr(line, ": job ")) sscanf(strstr(line, ": job ") + 2, "job %d", &first_done);
        }
    if (f) fclose(f);
    CHECK(first_done == 3, "job %d finished first; the high-priority job 3 should; log %s", first_done, s.log);
    st = cli(&s, out, sizeof out, "status 2");
    CHECK(st == 0 && strstr(out, "cancelled"), "status of the cancelled job: %s", out);
    worker_stop(w);
    service_stop(&s);
}

/* Poll `status JOB` until the coordinator counts want tiles done (all
 * journaled) or LONG passes; the last count. */
static int tiles_done_reach(const service *s, int job, int want) {
    char out[8192];
    int done = 0;
    for (int i = 0; i < (int)(LONG * 20) && done < want; i++) {
        cli(s, out, sizeof out, "status %d --json", job);
        const char *p = strstr(out, "\"tiles_done\":");
        if (p) sscanf(p, "\"tiles_done\":\t%d", &done);
        if (done < want) util_sleep(0.05);
    }
    return done;
}

TEST(service_restart_resumes_without_rerendering) {
    service s = {0};
    service_start(&s, "svc-restart");
    char hold[256];
    snprintf(hold, sizeof hold, "%s", util_temp_path("svc-restart.hold"));
    util_touch(hold);
    pid_t w = worker_start_held(&s, "w", hold, 20); /* 20 tiles, then it keeps them */
    char out[8192], img[256];
    int st = cli(&s, out, sizeof out, "submit " SCENE " --tile-size 8");
    CHECK(st == 0 && job_id(out) == 1, "submit (%d): %s", st, out);
    CHECK(util_wait_for_text(util_temp_path("w.log"), UTIL_HOLDING, LONG) == 0, "the worker never held a tile");
    int done = tiles_done_reach(&s, 1, 20);
    CHECK(done == 20, "%d tiles done before the kill; 20 expected", done);
    kill(s.pid, SIGKILL);
    util_wait(s.pid, LONG, NULL);
    unlink(hold);
    service_start(&s, "svc-restart");
    int resumed = -1, again = -1, rendered = -1;
    CHECK(util_wait_for_text(s.log, "job 1 resumed: ", LONG) == 0, "no resume; log %s", s.log);
    CHECK(util_wait_for_text(s.log, "job 1 done (", LONG) == 0, "resumed job never finished; log %s", s.log);
    util_resume_counts(s.log, &resumed, &again, &rendered);
    CHECK(resumed == 20 && again == resumed && resumed + rendered == 64,
          "resumed %d, then %d from the journal and %d rendered: finished tiles must not be rendered again", resumed,
          again, rendered);
    snprintf(img, sizeof img, "%s", util_temp_path("svc-restart.pfm"));
    st = cli(&s, out, sizeof out, "fetch 1 -o %s", img);
    CHECK(st == 0 && util_same_file(img, reference()), "image after a restart differs (%d): %s", st, out);
    /* The job's log outlived the kill (jobs/1.log): the lines written
     * before it, then this run's, in order; and a clean restart after
     * the job ended keeps them all again. */
    static char logs[65536];
    for (int run = 0; run < 2; run++) {
        st = cli(&s, logs, sizeof logs, "logs 1");
        const char *sub = strstr(logs, "job submitted by"), *handed = strstr(logs, "handed to w"),
                   *resumed = strstr(logs, "job resumed after a restart: 20 of 64"),
                   *done_line = strstr(logs, "job done (20 tiles from the journal, 44 rendered in this run)");
        CHECK(st == 0 && sub && handed && resumed && done_line && sub < handed && handed < resumed &&
                  resumed < done_line,
              "logs 1 after %s: %.3000s", run ? "a second, clean restart" : "the kill", logs);
        if (run) break;
        worker_stop(w);
        service_stop(&s);
        service_start(&s, "svc-restart");
    }
    service_stop(&s);
}

/* A job that must wait for memory after a restart is admitted later from
 * libuv's thread pool, which reads its scene and now also replays its
 * journal there, not on the loop: it still resumes with the tiles it had
 * (20 of 64) and its image is the same bytes as one rendered in one go. */
TEST(service_job_admitted_after_a_restart_resumes_its_journal) {
    const char *frame = "--width 1024 --height 1024 --spp 1 --tile-size 128"; /* 64 tiles, 24 MiB of need */
    char out[8192], img[256], ref[256], cmd[2048];
    snprintf(ref, sizeof ref, "%s", util_temp_path("svc-admit-ref.pfm"));
    snprintf(cmd, sizeof cmd, "%s render " SCENE " %s --workers 0 -o %s", harness_tessera(), frame, ref);
    CHECK(util_run(cmd, out, sizeof out) == 0, "%s: %s", cmd, out);
    service s = {0};
    service_start(&s, "svc-admit");
    int st = cli(&s, out, sizeof out, "submit " SCENE " %s", frame);
    CHECK(st == 0 && job_id(out) == 1, "submit 1 (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "submit " SCENE " %s --priority 5", frame);
    CHECK(st == 0 && job_id(out) == 2, "submit 2 (%d): %s", st, out);
    char hold[256];
    snprintf(hold, sizeof hold, "%s", util_temp_path("svc-admit.hold"));
    util_touch(hold);
    pid_t w = worker_start_held(&s, "wadmit", hold, 20); /* job 2's first 20 tiles, then it keeps one */
    int done = tiles_done_reach(&s, 2, 20);
    CHECK(done == 20, "job 2 had %d tiles done before the kill; 20 expected", done);
    kill(s.pid, SIGKILL);
    util_wait(s.pid, LONG, NULL);
    unlink(hold);
    kill(w, SIGKILL);
    util_wait(w, LONG, NULL);
    /* Room for one of the two jobs: job 1 is resumed at start, job 2 waits. */
    s.extra[0] = "--max-memory";
    s.extra[1] = "40M";
    service_start(&s, "svc-admit");
    CHECK(util_wait_for_text(s.log, "job 1 resumed: 0 of 64", LONG) == 0, "job 1 not resumed; log %s", s.log);
    CHECK(util_file_count(s.log, "job 2: waiting for memory") == 1, "job 2 did not wait; log %s", s.log);
    st = cli(&s, out, sizeof out, "cancel 1");
    CHECK(st == 0, "cancel 1 (%d): %s", st, out);
    CHECK(util_wait_for_text(s.log, "job 2 resumed: 20 of 64 tiles from the journal", LONG) == 0,
          "job 2 admitted without its journal; log %s", s.log);
    pid_t w2 = worker_start(&s, "wadmit2", "0");
    snprintf(img, sizeof img, "%s", util_temp_path("svc-admit.pfm"));
    CHECK(util_wait_for_text(s.log, "job 2 done (", LONG) == 0, "job 2 never finished; log %s", s.log);
    st = cli(&s, out, sizeof out, "fetch 2 -o %s", img);
    CHECK(st == 0 && util_same_file(img, ref), "job 2's image after its admission differs (%d): %s", st, out);
    worker_stop(w2);
    service_stop(&s);
}

/* `tessera submit --noise-threshold` is adaptive sampling on the service:
 * the image is the bytes of `tessera render --noise-threshold` in one
 * process (rounds decided on the whole image, whatever the tiles and
 * workers), not the uniform one; and an adaptive job the coordinator lost
 * to kill -9 mid-render is rendered again after the restart, to the same
 * bytes. */
TEST(service_adaptive_submit_same_bytes_as_render) {
    char out[8192], ref[256], uniform[256], img[256], cmd[1024];
    snprintf(ref, sizeof ref, "%s", util_temp_path("svc-adaptive-ref.pfm"));
    snprintf(uniform, sizeof uniform, "%s", util_temp_path("svc-adaptive-uniform.pfm"));
    snprintf(img, sizeof img, "%s", util_temp_path("svc-adaptive.pfm"));
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 --noise-threshold 0.05 -o %s", harness_tessera(), ref);
    double mean = 0;
    CHECK(util_run(cmd, out, sizeof out) == 0 && strstr(out, "adaptive: "), "%s: %s", cmd, out);
    sscanf(strstr(out, "adaptive: ") ? strstr(out, "adaptive: ") : "", "adaptive: %lf", &mean);
    CHECK(mean > 16 && mean < 64, "the threshold should stop some pixels early: %g samples per pixel", mean);
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 -o %s", harness_tessera(), uniform);
    CHECK(util_run(cmd, out, sizeof out) == 0, "%s: %s", cmd, out);
    service s = {0};
    service_start(&s, "svc-adaptive");
    pid_t w1 = worker_start(&s, "wa1", "0"), w2 = worker_start(&s, "wa2", "0");
    int st = cli(&s, out, sizeof out, "submit " SCENE " --noise-threshold 0.05 --tile-size 7 --wait -o %s", img);
    CHECK(st == 0 && strstr(out, "job 1 done"), "submit --noise-threshold --wait (%d): %s", st, out);
    CHECK(util_same_file(img, ref), "the service's adaptive image differs from tessera render's");
    CHECK(!util_same_file(img, uniform), "the service ignored --noise-threshold (uniform image)");
    worker_stop(w1);
    worker_stop(w2);
    /* Job 2 on a slow worker; the coordinator dies during its rounds. */
    w1 = worker_start(&s, "wa3", "15");
    st = cli(&s, out, sizeof out, "submit " SCENE " --noise-threshold 0.05 --tile-size 8");
    CHECK(st == 0 && job_id(out) == 2, "submit (%d): %s", st, out);
    int done = 0;
    for (int i = 0; i < (int)(LONG * 20) && done < 10; i++) {
        cli(&s, out, sizeof out, "status 2 --json");
        const char *p = strstr(out, "\"tiles_done\":");
        if (p) sscanf(p, "\"tiles_done\":\t%d", &done);
        if (done < 10) util_sleep(0.05);
    }
    CHECK(done >= 10 && strstr(out, "running"), "job 2 never got going: %s", out);
    st = cli(&s, out, sizeof out, "fetch 2 --partial -o %s", img);
    CHECK(st == 1 && strstr(out, "job 2 samples adaptively"), "fetch --partial of an adaptive job (%d): %s", st, out);
    kill(s.pid, SIGKILL);
    util_wait(s.pid, LONG, NULL);
    service_start(&s, "svc-adaptive");
    CHECK(util_wait_for_text(s.log, "job 2 done (", LONG) == 0, "the adaptive job never finished after a restart; log %s",
          s.log);
    st = cli(&s, out, sizeof out, "fetch 2 -o %s", img);
    CHECK(st == 0 && util_same_file(img, ref), "the adaptive image after a restart differs (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "status 2 --json");
    CHECK(st == 0 && strstr(out, "\"state\":\t\"done\""), "status of job 2: %s", out);
    worker_stop(w1);
    service_stop(&s);
}

TEST(service_survives_bad_clients_and_reports_errors) {
    service s = {0};
    service_start(&s, "svc-bad");
    char out[8192];
    /* A client that sends garbage, and one that disconnects mid-upload. */
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)s.port),
                            .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    CHECK(connect(fd, (struct sockaddr *)&a, sizeof a) == 0, "connect");
    send(fd, "GET / HTTP/1.0\r\n\r\n", 18, MSG_NOSIGNAL);
    close(fd);
    fd = socket(AF_INET, SOCK_STREAM, 0);
    CHECK(connect(fd, (struct sockaddr *)&a, sizeof a) == 0, "connect");
    const char hello[] = "{\"type\":\"hello\",\"role\":\"client\",\"protocol\":1,\"build\":\"x\",\"name\":\"c\",\"threads\":1}";
    uint8_t hdr[5] = {(uint8_t)(sizeof hello), 0, 0, 0, 'J'};
    send(fd, hdr, 5, MSG_NOSIGNAL);
    send(fd, hello, sizeof hello - 1, MSG_NOSIGNAL);
    uint8_t up[5] = {0, 0, 16, 0, 'S'}; /* a 1 MiB scene upload... */
    send(fd, up, 5, MSG_NOSIGNAL);
    send(fd, "partial", 7, MSG_NOSIGNAL); /* ...cut short */
    shutdown(fd, SHUT_WR);
    char drain[4096];
    while (recv(fd, drain, sizeof drain, 0) > 0) {
    }
    close(fd);
    CHECK(util_wait_for_text(s.log, "closed in the middle of a frame", LONG) == 0, "truncated upload not logged; log %s",
          s.log);
    int st = cli(&s, out, sizeof out, "status");
    CHECK(st == 0 && strstr(out, "0 workers connected"), "service unhealthy after bad clients (%d): %s", st, out);
    /* An invalid scene: the coordinator's own message, with file and field. */
    const char *bad = util_write_temp("bad-scene.json", "{\"render\": {\"spp\": 0}}");
    st = cli(&s, out, sizeof out, "submit %s", bad);
    CHECK(st == 1 && strstr(out, "bad-scene.json: render.spp: expected an integer"), "invalid scene (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "submit tests/scenes/missing.json");
    CHECK(st == 1 && strstr(out, "missing.json"), "missing scene (%d): %s", st, out);
    service_stop(&s);
    st = cli(&s, out, sizeof out, "status");
    CHECK(st == 1 && strstr(out, "cannot reach the coordinator at 127.0.0.1:"), "unreachable (%d): %s", st, out);
    char cmd[1024];
    snprintf(cmd, sizeof cmd, "%s --data-dir /etc/passwd/x --listen 127.0.0.1:0", util_bin("tessera-coordinator"));
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 1 && strstr(out, "/etc/passwd/x: cannot create the data dir: Not a directory"),
          "unusable data dir (%d): %s", st, out);
}

TEST(service_token_required_of_workers_and_clients) {
    char good[256], bad[256], out[8192], img[256];
    snprintf(good, sizeof good, "%s", util_write_temp("token", "correct horse battery staple\n"));
    snprintf(bad, sizeof bad, "%s", util_write_temp("token-wrong", "incorrect horse\n"));
    service s = {0};
    s.token = good;
    service_start(&s, "svc-auth");
    /* A worker with the wrong token is refused and exits 1; one with none too. */
    pid_t wrong = worker_start_token(&s, "intruder", "0", bad);
    CHECK(util_wait(wrong, LONG, NULL) == 1, "a worker with the wrong token was not refused");
    pid_t none = worker_start_token(&s, "anonymous", "0", NULL);
    CHECK(util_wait(none, LONG, NULL) == 1, "a worker without a token was not refused");
    CHECK(util_file_count(s.log, "calling itself worker intruder): authentication failed (wrong token)") &&
              util_file_count(s.log, "calling itself worker anonymous): authentication failed (no token)"),
          "refusals not logged; log %s", s.log);
    CHECK(util_file_count(util_temp_path("intruder.log"), "refused this worker: authentication failed") &&
              !util_file_count(util_temp_path("intruder.log"), "protocol 1"),
          "the refused worker should learn nothing but the refusal");
    /* Clients: no token or the wrong one are refused; the right one works. */
    int st = cli(&s, out, sizeof out, "status");
    CHECK(st == 1 && strstr(out, "authentication failed") && strstr(out, "requires a token") &&
              strstr(out, "--token-file F or TESSERA_CLIENT_TOKEN_FILE"),
          "client without a token is not told a token is required (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "status --token-file %s", bad);
    CHECK(st == 1 && strstr(out, "authentication failed") && strstr(out, "did not accept the token in"),
          "client with a wrong token (%d): %s", st, out);
    pid_t w = worker_start_token(&s, "member", "0", good);
    snprintf(img, sizeof img, "%s", util_temp_path("svc-auth.pfm"));
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "TESSERA_TOKEN_FILE=%s TESSERA_COORDINATOR=%s %s submit " SCENE " --wait -o %s", good,
             s.addr, harness_tessera(), img);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && util_same_file(img, reference()), "authenticated submit failed (%d): %s", st, out);
    /* A worker holding the token checks the coordinator too: an impostor
     * without it is not trusted. */
    service fake = {0};
    service_start(&fake, "svc-impostor"); /* no token */
    pid_t careful = worker_start_token(&fake, "careful", "0", good);
    char clog[256];
    snprintf(clog, sizeof clog, "%s", util_temp_path("careful.log"));
    CHECK(util_wait_for_text(clog, "could not prove it knows the token", LONG) == 0,
          "the worker trusted a coordinator without the token; log %s", clog);
    worker_stop(careful);
    worker_stop(w);
    service_stop(&fake);
    service_stop(&s);
}

TEST(service_limits_and_a_full_disk_are_reported) {
    service s = {0};
    service_place(&s, "svc-full", "127.0.0.1");
    /* A coordinator whose files may not grow past 20 KB: the tile journal
     * fills up part way through a job, as on a full disk. */
    char coord[4096];
    snprintf(coord, sizeof coord, "%s", util_bin("tessera-coordinator"));
    fflush(NULL);
    s.pid = fork();
    if (s.pid == 0) {
        struct rlimit rl = {20000, 20000};
        setrlimit(RLIMIT_FSIZE, &rl);
        int fd = open(s.log, O_WRONLY | O_CREAT | O_APPEND, 0644);
        dup2(fd, 1);
        dup2(fd, 2);
        execl(coord, coord, "--listen", s.addr, "--data-dir", s.dir, "--max-upload", "1", "--max-jobs", "1",
              (char *)NULL);
        _exit(127);
    }
    CHECK(util_wait_for_text(s.log, "listening on", LONG) == 0, "no coordinator; log %s", s.log);
    char out[8192];
    /* A scene whose mesh is over the 1 MiB upload limit. */
    static char obj[1600000];
    size_t n = 0;
    while (n < sizeof obj - 64) n += (size_t)snprintf(obj + n, sizeof obj - n, "v %zu 0 0\n", n);
    util_write_temp("huge.obj", obj);
    const char *big = util_write_temp(
        "huge.json", "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -3], \"look_at\": [0, 0, 0], \"fov\": 40},"
                     " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
                     " \"shapes\": [{\"type\": \"mesh\", \"file\": \"huge.obj\", \"material\": \"w\"}]}");
    int st = cli(&s, out, sizeof out, "submit %s", big);
    CHECK(st == 1 && strstr(out, "huge.json: the scene and its meshes are 1.5 MiB; the coordinator accepts at most 1.0 MiB"),
          "upload limit (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "submit " SCENE " --tile-size 8");
    CHECK(st == 0 && job_id(out) == 1, "submit (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "submit " SCENE);
    CHECK(st == 1 && strstr(out, "the queue is full (1 jobs)"), "job limit (%d): %s", st, out);
    pid_t w = worker_start(&s, "w", "0");
    CHECK(util_wait_for_text(s.log, "job 1 failed", LONG) == 0, "the full journal went unnoticed; log %s", s.log);
    st = cli(&s, out, sizeof out, "status 1");
    CHECK(st == 0 && strstr(out, "failed") && strstr(out, "1.tiles: cannot journal tile") && strstr(out, "File too large"),
          "status after a full disk (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "fetch 1 -o %s", util_temp_path("never.png"));
    CHECK(st == 1 && strstr(out, "job 1 is failed"), "fetch of a failed job (%d): %s", st, out);
    worker_stop(w);
    service_stop(&s);
}

/* Two coordinators on one data dir both accepted job 6 and one was lost
 * (issue 18): the second now refuses to start, naming the dir and the
 * holder's PID, and a lock left by a killed coordinator blocks nothing. */
TEST(service_second_coordinator_on_a_data_dir_is_refused) {
    service s = {0};
    service_start(&s, "svc-lock");
    char cmd[4096], out[8192], want[1024];
    snprintf(cmd, sizeof cmd, "timeout %d %s --data-dir %s --listen 127.0.0.1:%d", (int)LONG,
             util_bin("tessera-coordinator"), s.dir, util_free_port());
    int st = util_run(cmd, out, sizeof out);
    snprintf(want, sizeof want, "%s: in use by another tessera-coordinator (PID %d, lock %s/lock)", s.dir, (int)s.pid,
             s.dir);
    CHECK(st == 1 && strstr(out, want), "second coordinator on %s (%d): %s", s.dir, st, out);
    st = cli(&s, out, sizeof out, "submit " SCENE);
    CHECK(st == 0 && job_id(out) == 1, "the first coordinator after the refusal (%d): %s", st, out);
    kill(s.pid, SIGKILL); /* the kernel drops the lock; the file stays */
    util_wait(s.pid, LONG, NULL);
    service_start(&s, "svc-lock");
    st = cli(&s, out, sizeof out, "status 1");
    CHECK(st == 0 && strstr(out, "queued"), "restart after kill -9 with the lock file left (%d): %s; log %s", st, out,
          s.log);
    service_stop(&s);
}

/* The tEXt chunks of a PNG file as "keyword=text\n" lines in out. Returns
 * how many, or -1 when the file is not a PNG. */
static int png_text_chunks(const char *path, char *out, size_t cap) {
    size_t len = 0;
    char err[256];
    uint8_t *d = (uint8_t *)file_read_all(path, 1 << 24, &len, err, sizeof err);
    int n = -1;
    size_t used = 0;
    out[0] = '\0';
    if (d && len > 8 && memcmp(d, "\x89PNG\r\n\x1a\n", 8) == 0) n = 0;
    for (size_t p = 8; n >= 0 && p + 12 <= len;) {
        size_t l = (size_t)d[p] << 24 | (size_t)d[p + 1] << 16 | (size_t)d[p + 2] << 8 | d[p + 3];
        if (p + 12 + l > len) break;
        if (memcmp(d + p + 4, "tEXt", 4) == 0 && used + l + 2 < cap) {
            memcpy(out + used, d + p + 8, l);
            char *nul = memchr(out + used, '\0', l);
            if (nul) *nul = '=';
            used += l;
            out[used++] = '\n';
            out[used] = '\0';
            n++;
        }
        p += 12 + l;
    }
    free(d);
    return n;
}

/* `render`, `submit --wait` and `fetch` write the same header: the EXR
 * files (and PNG files) of one render are the same bytes whichever path
 * wrote them, and carry tessera:scene, spp, seed and version (issue 18). */
TEST(service_images_carry_the_render_header_whichever_command_wrote_them) {
    service s = {0};
    service_start(&s, "svc-meta");
    pid_t w = worker_start(&s, "wm", "0");
    char out[8192], cmd[4096], path[6][256];
    static const char *const names[6] = {"meta-render.exr", "meta-submit.exr", "meta-fetch.exr",
                                         "meta-render.png", "meta-submit.png", "meta-fetch.png"};
    for (int i = 0; i < 6; i++) snprintf(path[i], sizeof path[i], "%s", util_temp_path(names[i]));
    for (int k = 0; k < 2; k++) { /* EXR, then PNG */
        snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 --no-progress -o %s", harness_tessera(), path[3 * k]);
        int st = util_run(cmd, out, sizeof out);
        CHECK(st == 0, "render (%d): %s", st, out);
        st = cli(&s, out, sizeof out, "submit " SCENE " --wait -o %s", path[3 * k + 1]);
        CHECK(st == 0, "submit --wait (%d): %s", st, out);
        st = cli(&s, out, sizeof out, "fetch %d -o %s", k + 1, path[3 * k + 2]);
        CHECK(st == 0, "fetch (%d): %s", st, out);
        CHECK(util_same_file(path[3 * k], path[3 * k + 1]) && util_same_file(path[3 * k], path[3 * k + 2]),
              "%s, %s and %s differ", path[3 * k], path[3 * k + 1], path[3 * k + 2]);
    }
    static const char *const want[] = {"tessera:scene", SCENE, "tessera:spp", "64", "tessera:seed", "1",
                                       "tessera:version", TESSERA_VERSION};
    snprintf(cmd, sizeof cmd, "exrheader %s", path[2]);
    int st = util_run(cmd, out, sizeof out);
    for (int i = 0; i < 8; i += 2) {
        char line[256];
        snprintf(line, sizeof line, "%s (type string): \"%s\"", want[i], want[i + 1]);
        CHECK(st == 0 && strstr(out, line), "exrheader %s lacks %s: %s", path[2], line, out);
    }
    char text[4096];
    int n = png_text_chunks(path[5], text, sizeof text);
    for (int i = 0; i < 8; i += 2) {
        char line[256];
        snprintf(line, sizeof line, "%s=%s\n", want[i], want[i + 1]);
        CHECK(n == 4 && strstr(text, line), "%s: %d tEXt chunks, lacking %s: %s", path[5], n, line, text);
    }
    snprintf(cmd, sizeof cmd, "iinfo -v %s", path[5]); /* an independent PNG reader sees them too */
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "tessera:spp: \"64\"") && strstr(out, "tessera:scene: \"" SCENE "\""),
          "iinfo -v %s: %s", path[5], out);
    worker_stop(w);
    service_stop(&s);
}

/* Tiles of an 8-pixel tiling of img that are all zero, as ranges like the
 * coordinator's warning ("0-3, 9"); returns how many. */
static int black_tiles(const image *img, const image *ref, int *matching, char *out, size_t cap) {
    int tiles_x = (img->width + 7) / 8, tiles_y = (img->height + 7) / 8, black = 0, prev = -2, start = -1;
    size_t used = 0;
    out[0] = '\0';
    *matching = 0;
    for (int t = 0; t <= tiles_x * tiles_y; t++) {
        int zero = 0, same = 0;
        if (t < tiles_x * tiles_y) {
            zero = same = 1;
            for (int y = (t / tiles_x) * 8; y < (t / tiles_x) * 8 + 8 && y < img->height; y++)
                for (int x = (t % tiles_x) * 8; x < (t % tiles_x) * 8 + 8 && x < img->width; x++)
                    for (int c = 0; c < 3; c++) {
                        size_t i = 3 * ((size_t)y * (size_t)img->width + (size_t)x) + (size_t)c;
                        zero &= img->rgb[i] == 0.0f;
                        same &= img->rgb[i] == ref->rgb[i];
                    }
            black += zero;
            *matching += same && !zero;
        }
        if (zero && prev != t - 1) start = t;
        if (!zero && prev == t - 1 && start >= 0) {
            used += (size_t)snprintf(out + used, cap - used, start == t - 1 ? "%s%d" : "%s%d-%d", used ? ", " : "",
                                     start, t - 1);
            start = -1;
        }
        if (zero) prev = t;
    }
    return black;
}

/* fetch --partial of a running job, then of the same job cancelled and
 * after a restart: the 10 tiles journaled so far, the others black and
 * named in a warning; without --partial, an error that says how. */
TEST(service_fetch_partial_of_a_running_then_cancelled_job) {
    service s = {0};
    service_start(&s, "svc-partial");
    char hold[256], out[8192], img_path[3][256];
    snprintf(hold, sizeof hold, "%s", util_temp_path("svc-partial.hold"));
    util_touch(hold);
    pid_t w = worker_start_held(&s, "wp", hold, 10); /* 10 tiles, then it keeps them */
    int st = cli(&s, out, sizeof out, "submit " SCENE " --tile-size 8");
    CHECK(st == 0 && job_id(out) == 1, "submit (%d): %s", st, out);
    CHECK(util_wait_for_text(util_temp_path("wp.log"), UTIL_HOLDING, LONG) == 0, "the worker never held a tile");
    int done = 0;
    for (int i = 0; i < (int)(LONG * 20) && done < 10; i++) {
        cli(&s, out, sizeof out, "status 1 --json");
        const char *p = strstr(out, "\"tiles_done\":");
        if (p) sscanf(p, "\"tiles_done\":\t%d", &done);
        if (done < 10) util_sleep(0.05);
    }
    CHECK(done == 10, "%d tiles done; 10 expected", done);
    st = cli(&s, out, sizeof out, "fetch 1 -o %s", util_temp_path("never.pfm"));
    CHECK(st == 1 && strstr(out, "job 1 is running (10 of 64 tiles); fetch --partial writes what is done so far"),
          "fetch of a running job without --partial (%d): %s", st, out);
    image ref, got;
    char err[512], black_list[1024];
    CHECK(image_read(reference(), &ref, err, sizeof err) == 0, "%s", err);
    for (int k = 0; k < 3; k++) {
        static const char *const names[3] = {"partial-running.pfm", "partial-cancelled.pfm", "partial-restarted.pfm"};
        snprintf(img_path[k], sizeof img_path[k], "%s", util_temp_path(names[k]));
        if (k == 1) {
            st = cli(&s, out, sizeof out, "cancel 1");
            CHECK(st == 0, "cancel (%d): %s", st, out);
            CHECK(util_wait_for_text(s.log, "job 1 cancelled", LONG) == 0, "no cancel; log %s", s.log);
        }
        if (k == 2) { /* a partial fetch's PFM left by a coordinator killed while making it goes at the start */
            service_stop(&s);
            char stale[512];
            snprintf(stale, sizeof stale, "%s/jobs/1.partial-9.pfm", s.dir);
            util_touch(stale);
            service_start(&s, "svc-partial");
            /* It goes as the jobs are loaded, just after "listening on" is
             * logged (CI once looked in between). */
            for (int i = 0; i < (int)(LONG * 100) && access(stale, F_OK) == 0; i++) util_sleep(0.01);
            CHECK(access(stale, F_OK) != 0, "%s is still there after a restart", stale);
        }
        st = cli(&s, out, sizeof out, "fetch 1 --partial -o %s", img_path[k]);
        CHECK(st == 0, "fetch --partial (%d): %s", st, out);
        if (st != 0 || image_read(img_path[k], &got, err, sizeof err) != 0) continue;
        int matching = 0, black = black_tiles(&got, &ref, &matching, black_list, sizeof black_list);
        CHECK(black == 54 && matching == 10, "%s: %d tiles black, %d as in the full render; 54 and 10 expected",
              img_path[k], black, matching);
        char warning[2048];
        snprintf(warning, sizeof warning,
                 "warning: job 1 is %s: 54 of 64 tiles are not rendered yet and are black in %s: tiles %s (8x8 pixels",
                 k == 0 ? "running" : "cancelled", img_path[k], black_list);
        CHECK(strstr(out, warning), "fetch --partial does not warn \"%s\": %s", warning, out);
        image_free(&got);
    }
    image_free(&ref);
    unlink(hold);
    worker_stop(w);
    service_stop(&s);
}

/* A number field of `tessera status --json` output, or -1. */
static double json_number(const char *out, const char *key) {
    char want[64];
    snprintf(want, sizeof want, "\"%s\":", key);
    const char *p = strstr(out, want);
    return p ? atof(p + strlen(want)) : -1;
}

/* A job behind a higher-priority one is queued, not running with ETA 0 s;
 * its speed counts from its first tile handed out; peers' text in the table
 * is escaped; submit -v says the size the coordinator set. */
TEST(service_status_shows_queued_jobs_and_speed_over_rendering_time) {
    service s = {0};
    service_start(&s, "svc-queued");
    char hold[256], wlog[256], out[8192], scene_text[65536], esc_scene[512];
    snprintf(hold, sizeof hold, "%s", util_temp_path("svc-queued.hold"));
    snprintf(wlog, sizeof wlog, "%s", util_temp_path("queued-w.log"));
    util_touch(hold);
    pid_t w = worker_start_held(&s, "queued-w", hold, 0); /* 1 thread + 1 prefetch: two tiles of job 1 */
    int a = job_id((cli(&s, out, sizeof out, "submit " SCENE " --priority 5"), out));
    CHECK(util_wait_for_text(wlog, UTIL_HOLDING, LONG) == 0, "the worker holds no tile; log %s", wlog);
    util_run("cat " SCENE, scene_text, sizeof scene_text);
    snprintf(esc_scene, sizeof esc_scene, "%s", util_write_temp("esc\033[2Jname.json", scene_text));
    int st = cli(&s, out, sizeof out, "submit '%s' --width 32 -v", esc_scene);
    int b = job_id(out);
    CHECK(a == 1 && b == 2 && strstr(out, "job 2: 32x32 (one side given"), "submit -v (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "status");
    CHECK(st == 0 && strstr(out, "queued") && strstr(out, "running"), "status of a queued job (%d): %s", st, out);
    CHECK(!strchr(out, '\033') && strstr(out, "esc\\x1b[2Jname.json"), "a job name was printed unescaped: %s", out);
    st = cli(&s, out, sizeof out, "status 2 --json");
    CHECK(st == 0 && strstr(out, "\"state\":\t\"queued\"") && json_number(out, "eta_s") == 0 &&
              json_number(out, "samples_per_s") == 0,
          "status --json of the queued job: %s", out);
    util_sleep(1.5); /* job 2 waits; its speed must not count this */
    unlink(hold);
    CHECK(util_wait_for_text(s.log, "job 2 done", LONG) == 0, "job 2 did not finish; log %s", s.log);
    st = cli(&s, out, sizeof out, "status 2 --json");
    double submitted = json_number(out, "submitted"), since = json_number(out, "rendering_since");
    CHECK(st == 0 && since > 0 && since - submitted >= 1.4,
          "job 2's rendering time starts at submission (%.3f) not at its first tile (%.3f): %s", submitted, since, out);
    worker_stop(w);
    service_stop(&s);
}

/* SIGINT while `submit --wait` waits: the job is cancelled on the
 * coordinator and the client exits with 130. Meanwhile its progress, with
 * stderr not a terminal, is plain lines. */
TEST(service_submit_wait_sigint_cancels_the_job) {
    service s = {0};
    service_start(&s, "svc-sigint");
    char hold[256], wlog[256], clog[256], img[256], out[8192], tessera[4096], env_addr[128];
    snprintf(hold, sizeof hold, "%s", util_temp_path("svc-sigint.hold"));
    snprintf(wlog, sizeof wlog, "%s", util_temp_path("sigint-w.log"));
    snprintf(clog, sizeof clog, "%s", util_temp_path("sigint-client.log"));
    snprintf(img, sizeof img, "%s", util_temp_path("svc-sigint.pfm"));
    snprintf(tessera, sizeof tessera, "%s", harness_tessera());
    snprintf(env_addr, sizeof env_addr, "TESSERA_COORDINATOR=%s", s.addr);
    util_touch(hold);
    pid_t w = worker_start_held(&s, "sigint-w", hold, 0);
    const char *argv[] = {tessera, "submit", SCENE, "--wait", "-o", img, NULL};
    const char *env[] = {env_addr, "TESSERA_PROGRESS_SECONDS=0.1", NULL};
    pid_t c = util_spawn_env(argv, clog, env);
    CHECK(util_wait_for_text(wlog, UTIL_HOLDING, LONG) == 0 && util_wait_for_text(clog, "job 1 submitted", LONG) == 0,
          "the job did not start; logs %s %s", wlog, clog);
    /* stderr is a file: plain progress lines, not a bar */
    CHECK(util_wait_for_text(clog, "progress: 0/4 tiles (0%)", LONG) == 0 && !util_file_count(clog, "\r"),
          "no plain progress lines from submit --wait; log %s", clog);
    kill(c, SIGINT);
    int st = util_wait(c, LONG, NULL);
    unlink(hold);
    CHECK(st == 130 && util_file_count(clog, "interrupted: job 1 cancelled on the coordinator"),
          "submit --wait after SIGINT exited %d; log %s", st, clog);
    CHECK(access(img, F_OK) != 0, "%s was written after SIGINT", img);
    st = cli(&s, out, sizeof out, "status 1");
    CHECK(st == 0 && strstr(out, "cancelled"), "job 1 after the client's SIGINT (%d): %s", st, out);
    worker_stop(w);
    service_stop(&s);
}

/* Replace path's contents at once (a rename, as an operator rotating a
 * token would). */
static void rewrite(const char *path, const char *text) {
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.new", path);
    FILE *f = fopen(tmp, "w");
    fputs(text, f);
    fclose(f);
    rename(tmp, path);
}

/* --client-tokens DIR: a token per user (DIR/NAME.token). A user's token
 * speaks as that user only; no one else may take the name, not even with
 * the shared client token; a user cannot cancel another's job; a user
 * whose file is deleted is refused after SIGHUP. */
TEST(service_per_user_client_tokens) {
    char wt[256], ct[256], dir[256], alice[300], bob[300], out[8192];
    snprintf(wt, sizeof wt, "%s", util_write_temp("users-worker.token", "worker secret\n"));
    snprintf(ct, sizeof ct, "%s", util_write_temp("users-client.token", "shared client secret\n"));
    snprintf(dir, sizeof dir, "%s", util_temp_path("users.d"));
    mkdir(dir, 0700);
    snprintf(alice, sizeof alice, "%s/alice.token", dir);
    snprintf(bob, sizeof bob, "%s/bob.token", dir);
    rewrite(alice, "alice's own secret\n");
    rewrite(bob, "bob's own secret\n");
    service s = {.extra = {"--worker-token-file", wt, "--client-token-file", ct, "--client-tokens", dir}};
    service_start(&s, "svc-users");
    /* No worker: alice's job stays queued. */
    int st = cli(&s, out, sizeof out, "submit " SCENE " --client-name alice --token-file %s", alice);
    CHECK(st == 0 && job_id(out) == 1, "alice's submit with her own token (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "status --client-name alice --token-file %s", bob);
    CHECK(st == 1 && strstr(out, "authentication failed"), "bob's token spoke as alice (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "status --client-name alice --token-file %s", ct);
    CHECK(st == 1 && strstr(out, "authentication failed"), "the shared client token spoke as alice (%d): %s", st,
          out);
    CHECK(util_file_count(s.log, "(calling itself client alice): authentication failed (wrong token for user alice, "
                                 "who has a token of their own)") == 2,
          "the refusals of alice's name not logged with the reason; log %s", s.log);
    st = cli(&s, out, sizeof out, "cancel 1 --client-name bob --token-file %s", bob);
    CHECK(st == 1 && strstr(out, "belongs to client alice"), "bob cancelled alice's job (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "status --client-name carol --token-file %s", ct);
    CHECK(st == 0, "the shared client token under a name no user has (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "status --client-name carol --token-file %s", alice);
    CHECK(st == 1 && strstr(out, "authentication failed"), "alice's token spoke as carol (%d): %s", st, out);
    /* bob waits on a job of his over an open link; his file goes: the link
     * is cut at the SIGHUP and he is refused from then on; alice keeps her
     * job. */
    char waitlog[300];
    snprintf(waitlog, sizeof waitlog, "%s", util_temp_path("svc-users-bob-wait.log"));
    const char *wargv[] = {harness_tessera(), "submit", SCENE, "--wait", "--coordinator", s.addr, "--client-name", "bob",
                           "--token-file", bob, NULL};
    pid_t waiting = util_spawn(wargv, waitlog);
    CHECK(util_wait_for_text(s.log, "job 2 submitted", LONG) == 0, "bob's job never came; log %s", s.log);
    unlink(bob);
    kill(s.pid, SIGHUP);
    CHECK(util_wait(waiting, LONG, NULL) == 1 && util_file_count(waitlog, "your token was revoked or replaced"),
          "bob's open link was not cut when his token went; his log %s", waitlog);
    CHECK(util_file_count(s.log, "SIGHUP: client bob at ") && util_file_count(s.log, "its client token is gone"),
          "the cut not logged; log %s", s.log);
    CHECK(util_wait_for_text(s.log, "SIGHUP: token files re-read (worker, client, 1 users)", LONG) == 0,
          "no reload of the users folder logged; log %s", s.log);
    rewrite(util_temp_path("users-bob-old.token"), "bob's own secret\n");
    st = cli(&s, out, sizeof out, "status --client-name bob --token-file %s", util_temp_path("users-bob-old.token"));
    CHECK(st == 1 && strstr(out, "authentication failed"), "bob's removed token still works (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "cancel 1 --client-name alice --token-file %s", alice);
    CHECK(st == 0, "alice could not cancel her own job (%d): %s", st, out);
    service_stop(&s);
    /* Bad folders are refused at start, naming the folder. */
    char cmd[2048];
    snprintf(cmd, sizeof cmd, "%s --data-dir %s --worker-token-file %s --client-tokens %s/none 2>&1",
             util_bin("tessera-coordinator"), util_temp_path("svc-users-bad"), wt, dir);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 2 && strstr(out, "users.d/none: cannot open the users folder"), "a missing folder (%d): %s", st, out);
}

/* Separate credentials: a worker token only renders, a client token only
 * submits and handles its own jobs, the admin token any job; SIGHUP
 * rotates them without a restart, and a sealed worker link opened before
 * the rotation goes on rendering. */
TEST(service_worker_client_admin_tokens_and_sighup_rotation) {
    char wt[256], ct[256], at[256], old_w[256], old_c[256], out[8192], img[256];
    snprintf(wt, sizeof wt, "%s", util_write_temp("cls-worker.token", "worker secret one\n"));
    snprintf(ct, sizeof ct, "%s", util_write_temp("cls-client.token", "client secret one\n"));
    snprintf(at, sizeof at, "%s", util_write_temp("cls-admin.token", "admin secret one\n"));
    snprintf(old_w, sizeof old_w, "%s", util_write_temp("cls-worker-old.token", "worker secret one\n"));
    snprintf(old_c, sizeof old_c, "%s", util_write_temp("cls-client-old.token", "client secret one\n"));
    service s = {.extra = {"--worker-token-file", wt, "--client-token-file", ct, "--admin-token-file", at}};
    service_start(&s, "svc-classes");
    /* The wrong class is refused, with the fault in the log only. */
    pid_t intruder = worker_start_token(&s, "clientasworker", "0", ct);
    CHECK(util_wait(intruder, LONG, NULL) == 1, "a worker holding the client token was not refused");
    CHECK(util_file_count(s.log, "(calling itself worker clientasworker): authentication failed (the client token, "
                                 "which may not register as a worker)"),
          "refusal of the client token as a worker not logged; log %s", s.log);
    int st = cli(&s, out, sizeof out, "submit " SCENE " --token-file %s", wt);
    CHECK(st == 1 && strstr(out, "authentication failed"), "the worker token submitted a job (%d): %s", st, out);
    CHECK(util_file_count(s.log, "authentication failed (the worker token, which may not act as a client)"),
          "refusal of the worker token as a client not logged; log %s", s.log);
    /* Jobs belong to the client name that submitted them. */
    pid_t w = worker_start_token(&s, "member", "0", wt);
    snprintf(img, sizeof img, "%s", util_temp_path("svc-classes.pfm"));
    st = cli(&s, out, sizeof out, "submit " SCENE " --client-name alice --token-file %s --wait -o %s", ct, img);
    CHECK(st == 0 && util_same_file(img, reference()), "alice's submit failed (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "fetch 1 -o %s --client-name bob --token-file %s", img, ct);
    CHECK(st == 1 && strstr(out, "job 1 belongs to client alice"), "bob fetched alice's job (%d): %s", st, out);
    st = cli(&s, out, sizeof out, "cancel 1 --client-name bob --token-file %s", ct);
    CHECK(st == 1 && strstr(out, "belongs to client alice"), "bob cancelled alice's job (%d): %s", st, out);
    CHECK(util_file_count(s.log, "(bob, client token): cancel of job 1 refused: it belongs to alice"),
          "bob's refusal not logged; log %s", s.log);
    st = cli(&s, out, sizeof out, "fetch 1 -o %s --client-name bob --token-file %s", img, at);
    CHECK(st == 0, "the admin token could not fetch alice's job (%d): %s", st, out);
    /* Rotation: new worker and client tokens, read on SIGHUP. */
    rewrite(wt, "worker secret two\n");
    rewrite(ct, "client secret two\n");
    kill(s.pid, SIGHUP);
    CHECK(util_wait_for_text(s.log, "SIGHUP: token files re-read (worker, client, admin)", LONG) == 0,
          "no rotation logged; log %s", s.log);
    st = cli(&s, out, sizeof out, "status --token-file %s", old_c);
    CHECK(st == 1 && strstr(out, "authentication failed"), "the old client token still works (%d): %s", st, out);
    pid_t stale = worker_start_token(&s, "stale", "0", old_w);
    CHECK(util_wait(stale, LONG, NULL) == 1, "a worker with the old worker token was not refused");
    /* The worker connected before the rotation (old token, sealed) renders the new job. */
    st = cli(&s, out, sizeof out, "submit " SCENE " --client-name alice --token-file %s --wait -o %s", ct, img);
    CHECK(st == 0 && util_same_file(img, reference()), "submit after the rotation failed (%d): %s", st, out);
    CHECK(util_file_count(util_temp_path("member.log"), "refused") == 0, "the sealed worker was dropped");
    /* A token file that cannot be read keeps every old token. */
    unlink(at);
    kill(s.pid, SIGHUP);
    CHECK(util_wait_for_text(s.log, "keeping the previous tokens", LONG) == 0, "bad reload not logged; log %s",
          s.log);
    st = cli(&s, out, sizeof out, "status --token-file %s", ct);
    CHECK(st == 0, "the current client token stopped working after a failed reload (%d): %s", st, out);
    worker_stop(w);
    service_stop(&s);
}

/* The finished image is written off the loop (jobstore.c): held there by
 * the test hook, the coordinator still answers status at once, refuses a
 * cancel of the rendered job with the reason, and the job is done, its
 * image the same bytes as a render in one process, once the write goes. */
TEST(service_finished_image_is_saved_off_the_loop) {
    service s = {0};
    char hold[256], env[320];
    snprintf(hold, sizeof hold, "%s", util_temp_path("svc-save.hold"));
    util_touch(hold);
    snprintf(env, sizeof env, "%s", hold);
    setenv("TESSERA_TEST_SAVE_HOLD_FILE", env, 1);
    service_start(&s, "svc-save");
    unsetenv("TESSERA_TEST_SAVE_HOLD_FILE");
    pid_t w = worker_start(&s, "saver", "0");
    char out[8192];
    int st = cli(&s, out, sizeof out, "submit " SCENE " --tile-size 16");
    CHECK(st == 0 && job_id(out) == 1, "submit (%d): %s", st, out);
    CHECK(util_wait_for_text(s.log, "test hold: saving job 1 waits", LONG) == 0, "the save was not held; log %s",
          s.log);
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    st = cli(&s, out, sizeof out, "status 1");
    clock_gettime(CLOCK_MONOTONIC, &b);
    double took = (double)(b.tv_sec - a.tv_sec) + (b.tv_nsec - a.tv_nsec) / 1e9;
    CHECK(st == 0 && strstr(out, "running"), "status while the image is saved (%d): %s", st, out);
    CHECK(took < 10, "status took %.1f s while the image was saved", took);
    st = cli(&s, out, sizeof out, "cancel 1");
    CHECK(st != 0 && strstr(out, "job 1 is rendered: its image is being saved"), "cancel while saving (%d): %s", st,
          out);
    unlink(hold);
    CHECK(util_wait_for_text(s.log, "job 1 done", LONG) == 0, "job 1 did not finish; log %s", s.log);
    char got[300], want[300], cmd[4096], rout[4096];
    snprintf(got, sizeof got, "%s", util_temp_path("svc-save.pfm"));
    snprintf(want, sizeof want, "%s", util_temp_path("svc-save-render.pfm"));
    st = cli(&s, out, sizeof out, "fetch 1 -o %s", got);
    CHECK(st == 0, "fetch (%d): %s", st, out);
    snprintf(cmd, sizeof cmd, "%s render %s --workers 0 --threads 1 --no-progress -o %s", harness_tessera(), SCENE,
             want);
    CHECK(util_run(cmd, rout, sizeof rout) == 0, "render: %s", rout);
    CHECK(util_same_file(got, want), "the saved image differs from a render in one process (%s, %s)", got, want);
    worker_stop(w);
    service_stop(&s);
}

/* A worker holds the bundles its connection was sent until the coordinator
 * says forget_scene: past FARM_PEER_SCENES (8) it forgets the one used
 * longest ago that no unfinished job needs, and both sides agree on what
 * the worker holds. Before, the worker dropped a bundle of its own accord
 * once it held 8, the coordinator still thought it had it, and a later job
 * of that scene made the worker call the coordinator a protocol breaker and
 * reconnect. 10 scenes (different seeds, so different bundles), then the
 * 9th and the 1st again, on one worker: every job done on one connection,
 * 3 bundles forgotten (the 1st and 2nd for the 9th and 10th; the 3rd for
 * the 1st, sent again), the 1st's image the same both times. */
TEST(service_worker_forgets_scenes_as_the_coordinator_says) {
    service s = {0};
    service_start(&s, "svc-forget");
    char wlog[256], path[4096];
    snprintf(wlog, sizeof wlog, "%s", util_temp_path("svc-forget-w.log"));
    snprintf(path, sizeof path, "%s", util_bin("tessera-worker"));
    const char *argv[] = {path, "--connect", s.addr, "--threads", "1", "--name", "wf", "--retry-max", "1", "-v", NULL};
    pid_t w = util_spawn(argv, wlog);
    char err[256];
    size_t len = 0;
    char *text = file_read_all(SCENE, 1 << 20, &len, err, sizeof err);
    CHECK(text, "%s", err);
    const char *seed_at = text ? strstr(text, "\"seed\": 1") : NULL;
    CHECK(seed_at, SCENE " has no \"seed\": 1");
    static const int order[] = {1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 9, 1};
    for (size_t k = 0; seed_at && k < sizeof order / sizeof order[0]; k++) {
        char name[64], scene[8192], img[300], out[4096];
        snprintf(name, sizeof name, "forget-%d.json", order[k]);
        snprintf(scene, sizeof scene, "%.*s\"seed\": %d%s", (int)(seed_at - text), text, order[k],
                 seed_at + strlen("\"seed\": 1"));
        util_write_temp(name, scene);
        snprintf(img, sizeof img, "%s", util_temp_path(k < 11 ? name : "forget-1-again.json"));
        strcpy(strrchr(img, '.'), ".pfm");
        int st = cli(&s, out, sizeof out, "submit %s --width 16 --height 16 --spp 2 --wait -q -o %s",
                     util_temp_path(name), img);
        CHECK(st == 0 && strstr(out, "done"), "scene %d (submission %zu): status %d: %s", order[k], k + 1, st, out);
    }
    free(text);
    CHECK(!util_file_count(wlog, "broke the protocol") && util_file_count(wlog, "joined the farm") == 1,
          "the worker lost its connection; log %s", wlog);
    CHECK(util_file_count(wlog, "forgotten, as the coordinator says") == 3, "want 3 bundles forgotten; log %s", wlog);
    CHECK(util_same_file(util_temp_path("forget-1.pfm"), util_temp_path("forget-1-again.pfm")),
          "the first scene rendered again differs");
    worker_stop(w);
    service_stop(&s);
}

/* A coordinator on IPv6 loopback: its log, the workers table and the
 * per-address limit name the address as [::1]:PORT and ::1 (not
 * "::1:PORT"), and a job renders the reference's bytes. */
TEST(service_over_ipv6_names_addresses_with_brackets) {
    service s = {0};
    service_place(&s, "svc-v6", "::1");
    s.extra[0] = "--max-workers-per-address";
    s.extra[1] = "1";
    service_start(&s, "svc-v6");
    if (util_file_count(s.log, "cannot listen")) { /* a host without IPv6 loopback */
        printf("    skipped: no IPv6 loopback here\n");
        util_wait(s.pid, LONG, NULL);
        return;
    }
    char want[80], out[8192], img[256];
    snprintf(want, sizeof want, "listening on [::1]:%d,", s.port);
    CHECK(util_file_count(s.log, want) == 1, "no \"%s\" in %s", want, s.log);
    pid_t w1 = worker_start(&s, "v6a", "0");
    int st = 1;
    for (int i = 0; i < 500 && (st || !strstr(out, "v6a")); i++, util_sleep(0.02)) st = cli(&s, out, sizeof out, "workers");
    CHECK(st == 0 && strstr(out, "v6a") && strstr(out, "[::1]:"), "workers table over IPv6: %s", out);
    pid_t w2 = worker_start(&s, "v6b", "0");
    for (int i = 0; i < 500 && !util_file_count(s.log, "::1 has 1 worker connected"); i++) util_sleep(0.02);
    CHECK(util_file_count(s.log, "::1 has 1 worker connected (--max-workers-per-address 1)") >= 1,
          "the second worker from ::1 was not refused by address; log %s", s.log);
    snprintf(img, sizeof img, "%s", util_temp_path("svc-v6.pfm"));
    st = cli(&s, out, sizeof out, "submit " SCENE " --wait -o %s", img);
    CHECK(st == 0 && util_same_file(img, reference()), "a job over IPv6 (%d): %s", st, out);
    kill(w2, SIGTERM);
    util_wait(w2, LONG, NULL);
    worker_stop(w1);
    service_stop(&s);
}

/* A worker told to leave (SIGTERM) while it loads a big scene stops the
 * load at its next step (between shapes, or within the BVH build) instead
 * of finishing a load nobody will use: the log says "cancelled" and it
 * exits well before the load would have ended. The scene: 40 instances of
 * a 65,536-triangle grid (2.6M triangles; the OBJ parsed once). */
TEST(service_worker_leaving_cancels_a_scene_load) {
    service s = {0};
    service_start(&s, "svc-cancel-load");
    char obj[600], json[600], log[300], name[64];
    snprintf(obj, sizeof obj, "%s", util_temp_path("cancel-grid.obj"));
    FILE *f = fopen(obj, "w");
    CHECK(f != NULL, "cannot write %s", obj);
    if (!f) return;
    const int n = 128; /* (n+1)^2 vertices, 2 n^2... 4 n^2 = 65,536 triangles: two grids of n x n quads */
    for (int g = 0; g < 2; g++)
        for (int y = 0; y <= n; y++)
            for (int x = 0; x <= n; x++) fprintf(f, "v %d %d %d\n", x, y, g);
    for (int g = 0; g < 2; g++)
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                int a = g * (n + 1) * (n + 1) + y * (n + 1) + x + 1;
                fprintf(f, "f %d %d %d\nf %d %d %d\n", a, a + 1, a + n + 2, a, a + n + 2, a + n + 1);
            }
    fclose(f);
    char *text = malloc(1 << 20);
    int len = snprintf(text, 1 << 20, "{\"render\": {\"width\": 64, \"height\": 64, \"spp\": 1}, \"camera\": "
                       "{\"type\": \"perspective\", \"position\": [64, 64, -300], \"look_at\": [64, 64, 0], \"up\": [0, 1, 0], "
                       "\"fov\": 40}, \"materials\": "
                       "{\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, \"shapes\": [");
    for (int i = 0; i < 40; i++)
        len += snprintf(text + len, (size_t)(1 << 20) - (size_t)len, "%s{\"type\": \"mesh\", \"file\": "
                        "\"cancel-grid.obj\", \"material\": \"m\", \"translate\": [0, 0, %d]}", i ? ", " : "", 3 * i);
    snprintf(text + len, (size_t)(1 << 20) - (size_t)len, "], \"background\": [1, 1, 1]}\n");
    snprintf(json, sizeof json, "%s", util_write_temp("cancel-load.json", text));
    free(text);
    snprintf(log, sizeof log, "%s", util_temp_path("cancel-load-worker.log"));
    snprintf(name, sizeof name, "%s", util_bin("tessera-worker"));
    const char *argv[] = {name, "--connect", s.addr, "--threads", "1", "--name", "loader", "-v", NULL};
    pid_t w = util_spawn(argv, log);
    char out[8192];
    int st = cli(&s, out, sizeof out, "submit %s", json);
    CHECK(st == 0, "submit (%d): %s", st, out);
    if (st == 0)
        CHECK(util_wait_for_text(log, "job 1: scene ", LONG) == 0, "the worker never started the job; log %s", log);
    util_sleep(0.3);
    kill(w, SIGTERM);
    double t0 = util_now();
    st = util_wait(w, LONG, NULL);
    double took = util_now() - t0;
    CHECK(st == 0 && util_file_count(log, "cancelled") == 1 && !util_file_count(log, "loaded, "),
          "the load was not cancelled (status %d, %.2f s); log %s", st, took, log);
    CHECK(took < 5 * harness_slack(), "the worker took %.2f s to leave while loading; log %s", took, log);
    printf("    left %.2f s after SIGTERM, 0.3 s into the load\n", took);
    service_stop(&s);
}

/* submit - < model.glb: the streamed model is uploaded (it is no file, so
 * the check that uploads stay under the scene's folder passes it) and
 * renders the bytes `tessera render model.glb` gives. */
TEST(service_submit_of_a_model_from_stdin) {
    service s = {0};
    service_start(&s, "svc-stdin-model");
    pid_t w = worker_start(&s, "sm", "0");
    char out[8192], a[256], b[256], cmd[4096];
    snprintf(a, sizeof a, "%s", util_temp_path("svc-stdin-model.pfm"));
    snprintf(b, sizeof b, "%s", util_temp_path("svc-stdin-model-ref.pfm"));
    snprintf(cmd, sizeof cmd, "TESSERA_COORDINATOR=%s %s submit - --width 48 --spp 2 --wait -q -o %s "
             "< scenes/gltf/suzanne.glb 2>&1", s.addr, harness_tessera(), a);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 0, "submit - < suzanne.glb (%d): %s", st, out);
    snprintf(cmd, sizeof cmd, "%s render scenes/gltf/suzanne.glb --width 48 --spp 2 --workers 0 -q -o %s 2>&1",
             harness_tessera(), b);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && util_same_file(a, b), "the streamed model's image differs from the file's (%d): %s", st, out);
    worker_stop(w);
    service_stop(&s);
}

/* Jobs of one scene at another size, seed or depth share the worker's
 * loaded scene (each renders through its own view of it) and give the
 * bytes a render of their own settings gives, also a model framed by the
 * automatic camera (an OBJ alone), whose camera the view frames again for
 * its aspect ratio. */
TEST(service_jobs_of_other_sizes_and_seeds_share_a_loaded_scene) {
    service s = {0};
    service_start(&s, "svc-share-seed");
    char wlog[300], name[4096], out[8192], img[3][256], ref[256], cmd[4096];
    snprintf(wlog, sizeof wlog, "%s", util_temp_path("share-seed-worker.log"));
    snprintf(name, sizeof name, "%s", util_bin("tessera-worker"));
    const char *argv[] = {name, "--connect", s.addr, "--threads", "1", "--name", "sharer", "-v", NULL};
    pid_t w = util_spawn(argv, wlog);
    static const char *const opts[3] = {"--width 32 --height 32 --seed 1 --max-depth 8",
                                        "--width 32 --height 32 --seed 7 --max-depth 3 --roulette-depth 1",
                                        "--width 40 --height 24 --seed 1 --max-depth 8"};
    for (int i = 0; i < 3; i++) {
        snprintf(img[i], sizeof img[i], "%s", util_temp_path(i == 0 ? "share-a.pfm" : i == 1 ? "share-b.pfm" : "share-c.pfm"));
        int st = cli(&s, out, sizeof out, "submit " SCENE " --spp 4 %s --wait -q -o %s", opts[i], img[i]);
        CHECK(st == 0, "job %d (%d): %s", i + 1, st, out);
        snprintf(ref, sizeof ref, "%s", util_temp_path("share-ref.pfm"));
        snprintf(cmd, sizeof cmd, "%s render " SCENE " --spp 4 %s --workers 0 -q -o %s 2>&1", harness_tessera(), opts[i],
                 ref);
        st = util_run(cmd, out, sizeof out);
        CHECK(st == 0 && util_same_file(img[i], ref), "job %d (%s) differs from its in-process render (%d): %s", i + 1,
              opts[i], st, out);
    }
    CHECK(!util_same_file(img[0], img[1]), "the two seeds gave the same image");
    int loads = util_file_count(wlog, " loaded, "), shared = util_file_count(wlog, "shared, not loaded again");
    CHECK(loads == 1 && shared == 2, "want 1 load and 2 shared, got %d and %d; log %s", loads, shared, wlog);
    for (int i = 0; i < 2; i++) {
        int st = cli(&s, out, sizeof out, "submit scenes/meshes/tetrahedron.obj --width %d --height 24 --spp 2 --wait -q "
                     "-o %s", i ? 40 : 32, img[i]);
        CHECK(st == 0, "the OBJ at size %d (%d): %s", i, st, out);
        snprintf(cmd, sizeof cmd, "%s render scenes/meshes/tetrahedron.obj --width %d --height 24 --spp 2 --workers 0 -q "
                 "-o %s 2>&1", harness_tessera(), i ? 40 : 32, ref);
        st = util_run(cmd, out, sizeof out);
        CHECK(st == 0 && util_same_file(img[i], ref), "the OBJ at size %d differs from its in-process render (%d): %s", i,
              st, out);
    }
    loads = util_file_count(wlog, " loaded, "), shared = util_file_count(wlog, "shared, not loaded again");
    CHECK(loads == 2 && shared == 3, "the OBJ framed by the automatic camera at two sizes: want 1 more load and 1 "
          "more shared, got %d and %d; log %s", loads - 1, shared - 2, wlog);
    worker_stop(w);
    service_stop(&s);
}
