/* test_hostile.c - the coordinator against hostile or merely heavy clients
 * (issue 20): long listings, silent peers, bad numbers, idle connections,
 * full disks. Each test runs a real tessera-coordinator on loopback and
 * checks what a user would see; each is bounded (a few seconds). */
#include <arpa/inet.h>
#include <errno.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <poll.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "fileio.h"
#include "harness.h"
#include "net/protocol.h"
#include "net/wire.h"
#include "render/scene.h"
#include "render/scene_bundle.h"
#include "util.h"

#define HASH "0000000000000000000000000000000000000000000000000000000000000000"

typedef struct {
    char dir[256], log[256], addr[64];
    int port;
    pid_t pid;
} coord;


/* Start tessera-coordinator on a free port over the data dir c->dir (made
 * under the test folder when empty), with extra options (NULL-terminated).
 * Returns 0 once it listens, -1 after 30 s. */
static int coord_start(coord *c, const char *name, const char *const *extra) {
    if (!c->port) {
        c->port = util_free_port();
        if (!c->dir[0]) snprintf(c->dir, sizeof c->dir, "%s", util_temp_path(name));
        char logname[128];
        snprintf(logname, sizeof logname, "%s.log", name);
        snprintf(c->log, sizeof c->log, "%s", util_temp_path(logname));
        snprintf(c->addr, sizeof c->addr, "127.0.0.1:%d", c->port);
    }
    char bin[4096];
    snprintf(bin, sizeof bin, "%s", util_bin("tessera-coordinator"));
    const char *argv[32] = {bin, "--listen", c->addr, "--data-dir", c->dir, "--heartbeat", "0.2", "--worker-timeout", "2"};
    int n = 9;
    for (int i = 0; extra && extra[i] && n < 31; i++) argv[n++] = extra[i];
    argv[n] = NULL;
    int before = util_file_count(c->log, "listening on");
    c->pid = util_spawn(argv, c->log);
    for (int i = 0; i < 3000 && util_file_count(c->log, "listening on") == before; i++) util_sleep(0.01);
    return util_file_count(c->log, "listening on") > before ? 0 : -1;
}

static void coord_stop(coord *c) {
    kill(c->pid, SIGTERM);
    int st = util_wait(c->pid, 30, NULL);
    CHECK(st == 0, "coordinator exited with %d on SIGTERM; log %s", st, c->log);
    CHECK(!util_file_count(c->log, "Sanitizer") && !util_file_count(c->log, "runtime error"), "sanitizer report in %s",
          c->log);
}

/* CPU seconds (user + system) of the waited-for children of this process. */
static double children_cpu_s(void) {
    struct rusage ru;
    getrusage(RUSAGE_CHILDREN, &ru);
    return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)ru.ru_stime.tv_usec;
}

/* CPU seconds of a running process (from /proc), or 0. */
static double proc_cpu_s(pid_t pid) {
    char path[64], buf[1024];
    snprintf(path, sizeof path, "/proc/%d/stat", (int)pid);
    FILE *f = fopen(path, "r");
    size_t n = f ? fread(buf, 1, sizeof buf - 1, f) : 0;
    if (f) fclose(f);
    buf[n] = 0;
    const char *p = strrchr(buf, ')'); /* fields after the command name */
    unsigned long ut = 0, st = 0;
    if (p && sscanf(p + 2, "%*c %*d %*d %*d %*d %*d %*u %*u %*u %*u %*u %lu %lu", &ut, &st) != 2) ut = st = 0;
    return (double)(ut + st) / (double)sysconf(_SC_CLK_TCK);
}

/* How often text occurs in the file at path (whole file, any size). */
static int count_in(const char *path, const char *text) {
    size_t len;
    char err[256];
    char *data = file_read_all(path, (size_t)1 << 30, &len, err, sizeof err);
    int n = 0;
    for (const char *p = data; p && (p = strstr(p, text)) != NULL; p += strlen(text)) n++;
    free(data);
    return n;
}

/* Run `tessera ARGS` against c with a client timeout of 5 s; output in out. */
static int cli(const coord *c, char *out, size_t cap, const char *args) {
    char cmd[8192];
    snprintf(cmd, sizeof cmd, "TESSERA_CLIENT_TIMEOUT=%d TESSERA_COORDINATOR=%s %s %s", (int)(5 * harness_slack()), c->addr,
             harness_tessera(), args);
    return util_run(cmd, out, cap);
}

/* Write n finished jobs straight into a data dir's jobs/ folder, as a
 * coordinator that kept them would have. */
static int write_kept_jobs(const char *dir, int n) {
    char path[512], text[1024];
    long now = (long)time(NULL);
    snprintf(path, sizeof path, "%s", dir);
    mkdir(path, 0755);
    snprintf(path, sizeof path, "%s/jobs", dir);
    mkdir(path, 0755);
    snprintf(path, sizeof path, "%s/scenes", dir);
    mkdir(path, 0755);
    for (int i = 1; i <= n; i++) {
        snprintf(path, sizeof path, "%s/jobs/%d.json", dir, i);
        snprintf(text, sizeof text,
                 "{\"job\": %d, \"name\": \"scenes/kept-%d.json\", \"scene\": \"" HASH "\", \"width\": 64, "
                 "\"height\": 64, \"spp\": 4, \"max_depth\": 8, \"seed\": \"1\", \"nee\": true, \"mis\": true, "
                 "\"sampler\": \"sobol\", \"priority\": 0, \"tile_size\": 32, \"state\": \"done\", \"error\": \"\", "
                 "\"submitted\": %ld, \"finished\": %ld}",
                 i, i, now, now);
        FILE *f = fopen(path, "w"); /* not synced: a test's scratch */
        if (!f || fputs(text, f) < 0 || fclose(f) != 0) return -1;
    }
    return 0;
}

/* `tessera status` of 10,000 kept jobs: the listing is 1.5 MB of JSON, far
 * past one frame; it comes in pages, whole, in under a second. */
TEST(hostile_status_of_10000_kept_jobs_answers_within_a_second) {
    coord c = {0};
    snprintf(c.dir, sizeof c.dir, "%s", util_temp_path("hostile-list"));
    CHECK(write_kept_jobs(c.dir, 10000) == 0, "cannot write the job files");
    const char *keep[] = {"--keep-jobs", "20000", NULL};
    if (coord_start(&c, "hostile-list", keep)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    char listing[300], args[600], out[4096];
    snprintf(listing, sizeof listing, "%s", util_temp_path("hostile-list.txt"));
    double best = 1e9, best_cpu = 1e9;
    for (int run = 0; run < 3; run++) { /* the best of three: the machine is shared */
        snprintf(args, sizeof args, "status > %s", listing);
        double t0 = util_now(), c0 = children_cpu_s() + proc_cpu_s(c.pid);
        int rc = cli(&c, out, sizeof out, args);
        double t = util_now() - t0, cpu = children_cpu_s() + proc_cpu_s(c.pid) - c0;
        best = t < best ? t : best;
        best_cpu = cpu < best_cpu ? cpu : best_cpu;
        CHECK(rc == 0, "status of 10,000 jobs exited %d: %s", rc, out);
    }
    CHECK(count_in(listing, "scenes/kept-") == 10000, "status listed %d of 10000 jobs",
          count_in(listing, "scenes/kept-"));
    CHECK(count_in(listing, "scenes/kept-10000.json") == 1, "the last job is missing");
    /* Under a second of work (the coordinator's CPU and the client's); the
     * wall clock is checked loosely, since on a loaded host (load 27 on 2
     * cores while this was written: 0.8 to 1.2 s for 0.15 s of CPU) it
     * measures the neighbours. */
    CHECK(best_cpu < 1.0 * harness_slack(), "status of 10,000 jobs took %.2f s of CPU (want < 1 s)", best_cpu);
    CHECK(best < 5.0 * harness_slack(), "status of 10,000 jobs took %.2f s (want < 1 s on an idle host)", best);
    fprintf(stderr, "  (status of 10,000 jobs: %.2f s wall, %.2f s of CPU)\n", best, best_cpu);
    snprintf(args, sizeof args, "status --json > %s", listing);
    CHECK(cli(&c, out, sizeof out, args) == 0, "status --json failed: %s", out);
    CHECK(count_in(listing, "\"state\"") == 10000 && !count_in(listing, "\"more\""),
          "status --json has %d jobs (want 10000, one array, no \"more\")", count_in(listing, "\"state\""));
    coord_stop(&c);
}

/* A coordinator that accepts and then says nothing: the client gives up
 * after its timeout with a message naming the coordinator and the wait. */
TEST(hostile_silent_coordinator_is_a_timeout_not_a_hang) {
    int port, fd = util_listen_loopback(8, &port);
    CHECK(fd >= 0, "cannot listen");
    char cmd[1024], out[4096];
    snprintf(cmd, sizeof cmd, "TESSERA_CLIENT_TIMEOUT=1 TESSERA_COORDINATOR=127.0.0.1:%d %s status", port,
             harness_tessera());
    double t0 = util_now();
    int rc = util_run(cmd, out, sizeof out);
    double t = util_now() - t0;
    close(fd);
    CHECK(rc != 0, "status against a silent coordinator exited 0");
    CHECK(strstr(out, "did not answer within 1 s") != NULL, "no timeout message: %s", out);
    CHECK(t < 5, "the client waited %.1f s for a silent coordinator (timeout 1 s)", t);
}

/* ---- a raw client: the protocol by hand, for what the CLI never sends ---- */

static int raw_send(int fd, int kind, const void *body, size_t len) {
    uint8_t hdr[WIRE_HEADER_BYTES];
    wire_put_u32(hdr, (uint32_t)(len + 1));
    hdr[4] = (uint8_t)kind;
    if (send(fd, hdr, sizeof hdr, MSG_NOSIGNAL) != (ssize_t)sizeof hdr) return -1;
    const uint8_t *p = body;
    while (len > 0) {
        ssize_t n = send(fd, p, len, MSG_NOSIGNAL);
        if (n <= 0) return -1;
        p += n;
        len -= (size_t)n;
    }
    return 0;
}

static int raw_send_text(int fd, const char *json) { return raw_send(fd, WIRE_KIND_JSON, json, strlen(json)); }

/* Read one JSON frame's text into out (NUL-terminated) within timeout_s.
 * Returns 0, or -1 on EOF, timeout or a non-JSON frame. */
static int raw_read(int fd, char *out, size_t cap, double timeout_s) {
    uint8_t hdr[WIRE_HEADER_BYTES];
    size_t have = 0, need = sizeof hdr, len = 0;
    double end = util_now() + timeout_s;
    while (have < need) {
        struct pollfd pf = {fd, POLLIN, 0};
        int left = (int)((end - util_now()) * 1000);
        if (left <= 0 || poll(&pf, 1, left) <= 0) return -1;
        ssize_t n = have < sizeof hdr ? recv(fd, hdr + have, sizeof hdr - have, 0)
                                      : recv(fd, out + have - sizeof hdr, need - have, 0);
        if (n <= 0) return -1;
        have += (size_t)n;
        if (have == sizeof hdr) {
            len = wire_get_u32(hdr) - 1;
            if (hdr[4] != WIRE_KIND_JSON || len + 1 > cap) return -1;
            need = sizeof hdr + len;
        }
    }
    out[len] = 0;
    return 0;
}

/* A TCP connection to c from the loopback address src (NULL: any; the
 * whole of 127/8 is this machine, so "127.0.0.3" is another peer address
 * to the coordinator), before any hello. Returns the socket, or -1. */
static int raw_connect_from(const coord *c, const char *src) {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    a.sin_port = htons((uint16_t)c->port);
    struct sockaddr_in from = {.sin_family = AF_INET};
    if (fd >= 0 && src && (inet_pton(AF_INET, src, &from.sin_addr) != 1 || bind(fd, (struct sockaddr *)&from, sizeof from))) {
        close(fd);
        return -1;
    }
    if (fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

/* Connect to c from src (NULL: any) and say hello as role ("client" or
 * NULL: a worker). Returns the socket after the welcome, or -1. */
static int raw_hello_from(const coord *c, const char *src, const char *role) {
    int fd = raw_connect_from(c, src);
    char buf[4096], hello[512];
    snprintf(hello, sizeof hello,
             "{\"type\":\"hello\",%s%s%s\"protocol\":%d,\"build\":\"%s\",\"name\":\"raw\",\"threads\":1}",
             role ? "\"role\":\"" : "", role ? role : "", role ? "\"," : "", PROTOCOL_VERSION, protocol_build_id());
    if (fd < 0 || raw_read(fd, buf, sizeof buf, 5) || raw_send_text(fd, hello) || raw_read(fd, buf, sizeof buf, 5) ||
        !strstr(buf, "welcome")) {
        if (fd >= 0) close(fd);
        return -1;
    }
    return fd;
}

/* Connect to c as a client (no token) and say hello. Returns the socket
 * after the welcome, or -1. */
static int raw_open(const coord *c) { return raw_hello_from(c, NULL, "client"); }

/* Upload the bundle of scene path on fd; its hash in hash. Returns 0/-1. */
static int raw_upload(int fd, const char *path, char hash[SCENE_BUNDLE_HASH_HEX]) {
    scene_bundle b;
    char err[512];
    if (scene_bundle_read(path, &b, err, sizeof err)) return -1;
    size_t len;
    uint8_t *bytes = scene_bundle_serialise(&b, &len);
    scene_bundle_free(&b);
    if (!bytes) return -1;
    scene_bundle_hash(bytes, len, hash);
    int rc = raw_send(fd, WIRE_KIND_SCENE, bytes, len);
    free(bytes);
    return rc;
}

/* A submit with each bad field from a client that is not the CLI: refused,
 * naming the field, and nothing is queued. */
TEST(hostile_submit_fields_are_checked_by_the_coordinator) {
    coord c = {0};
    if (coord_start(&c, "hostile-fields", NULL)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    int fd = raw_open(&c);
    char hash[SCENE_BUNDLE_HASH_HEX], msg[1024], ans[4096];
    CHECK(fd >= 0 && raw_upload(fd, "tests/scenes/cornell-small.json", hash) == 0, "cannot connect and upload");
    static const struct { const char *field, *want; } bad[] = {
        {"\"seed\":\"abc\"", "seed"},          {"\"seed\":\"-1\"", "seed"},
        {"\"seed\":\"18446744073709551616\"", "seed"}, {"\"seed\":\" 5\"", "seed"},
        {"\"seed\":5", "seed"},                {"\"width\":1e30", "width"},
        {"\"spp\":-3", "spp"},                 {"\"tile_size\":0.5", "tile_size"},
        {"\"name\":7", "name"},                {"\"nee\":\"no\"", "nee"},
    };
    for (size_t i = 0; fd >= 0 && i < sizeof bad / sizeof bad[0]; i++) {
        snprintf(msg, sizeof msg, "{\"type\":\"submit\",\"scene\":\"%s\",\"name\":\"x\",%s}", hash, bad[i].field);
        if (strncmp(bad[i].field, "\"name\"", 6) == 0)
            snprintf(msg, sizeof msg, "{\"type\":\"submit\",\"scene\":\"%s\",%s}", hash, bad[i].field);
        int rc = raw_send_text(fd, msg) || raw_read(fd, ans, sizeof ans, 10);
        CHECK(rc == 0, "no answer to %s", bad[i].field);
        CHECK(strstr(ans, "\"error\"") && strstr(ans, bad[i].want), "%s: answer does not refuse %s: %s", bad[i].field,
              bad[i].want, ans);
    }
    snprintf(msg, sizeof msg, "{\"type\":\"submit\",\"scene\":\"%s\",\"name\":\"ok\",\"seed\":\"18446744073709551615\"}",
             hash);
    CHECK(fd >= 0 && raw_send_text(fd, msg) == 0 && raw_read(fd, ans, sizeof ans, 10) == 0 && strstr(ans, "submitted"),
          "the largest seed was refused: %s", ans);
    if (fd >= 0) close(fd);
    char out[8192];
    CHECK(cli(&c, out, sizeof out, "status") == 0 && !strstr(out, "  x"), "a refused submit was queued: %s", out);
    coord_stop(&c);
}

static pid_t worker_start(const coord *c, const char *name) {
    char path[4096], log[256], lname[64];
    snprintf(path, sizeof path, "%s", util_bin("tessera-worker"));
    snprintf(lname, sizeof lname, "%s.log", name);
    snprintf(log, sizeof log, "%s", util_temp_path(lname));
    const char *argv[] = {path, "--connect", c->addr, "--threads", "1", "--name", name, "--retry-max", "1",
                          "--throttle-ms", "10", NULL};
    return util_spawn(argv, log);
}

/* The number after "tiles_done": in a status --json answer, or -1. */
static int tiles_done_of(const char *out) {
    int done = -1;
    const char *p = strstr(out, "\"tiles_done\":");
    if (p) sscanf(p, "\"tiles_done\":\t%d", &done);
    return done;
}

/* Tiles are synced in batches off the loop; a tile counts (status) only
 * once its batch is durable. kill -9 mid-render, with two workers
 * finishing small tiles (each held 10 ms): after the restart the journal
 * holds at least every tile status had counted, and the image is the same
 * bytes as a single-process render. */
TEST(hostile_kill9_mid_render_loses_no_counted_tile) {
    coord c = {0};
    if (coord_start(&c, "hostile-kill9", NULL)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    pid_t w1 = worker_start(&c, "k1"), w2 = worker_start(&c, "k2");
    char out[8192], ref[256], img[256], cmd[1024];
    CHECK(cli(&c, out, sizeof out, "submit tests/scenes/cornell-small.json --tile-size 4 --spp 8") == 0,
          "submit: %s", out);
    int counted = -1;
    for (int i = 0; i < 2000 && counted < 40; i++) {
        if (cli(&c, out, sizeof out, "status 1 --json") == 0) counted = tiles_done_of(out);
        if (counted < 40) util_sleep(0.005);
    }
    kill(c.pid, SIGKILL);
    util_wait(c.pid, 10, NULL);
    CHECK(counted >= 40 && counted < 256, "status counted %d tiles before the kill (want 40 to 255)", counted);
    if (coord_start(&c, "hostile-kill9", NULL)) CHECK(0, "coordinator did not restart; log %s", c.log);
    int resumed = -1;
    CHECK(util_wait_for_text(c.log, "job 1 resumed: ", 30) == 0, "no resume; log %s", c.log);
    const char *p = NULL;
    size_t len;
    char err[256];
    char *log = file_read_all(c.log, 1 << 24, &len, err, sizeof err);
    if (log) p = strstr(log, "job 1 resumed: ");
    if (p) sscanf(p, "job 1 resumed: %d", &resumed);
    free(log);
    CHECK(resumed >= counted, "status had counted %d tiles; only %d were in the journal after kill -9", counted, resumed);
    CHECK(util_wait_for_text(c.log, "job 1 done (", 60) == 0, "the resumed job never finished; log %s", c.log);
    snprintf(img, sizeof img, "%s", util_temp_path("hostile-kill9.pfm"));
    snprintf(ref, sizeof ref, "%s", util_temp_path("hostile-kill9-ref.pfm"));
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json --spp 8 --workers 0 -o %s", harness_tessera(), ref);
    CHECK(util_run(cmd, out, sizeof out) == 0, "reference render: %s", out);
    snprintf(cmd, sizeof cmd, "fetch 1 -o %s", img);
    CHECK(cli(&c, out, sizeof out, cmd) == 0 && util_same_file(img, ref), "image after kill -9 differs: %s", out);
    kill(w1, SIGTERM);
    kill(w2, SIGTERM);
    util_wait(w1, 10, NULL);
    util_wait(w2, 10, NULL);
    coord_stop(&c);
}

/* A scene of n materials, each used by one sphere; the last name repeated
 * when dup. malloc'd text. */
static char *many_materials(int n, int dup) {
    size_t cap = (size_t)n * 160 + 1024, len = 0;
    char *t = malloc(cap);
    if (!t) return NULL;
    len += (size_t)snprintf(t + len, cap - len,
                            "{\"render\": {\"width\": 8, \"height\": 8, \"spp\": 1}, \"camera\": {\"type\": "
                            "\"perspective\", \"position\": [0, 0, -10], \"look_at\": [0, 0, 0], \"up\": [0, 1, 0], "
                            "\"fov\": 40}, \"materials\": {");
    for (int i = 0; i < n + dup; i++)
        len += (size_t)snprintf(t + len, cap - len, "%s\"m%d\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}",
                                i ? ", " : "", i < n ? i : n - 1);
    len += (size_t)snprintf(t + len, cap - len, "}, \"shapes\": [");
    for (int i = 0; i < n; i++)
        len += (size_t)snprintf(t + len, cap - len,
                                "%s{\"type\": \"sphere\", \"center\": [0, 0, %d], \"radius\": 0.5, \"material\": \"m%d\"}",
                                i ? ", " : "", i, n - 1 - i);
    snprintf(t + len, cap - len, "]}");
    return t;
}

/* 100,000 materials (each used once) load in linear time: the duplicate
 * check and each shape's material look-up hash the names (30 s before). A
 * name given twice is still refused, naming it. */
TEST(hostile_scene_of_100000_materials_loads_in_linear_time) {
    char *text = many_materials(100000, 0), err[512];
    double t0 = util_now();
    scene *s = text ? util_scene_from_text(text, err, sizeof err) : NULL;
    double t = util_now() - t0;
    CHECK(s != NULL, "scene of 100,000 materials refused: %s", s ? "" : err);
    CHECK(t < 10.0 * harness_slack(), "loading 100,000 materials took %.1f s (want < 10 s: linear; quadratic took 30 s)", t);
    if (s) scene_free(s);
    free(text);
    text = many_materials(1000, 1);
    s = text ? util_scene_from_text(text, err, sizeof err) : NULL;
    CHECK(!s && strstr(err, "materials.m999") && strstr(err, "defined twice"), "duplicate not refused: %s", err);
    if (s) scene_free(s);
    free(text);
}

/* The "longest_stall_ms" of a status answer, or -1. */
static double stall_of(const char *ans, const char *key) {
    char pat[64];
    double v = -1;
    snprintf(pat, sizeof pat, "\"%s\":", key);
    const char *p = strstr(ans, pat);
    if (p) sscanf(p + strlen(pat), "%lf", &v);
    return v;
}

/* While the coordinator checks a large scene (100,000 materials and
 * spheres: seconds of parsing and validation), its loop goes on: status
 * from another client answers within 100 ms each time, the coordinator's
 * own longest loop iteration stays under 100 ms, and a connected worker is
 * never timed out. */
TEST(hostile_large_upload_is_checked_off_the_loop) {
    coord c = {0};
    if (coord_start(&c, "hostile-upload", NULL)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    pid_t w = worker_start(&c, "u1");
    char out[4096];
    for (int i = 0; i < 500 && !(cli(&c, out, sizeof out, "workers") == 0 && strstr(out, "u1")); i++) util_sleep(0.02);
    CHECK(strstr(out, "u1") != NULL, "worker never joined: %s", out);
    char *text = many_materials(100000, 0), ans[8192], hash[SCENE_BUNDLE_HASH_HEX], msg[512];
    char *path = strdup(util_temp_path("hostile-upload.json"));
    FILE *f = fopen(path, "w");
    CHECK(f && text && fputs(text, f) >= 0 && fclose(f) == 0, "cannot write the scene");
    free(text);
    int up = raw_open(&c), st = raw_open(&c);
    CHECK(up >= 0 && st >= 0 && raw_upload(up, path, hash) == 0, "cannot connect and upload");
    snprintf(msg, sizeof msg, "{\"type\":\"submit\",\"scene\":\"%s\",\"name\":\"big\"}", hash);
    CHECK(raw_send_text(up, msg) == 0, "cannot submit");
    double t0 = util_now(), worst = 0;
    int polls = 0, answered = 0;
    while (!answered && util_now() - t0 < 60) {
        double a = util_now();
        if (raw_send_text(st, "{\"type\":\"status\"}") || raw_read(st, ans, sizeof ans, 10)) break;
        double rt = util_now() - a;
        worst = rt > worst ? rt : worst;
        polls++;
        struct pollfd pf = {up, POLLIN, 0};
        answered = poll(&pf, 1, 20) > 0;
    }
    CHECK(answered && raw_read(up, ans, sizeof ans, 5) == 0 && strstr(ans, "submitted"), "the large scene: %s", ans);
    CHECK(polls >= 5, "only %d status answers while the scene was checked (it took %.2f s)", polls, util_now() - t0);
    CHECK(worst < 1.0 * harness_slack(), "a status took %.0f ms while the scene was checked (want < 100 ms; < 1 s on a loaded host)",
          worst * 1e3);
    CHECK(raw_send_text(st, "{\"type\":\"status\"}") == 0 && raw_read(st, ans, sizeof ans, 10) == 0, "no status");
    double stall = stall_of(ans, "longest_stall_ms"), cpu = stall_of(ans, "longest_stall_cpu_ms");
    /* The loop's own work per iteration (its thread's CPU time) is what the
     * coordinator controls; wall-clock figures also hold the time a loaded
     * host (load 20 on 2 cores while this was written) gave to others. */
    /* Goal 100 ms; measured 58 to 110 ms of loop CPU for this 12 MB scene
     * while the farm's copy of the bundle was made on the loop, 15 ms since
     * it is made on the upload's pool thread; checking the scene on the
     * loop took seconds. */
    CHECK(cpu >= 0 && cpu < 100 * harness_slack(), "the loop worked %.1f ms in one iteration while a large scene was checked (want < 100)",
          cpu);
    fprintf(stderr, "  (loop: %.1f ms of CPU, %.1f ms wall in its longest iteration; slowest status %.0f ms)\n", cpu,
            stall, worst * 1e3);
    CHECK(!util_file_count(c.log, "silent for"), "a worker was found silent; log %s", c.log);
    close(up);
    close(st);
    free(path);
    kill(w, SIGTERM);
    util_wait(w, 10, NULL);
    coord_stop(&c);
}

/* Clients that finish the hello and then say nothing, and one that trickles
 * an upload a byte at a time, are closed after --client-timeout (each close
 * logged once); a legitimate status is answered throughout. */
TEST(hostile_idle_and_trickling_clients_are_closed) {
    coord c = {0};
    const char *extra[] = {"--client-timeout", "1", NULL};
    if (coord_start(&c, "hostile-idle", extra)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    enum { IDLE = 50 };
    int fds[IDLE], opened = 0;
    for (int i = 0; i < IDLE; i++) opened += (fds[i] = raw_open(&c)) >= 0;
    CHECK(opened == IDLE, "only %d of %d idle clients got in", opened, IDLE);
    int tr = raw_open(&c);
    uint8_t hdr[WIRE_HEADER_BYTES];
    wire_put_u32(hdr, 100001);
    hdr[4] = WIRE_KIND_SCENE;
    CHECK(tr >= 0 && send(tr, hdr, sizeof hdr, MSG_NOSIGNAL) == (ssize_t)sizeof hdr, "trickler could not start");
    char out[4096], ans[4096];
    int tr_closed = 0;
    for (int i = 0; i < 40 && !tr_closed; i++) { /* a byte every 0.1 s for up to 4 s */
        tr_closed = send(tr, "x", 1, MSG_NOSIGNAL) != 1;
        util_sleep(0.1);
        CHECK(cli(&c, out, sizeof out, "status") == 0, "status failed beside idle clients: %s", out);
    }
    int closed = 0;
    for (int i = 0; i < IDLE; i++) { /* each gets a last error naming the timeout, then EOF */
        if (fds[i] < 0) continue;
        int got = raw_read(fds[i], ans, sizeof ans, 3) == 0 && strstr(ans, "--client-timeout");
        char b;
        closed += got && recv(fds[i], &b, 1, 0) == 0;
        close(fds[i]);
    }
    CHECK(closed == IDLE, "%d of %d idle clients were closed after --client-timeout 1", closed, IDLE);
    CHECK(raw_read(tr, ans, sizeof ans, 3) == 0 && strstr(ans, "bytes of a frame"), "trickler not closed: %s", ans);
    close(tr);
    CHECK(util_file_count(c.log, "idle for") == IDLE, "%d idle closes logged (want %d, once each)",
          util_file_count(c.log, "idle for"), IDLE);
    coord_stop(&c);
}

/* Fill the file system holding dir with a filler file until it is full.
 * Returns 0, or -1. */
static int fill_disk(const char *filler) {
    FILE *f = fopen(filler, "wb");
    if (!f) return -1;
    static char block[4096];
    while (fwrite(block, 1, sizeof block, f) == sizeof block) {
    }
    fclose(f); /* the last block may be short: the disk is full either way */
    f = fopen(filler, "ab");
    while (f && fwrite(block, 1, 1, f) == 1 && fflush(f) == 0) {
    }
    if (f) fclose(f);
    return 0;
}

/* A full disk under the journal (a 2 MiB tmpfs the test mounts, filled on
 * purpose) pauses the job: no tile counts while nothing can be written, the
 * pause is logged once, nothing durable is deleted, and when space comes
 * back the job finishes byte-identical to a single-process render. */
TEST(hostile_full_disk_pauses_the_job_and_loses_nothing) {
    char mnt[200], cmd[1024], out[8192], filler[300], ref[300], img[300];
    snprintf(mnt, sizeof mnt, "%s", util_temp_path("hostile-tmpfs"));
    mkdir(mnt, 0755);
    snprintf(cmd, sizeof cmd, "mount -t tmpfs -o size=2m tmpfs %s 2>&1", mnt);
    if (geteuid() != 0 || util_run(cmd, out, sizeof out) != 0) {
        fprintf(stderr, "  skipped: cannot mount a small tmpfs here (needs root and CAP_SYS_ADMIN): %s\n",
                geteuid() ? "not root" : out);
        return;
    }
    coord c = {0};
    snprintf(c.dir, sizeof c.dir, "%s/data", mnt);
    if (coord_start(&c, "hostile-enospc", NULL)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
    } else {
        CHECK(cli(&c, out, sizeof out, "submit tests/scenes/cornell-small.json --tile-size 8 --spp 8") == 0, "submit: %s",
              out);
        snprintf(filler, sizeof filler, "%s/filler", mnt);
        fill_disk(filler);
        pid_t w = worker_start(&c, "f1");
        CHECK(util_wait_for_text(c.log, "out of space", 30) == 0, "the full disk went unnoticed; log %s", c.log);
        util_sleep(1.5); /* tiles keep landing; retries keep failing */
        CHECK(cli(&c, out, sizeof out, "status 1 --json") == 0 && tiles_done_of(out) == 0 && strstr(out, "running") &&
                  strstr(out, "paused"),
              "while the disk is full, status must show the job running, paused, with 0 tiles counted: %s", out);
        CHECK(util_file_count(c.log, "out of space") == 1, "the pause was logged %d times (want once)",
              util_file_count(c.log, "out of space"));
        unlink(filler);
        CHECK(util_wait_for_text(c.log, "job 1 done (", 60) == 0, "the job did not finish once space was back; log %s",
              c.log);
        CHECK(util_file_count(c.log, "space is back") >= 1, "resume not logged; log %s", c.log);
        snprintf(ref, sizeof ref, "%s", util_temp_path("hostile-enospc-ref.pfm"));
        snprintf(img, sizeof img, "%s", util_temp_path("hostile-enospc.pfm"));
        snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json --spp 8 --workers 0 -o %s",
                 harness_tessera(), ref);
        CHECK(util_run(cmd, out, sizeof out) == 0, "reference: %s", out);
        snprintf(cmd, sizeof cmd, "fetch 1 -o %s", img);
        CHECK(cli(&c, out, sizeof out, cmd) == 0 && util_same_file(img, ref), "image after a full disk differs: %s", out);
        kill(w, SIGTERM);
        util_wait(w, 10, NULL);
        coord_stop(&c);
    }
    snprintf(cmd, sizeof cmd, "umount %s 2>&1", mnt);
    CHECK(util_run(cmd, out, sizeof out) == 0, "umount: %s", out);
}

/* submit refuses a scene that names a file outside its own folder (a
 * "../" path, an absolute path, a symbolic link out), naming the path and
 * sending nothing; a mesh inside the folder is sent. */
TEST(hostile_submit_uploads_only_files_under_the_scene_folder) {
    coord c = {0};
    if (coord_start(&c, "hostile-paths", NULL)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    char dir[256], secret[300], link[300], scene[300], text[1024], out[8192], args[700];
    snprintf(dir, sizeof dir, "%s", util_temp_path("hostile-paths-scene"));
    mkdir(dir, 0755);
    snprintf(secret, sizeof secret, "%s", util_temp_path("hostile-secret.obj"));
    FILE *f = fopen(secret, "w");
    if (f) fputs("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", f), fclose(f);
    snprintf(link, sizeof link, "%s/inside.obj", dir);
    unlink(link);
    CHECK(symlink(secret, link) == 0, "cannot make a symlink");
    snprintf(text, sizeof text, "%s/ok.obj", dir);
    f = fopen(text, "w");
    if (f) fputs("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", f), fclose(f);
    const char *names[] = {"../hostile-secret.obj", secret, "inside.obj"};
    for (int i = 0; i < 3; i++) {
        snprintf(scene, sizeof scene, "%s/s%d.json", dir, i);
        snprintf(text, sizeof text,
                 "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -3], \"look_at\": [0, 0, 0], \"fov\": 40},"
                 " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
                 " \"shapes\": [{\"type\": \"mesh\", \"file\": \"%s\", \"material\": \"w\"}]}",
                 names[i]);
        f = fopen(scene, "w");
        if (f) fputs(text, f), fclose(f);
        snprintf(args, sizeof args, "submit %s", scene);
        int st = cli(&c, out, sizeof out, args);
        CHECK(st != 0 && strstr(out, names[i]) && strstr(out, "outside the scene's folder"),
              "a mesh at %s was not refused (%d): %s", names[i], st, out);
    }
    CHECK(!util_file_count(c.log, "submitted"), "a refused scene reached the coordinator; log %s", c.log);
    snprintf(scene, sizeof scene, "%s/good.json", dir);
    snprintf(text, sizeof text,
             "{\"render\": {\"width\": 8, \"height\": 8, \"spp\": 1}, \"camera\": {\"type\": \"perspective\", "
             "\"position\": [0, 0, -3], \"look_at\": [0, 0, 0], \"fov\": 40},"
             " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
             " \"shapes\": [{\"type\": \"mesh\", \"file\": \"ok.obj\", \"material\": \"w\"}]}");
    f = fopen(scene, "w");
    if (f) fputs(text, f), fclose(f);
    snprintf(args, sizeof args, "submit %s", scene);
    CHECK(cli(&c, out, sizeof out, args) == 0, "a mesh inside the folder was refused: %s", out);
    snprintf(args, sizeof args, "submit -v %s", scene); /* -v names every file sent, with its bytes */
    struct stat sb;
    snprintf(text, sizeof text, "sending %s (%lld bytes)", scene, stat(scene, &sb) == 0 ? (long long)sb.st_size : -1LL);
    char mesh_line[64];
    snprintf(mesh_line, sizeof mesh_line, "sending ok.obj (%d bytes)", (int)strlen("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n"));
    CHECK(cli(&c, out, sizeof out, args) == 0 && strstr(out, text) && strstr(out, mesh_line),
          "submit -v does not name each file sent with its bytes (want \"%s\" and \"%s\"): %s", text, mesh_line, out);
    coord_stop(&c);
}

/* Bytes in the regular files under dir (recursive), or -1. */
static long long dir_bytes(const char *dir) {
    char cmd[600], out[256];
    snprintf(cmd, sizeof cmd, "find %s -type f ! -name '*.lock' ! -name lock -printf '%%s\\n' | awk '{s+=$1} END {print s+0}'",
             dir);
    if (util_run(cmd, out, sizeof out) != 0) return -1;
    return atoll(out);
}

/* Finished jobs past --keep-jobs are deleted, oldest first, and each
 * uploaded scene goes once no kept job names it; with --keep-hours 0 every
 * finished job goes and the data dir returns to its starting size. */
TEST(hostile_kept_jobs_are_capped_and_their_scenes_removed) {
    coord c = {0};
    const char *extra[] = {"--keep-jobs", "1", NULL};
    if (coord_start(&c, "hostile-keep", extra)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    pid_t w = worker_start(&c, "r1");
    char out[8192], scenes[400];
    snprintf(scenes, sizeof scenes, "%s/scenes", c.dir);
    long long start = dir_bytes(c.dir);
    char args[600];
    snprintf(args, sizeof args, "submit tests/scenes/cornell-small.json --spp 1 --wait -o %s",
             util_temp_path("hostile-keep-1.pfm"));
    CHECK(cli(&c, out, sizeof out, args) == 0, "submit: %s", out);
    CHECK(cli(&c, out, sizeof out, "submit scenes/cornell-box.json --width 16 --height 16 --spp 1") == 0, "submit: %s",
          out);
    CHECK(util_wait_for_text(c.log, "job 2 done (", 30) == 0, "job 2 did not finish; log %s", c.log);
    CHECK(util_wait_for_text(c.log, "job 1 was over --keep-jobs", 10) == 0, "job 1 not deleted past --keep-jobs 1");
    CHECK(util_wait_for_text(c.log, "removed: no kept job names it", 10) == 0, "job 1's scene was not removed");
    char cmd[600];
    snprintf(cmd, sizeof cmd, "ls %s | wc -l", scenes);
    CHECK(util_run(cmd, out, sizeof out) == 0 && atoi(out) == 1, "%s holds %s scenes (want 1: job 2's)", scenes, out);
    kill(c.pid, SIGTERM);
    util_wait(c.pid, 30, NULL);
    const char *gone[] = {"--keep-hours", "0", NULL};
    CHECK(coord_start(&c, "hostile-keep", gone) == 0, "restart failed; log %s", c.log);
    CHECK(util_wait_for_text(c.log, "job 2 expired", 10) == 0, "job 2 did not expire with --keep-hours 0");
    util_sleep(0.5);
    long long end = dir_bytes(c.dir);
    CHECK(end == start, "the data dir holds %lld bytes after every job expired; %lld at the start", end, start);
    kill(w, SIGTERM);
    util_wait(w, 10, NULL);
    coord_stop(&c);
}

/* Resident memory of a process in KiB (VmRSS), or -1. */
static long rss_kib(pid_t pid) {
    char path[64], line[256];
    snprintf(path, sizeof path, "/proc/%d/status", (int)pid);
    FILE *f = fopen(path, "r");
    long kib = -1;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "VmRSS: %ld kB", &kib) == 1) break;
    if (f) fclose(f);
    return kib;
}

/* One worker hello and close (no token). Returns 0 after the welcome. */
static int worker_hello_close(const coord *c, int i) {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    a.sin_port = htons((uint16_t)c->port);
    char buf[4096], hello[512];
    snprintf(hello, sizeof hello,
             "{\"type\":\"hello\",\"protocol\":%d,\"build\":\"%s\",\"name\":\"cycle-%d\",\"threads\":1}",
             PROTOCOL_VERSION, protocol_build_id(), i);
    int rc = fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) == 0 && raw_read(fd, buf, sizeof buf, 5) == 0 &&
                     raw_send_text(fd, hello) == 0 && raw_read(fd, buf, sizeof buf, 5) == 0 && strstr(buf, "welcome")
                 ? 0
                 : -1;
    if (fd >= 0) close(fd);
    return rc;
}

/* 3,000 worker hellos and closes: the coordinator's memory stays flat (each
 * departure was kept for ever: 312 bytes, +916 KiB per 3,000). Not
 * checked under a sanitizer, whose quarantine holds freed memory. */
TEST(hostile_worker_hello_close_cycles_keep_memory_flat) {
    coord c = {0};
    if (coord_start(&c, "hostile-cycles", NULL)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    int ok = 0;
    for (int i = 0; i < 500; i++) ok += worker_hello_close(&c, i) == 0; /* warm up the allocator */
    util_sleep(0.3);
    long before = rss_kib(c.pid);
    for (int i = 500; i < 3500; i++) ok += worker_hello_close(&c, i) == 0;
    util_sleep(0.3);
    long after = rss_kib(c.pid);
    CHECK(ok == 3500, "%d of 3500 hellos welcomed", ok);
    CHECK(harness_slack() > 1 || (before > 0 && after - before < 300), "RSS grew %ld KiB over 3,000 hello/close cycles (want < 300)",
          after - before);
    fprintf(stderr, "  (3,000 hello/close cycles: RSS %ld -> %ld KiB)\n", before, after);
    coord_stop(&c);
}

/* A mesh scaled by 1e30 rendered a black image and exited 0: refused,
 * naming the field. */
TEST(hostile_absurd_mesh_scale_is_refused) {
    char dir[256], text[1024], err[512];
    snprintf(dir, sizeof dir, "%s", util_temp_path("hostile-scale"));
    mkdir(dir, 0755);
    snprintf(text, sizeof text, "%s/tri.obj", dir);
    FILE *f = fopen(text, "w");
    if (f) fputs("v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n", f), fclose(f);
    char scene[300], cmd[1024], out[4096];
    snprintf(scene, sizeof scene, "%s/s.json", dir);
    f = fopen(scene, "w");
    if (f)
        fputs("{\"render\": {\"width\": 8, \"height\": 8, \"spp\": 1}, \"camera\": {\"type\": \"perspective\", "
              "\"position\": [0, 0, -3], \"look_at\": [0, 0, 0], \"fov\": 40}, \"materials\": {\"w\": {\"type\": "
              "\"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, \"shapes\": [{\"type\": \"mesh\", \"file\": \"tri.obj\", "
              "\"scale\": 1e30, \"material\": \"w\"}]}",
              f),
            fclose(f);
    snprintf(cmd, sizeof cmd, "%s render %s --workers 0 -o %s/out.pfm", harness_tessera(), scene, dir);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st != 0 && strstr(out, "scale"), "a mesh scaled by 1e30 was not refused (%d): %s", st, out);
    (void)err;
}

/* Read one frame of any kind within timeout_s into a malloc'd body (the
 * caller frees). Returns its kind, or -1 on EOF or timeout. */
static int raw_frame(int fd, uint8_t **body, size_t *len, double timeout_s) {
    uint8_t hdr[WIRE_HEADER_BYTES];
    size_t have = 0, need = sizeof hdr;
    double end = util_now() + timeout_s;
    *body = NULL;
    while (have < need) {
        struct pollfd pf = {fd, POLLIN, 0};
        int left = (int)((end - util_now()) * 1000);
        ssize_t n = left > 0 && poll(&pf, 1, left) > 0
                        ? (have < sizeof hdr ? recv(fd, hdr + have, sizeof hdr - have, 0)
                                             : recv(fd, *body + have - sizeof hdr, need - have, 0))
                        : -1;
        if (n <= 0) break;
        have += (size_t)n;
        if (have == sizeof hdr) {
            *len = wire_get_u32(hdr) - 1;
            need = sizeof hdr + *len;
            *body = malloc(*len + 1);
            if (!*body || wire_get_u32(hdr) == 0 || wire_get_u32(hdr) > (64u << 20)) break;
        }
    }
    if (have == need && *body) {
        (*body)[*len] = 0;
        return hdr[4];
    }
    free(*body);
    *body = NULL;
    return -1;
}

/* A raw fetch of job on fd, read to the end: the image's bytes (malloc'd,
 * *len) and the number of D frames, or NULL with why in err. */
static uint8_t *raw_fetch_read(int fd, size_t *len, int *chunks, char *err, size_t err_len) {
    uint8_t *body, *img = NULL;
    size_t n = 0, want = 0;
    *len = 0;
    *chunks = 0;
    for (int kind; (kind = raw_frame(fd, &body, &n, 30 * harness_slack())) >= 0; free(body)) {
        if (kind == WIRE_KIND_DATA && img && *len + n <= want) {
            memcpy(img + *len, body, n);
            *len += n;
            ++*chunks;
        } else if (kind == WIRE_KIND_JSON && strstr((char *)body, "\"image\"") && !img) {
            const char *b = strstr((char *)body, "\"bytes\":");
            want = b ? strtoull(b + 8, NULL, 10) : 0;
            img = malloc(want + 1);
        } else if (kind == WIRE_KIND_JSON && strstr((char *)body, "\"image_end\"") && img && *len == want) {
            free(body);
            return img;
        } else {
            snprintf(err, err_len, "unexpected frame '%c' (%zu bytes) after %zu of %zu bytes: %.200s", kind, n, *len, want,
                     kind == WIRE_KIND_JSON ? (char *)body : "");
            free(body);
            free(img);
            return NULL;
        }
    }
    snprintf(err, err_len, "the stream ended after %zu of %zu bytes", *len, want);
    free(img);
    return NULL;
}

/* Images of any size (more than 2 GiB could not be fetched; one frame built
 * on the loop): fetch streams the finished file in chunks read off the
 * loop, only as fast as the client reads. With 64 KiB chunks
 * (TESSERA_FETCH_CHUNK), a 1024x768 image comes in 145 of them, each byte
 * as in a single-process render, through the CLI too (PFM renamed into
 * place, PNG converted); a client that asks and then does not read holds
 * the coordinator's memory to about a chunk while `status` answers at once
 * (the image built whole and queued: +9 MiB). */
TEST(hostile_fetch_streams_in_chunks_with_back_pressure) {
    coord c = {0};
    setenv("TESSERA_FETCH_CHUNK", "65536", 1);
    int started = coord_start(&c, "hostile-fetch", NULL);
    unsetenv("TESSERA_FETCH_CHUNK");
    if (started) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    pid_t w = worker_start(&c, "fetch-w");
    char ref[256], got[256], png[256], cmd[4096], out[8192], err[512];
    snprintf(ref, sizeof ref, "%s", util_temp_path("hostile-fetch-ref.pfm"));
    snprintf(got, sizeof got, "%s", util_temp_path("hostile-fetch.pfm"));
    snprintf(png, sizeof png, "%s", util_temp_path("hostile-fetch.png"));
    /* Past the kernel's socket buffers (4 MiB each way at most here), so that
     * an image queued whole would show in the coordinator's memory; smaller
     * under a sanitizer, which renders 10 times slower and whose memory
     * figures are not checked. */
    const char *size = harness_slack() > 1 ? "--width 512 --height 512" : "--width 1024 --height 768";
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json %s --spp 1 --workers 0 -o %s", harness_tessera(),
             size, ref);
    CHECK(util_run(cmd, out, sizeof out) == 0, "reference render: %s", out);
    snprintf(cmd, sizeof cmd, "submit tests/scenes/cornell-small.json %s --spp 1 --tile-size 128", size);
    int st = cli(&c, out, sizeof out, cmd);
    CHECK(st == 0, "submit (%d): %s", st, out);
    for (int i = 0; i < (int)(600 * harness_slack()) && !strstr(out, "\"done\""); i++) {
        util_sleep(0.1);
        cli(&c, out, sizeof out, "status 1 --json");
    }
    CHECK(strstr(out, "\"done\"") != NULL, "the job did not finish: %s", out);
    long before = rss_kib(c.pid); /* before any fetch: the first one's memory shows */
    int fd = raw_open(&c), small = 16384;
    CHECK(fd >= 0, "raw client not welcomed");
    if (fd < 0) goto out;
    setsockopt(fd, SOL_SOCKET, SO_RCVBUF, &small, sizeof small);
    raw_send_text(fd, "{\"type\":\"fetch\",\"job\":1}");
    util_sleep(1.0);
    long during = rss_kib(c.pid);
    double t0 = util_now();
    st = cli(&c, out, sizeof out, "status");
    double t = util_now() - t0;
    CHECK(st == 0 && t < 2 * harness_slack(), "status took %.2f s (%d) while a client stalled a fetch: %s", t, st, out);
    CHECK(harness_slack() > 1 || (before > 0 && during - before < 1024),
          "coordinator RSS grew %ld KiB while a client did not read a 9 MiB image (want < 1024)", during - before);
    size_t len, flen;
    int chunks;
    uint8_t *img = raw_fetch_read(fd, &len, &chunks, err, sizeof err);
    snprintf(cmd, sizeof cmd, "fetch 1 -o %s", got);
    st = cli(&c, out, sizeof out, cmd);
    CHECK(st == 0 && util_same_file(got, ref), "fetch (%d) did not give the single-process image: %s", st, out);
    snprintf(cmd, sizeof cmd, "fetch 1 -o %s", png);
    st = cli(&c, out, sizeof out, cmd);
    CHECK(st == 0 && access(png, F_OK) == 0, "fetch to PNG (%d): %s", st, out);
    char *file = file_read_all(got, (size_t)1 << 26, &flen, err, sizeof err);
    CHECK(img && file && len == flen && memcmp(img, file, len) == 0 && chunks == (int)((flen + 65535) / 65536),
          "raw fetch: %zu bytes in %d chunks against %zu in the file: %s", len, chunks, flen, img ? "bytes differ" : err);
    fprintf(stderr, "  (stalled fetch: coordinator RSS %ld -> %ld KiB; status in %.3f s; %d chunks)\n", before, during, t,
            chunks);
    free(img);
    free(file);
    close(fd);
out:
    kill(w, SIGTERM);
    util_wait(w, 30, NULL);
    coord_stop(&c);
}
/* ---- an honest job beside each hostile case ---- */

/* The honest job's image rendered in one process (cornell-small, 8 spp),
 * made once per run; its path, or NULL. */
static const char *honest_reference(void) {
    static char ref[300];
    if (ref[0]) return ref;
    char cmd[1024], out[4096];
    snprintf(ref, sizeof ref, "%s", util_temp_path("hostile-honest-ref.pfm"));
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json --spp 8 --workers 0 -o %s", harness_tessera(),
             ref);
    if (util_run(cmd, out, sizeof out) != 0) {
        ref[0] = 0;
        return NULL;
    }
    return ref;
}

/* Submit the honest job (cornell-small, 8 spp, tiles of 8, priority 10)
 * from 127.0.0.1. Returns its number, or -1. */
static int honest_submit(const coord *c) {
    char out[4096];
    int job = -1;
    if (cli(c, out, sizeof out, "submit tests/scenes/cornell-small.json --spp 8 --tile-size 8 --priority 10") != 0)
        return -1;
    const char *p = strstr(out, "job ");
    if (p) sscanf(p, "job %d", &job);
    return job;
}

/* Wait for the honest job to end (60 s) and check that its image is the
 * same bytes as a single-process render. */
static void honest_check(const coord *c, int job, const char *tag) {
    char text[64], img[300], args[600], out[8192];
    snprintf(text, sizeof text, "job %d done (", job);
    CHECK(job > 0 && util_wait_for_text(c->log, text, 60 * harness_slack()) == 0, "%s: the honest job %d never finished; log %s",
          tag, job, c->log);
    snprintf(img, sizeof img, "%s-%s.pfm", util_temp_path("hostile-honest"), tag);
    snprintf(args, sizeof args, "fetch %d -o %s", job, img);
    const char *ref = honest_reference();
    CHECK(ref && cli(c, out, sizeof out, args) == 0 && util_same_file(img, ref),
          "%s: the honest job's image differs from a single-process render: %s", tag, out);
}

/* The first frame on a fresh connection: 1 for a challenge, 0 for an
 * error (its text in out), -1 for nothing within 5 s. */
static int first_frame(int fd, char *out, size_t cap) {
    if (raw_read(fd, out, cap, 5)) return -1;
    return strstr(out, "challenge") ? 1 : strstr(out, "\"error\"") ? 0 : -1;
}

/* Connection caps (Redis maxclients, nginx limit_conn): past
 * --max-per-address, connections from one address are refused with an
 * error naming the address and the cap; past --max-connections, any; each
 * cap's refusals are logged once (not per attempt); meanwhile a status
 * from another address answers fast, a connected worker keeps rendering,
 * and the honest job beside it finishes byte-identical. Closed connections
 * stop counting. */
TEST(hostile_connections_past_the_caps_are_refused) {
    coord c = {0};
    const char *extra[] = {"--max-connections", "24", "--max-per-address", "8", NULL};
    if (coord_start(&c, "hostile-caps", extra)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    pid_t w = worker_start(&c, "cap1");
    int job = honest_submit(&c);
    CHECK(job > 0, "the honest job was not submitted");
    enum { N = 40 };
    int fds[N], n = 0, kept3 = 0, refused3 = 0, kept_more = 0, refused_total = 0;
    char ans[4096], why3[4096] = "", why_total[4096] = "";
    for (int i = 0; i < 12; i++) { /* one address: 8 in, 4 refused */
        int fd = raw_connect_from(&c, "127.0.0.3"), k = fd >= 0 ? first_frame(fd, ans, sizeof ans) : -1;
        if (k == 0) snprintf(why3, sizeof why3, "%s", ans);
        kept3 += k == 1;
        refused3 += k == 0;
        if (k == 1) fds[n++] = fd;
        else if (fd >= 0) close(fd);
    }
    CHECK(kept3 == 8 && refused3 == 4, "from 127.0.0.3: %d let in, %d refused (want 8 and 4 with --max-per-address 8)",
          kept3, refused3);
    CHECK(strstr(why3, "127.0.0.3") && strstr(why3, "--max-per-address 8"), "the refusal does not name the address "
          "and the cap: %s", why3);
    double t0 = util_now();
    int st = raw_hello_from(&c, "127.0.0.2", "client");
    int ok = st >= 0 && raw_send_text(st, "{\"type\":\"status\"}") == 0 && raw_read(st, ans, sizeof ans, 10) == 0 &&
             strstr(ans, "\"jobs\"");
    double t = util_now() - t0;
    if (st >= 0) close(st);
    CHECK(ok, "status from 127.0.0.2 beside a capped 127.0.0.3 failed: %s", ans);
    CHECK(t < 1.0 * harness_slack(), "status from 127.0.0.2 took %.0f ms (connect, hello and answer; want well under 1 s)", t * 1e3);
    fprintf(stderr, "  (status from another address while one is capped: %.1f ms)\n", t * 1e3);
    const char *more[] = {"127.0.0.4", "127.0.0.5", "127.0.0.6"};
    for (int a = 0; a < 3; a++)
        for (int i = 0; i < 8 && n < N; i++) { /* fill the total: 1 worker + 8 + up to 24 more > 24 */
            int fd = raw_connect_from(&c, more[a]), k = fd >= 0 ? first_frame(fd, ans, sizeof ans) : -1;
            if (k == 0 && strstr(ans, "--max-connections")) snprintf(why_total, sizeof why_total, "%s", ans);
            kept_more += k == 1;
            refused_total += k == 0 && strstr(ans, "--max-connections");
            if (k == 1) fds[n++] = fd;
            else if (fd >= 0) close(fd);
        }
    CHECK(refused_total > 0 && kept3 + kept_more <= 23, "past --max-connections 24: %d more let in, %d refused",
          kept_more, refused_total);
    CHECK(strstr(why_total, "--max-connections 24"), "the total's refusal does not name the cap: %s", why_total);
    char out[4096];
    CHECK(cli(&c, out, sizeof out, "status") != 0 && strstr(out, "--max-connections 24"),
          "a status while every connection is taken must be refused naming the cap: %s", out);
    CHECK(count_in(c.log, "refused a connection from 127.0.0.3") == 1,
          "the per-address refusals were logged %d times (want once for 4 refusals)",
          count_in(c.log, "refused a connection from 127.0.0.3"));
    CHECK(count_in(c.log, "(--max-connections 24); further") == 1, "the total's refusals were logged %d times (want once)",
          count_in(c.log, "(--max-connections 24); further"));
    for (int i = 0; i < n; i++) close(fds[i]);
    int again = 0; /* closed connections stop counting */
    for (int i = 0; i < 100 && !again; i++) {
        int fd = raw_connect_from(&c, "127.0.0.3");
        again = fd >= 0 && first_frame(fd, ans, sizeof ans) == 1;
        if (fd >= 0) close(fd);
        if (!again) util_sleep(0.05);
    }
    CHECK(again, "127.0.0.3 is still refused after its connections closed: %s", ans);
    honest_check(&c, job, "caps");
    CHECK(!util_file_count(c.log, "silent for"), "the worker was found silent during the flood; log %s", c.log);
    kill(w, SIGTERM);
    util_wait(w, 10, NULL);
    coord_stop(&c);
}

/* Read and drop what fd has; 1 when the peer has closed it. */
static int drained_to_eof(int fd) {
    char buf[4096];
    for (;;) {
        struct pollfd pf = {fd, POLLIN, 0};
        if (poll(&pf, 1, 0) <= 0) return 0;
        ssize_t r = recv(fd, buf, sizeof buf, MSG_DONTWAIT);
        if (r == 0 || (r < 0 && errno != EAGAIN && errno != EWOULDBLOCK)) return 1;
        if (r < 0) return 0;
    }
}

/* An idle connection is closed at every stage: silent and trickling
 * before its hello (within --client-timeout, 10 s at most), a client
 * silent after its hello (--client-timeout), a worker silent or trickling
 * a frame after its hello (--worker-drop). The honest job beside them
 * finishes byte-identical. */
TEST(hostile_idle_connections_are_closed_at_every_stage) {
    coord c = {0};
    const char *extra[] = {"--client-timeout", "1", "--worker-drop", "3", NULL};
    if (coord_start(&c, "hostile-stages", extra)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    pid_t w = worker_start(&c, "st1");
    int job = honest_submit(&c);
    CHECK(job > 0, "the honest job was not submitted");
    enum { PRE_SILENT, PRE_TRICKLE, CLIENT_IDLE, WORKER_SILENT, WORKER_TRICKLE, STAGES };
    static const char *const names[] = {"silent before its hello", "trickling before its hello",
                                        "a client idle after its hello", "a worker silent after its hello",
                                        "a worker trickling a frame"};
    const double limit[] = {1, 1, 1, 3, 3};
    char buf[4096];
    int fd[STAGES];
    fd[PRE_SILENT] = raw_connect_from(&c, NULL);
    fd[PRE_TRICKLE] = raw_connect_from(&c, NULL);
    fd[CLIENT_IDLE] = raw_hello_from(&c, NULL, "client");
    fd[WORKER_SILENT] = raw_hello_from(&c, NULL, NULL);
    fd[WORKER_TRICKLE] = raw_hello_from(&c, NULL, NULL);
    double t0 = util_now(), closed_at[STAGES] = {0};
    for (int i = 0; i < STAGES; i++) CHECK(fd[i] >= 0, "cannot open the connection %s", names[i]);
    uint8_t hdr[WIRE_HEADER_BYTES];
    wire_put_u32(hdr, 1001); /* a JSON frame of 1000 bytes that never completes */
    hdr[4] = WIRE_KIND_JSON;
    if (fd[WORKER_TRICKLE] >= 0) send(fd[WORKER_TRICKLE], hdr, sizeof hdr, MSG_NOSIGNAL);
    if (fd[PRE_TRICKLE] >= 0) send(fd[PRE_TRICKLE], hdr, sizeof hdr, MSG_NOSIGNAL);
    int open_left = STAGES;
    for (int tick = 0; open_left > 0 && util_now() - t0 < 15 * harness_slack(); tick++) {
        for (int i = 0; i < STAGES; i++) {
            if (fd[i] < 0 || closed_at[i] > 0) continue;
            if ((i == PRE_TRICKLE || i == WORKER_TRICKLE) && tick % 4 == 0) send(fd[i], "x", 1, MSG_NOSIGNAL);
            if (drained_to_eof(fd[i])) {
                closed_at[i] = util_now() - t0;
                open_left--;
            }
        }
        util_sleep(0.05);
    }
    for (int i = 0; i < STAGES; i++) {
        CHECK(closed_at[i] > 0, "a connection %s was not closed within %.0f s", names[i], 15 * harness_slack());
        CHECK(closed_at[i] == 0 || closed_at[i] > 0.8 * limit[i], "a connection %s was closed after %.2f s, before "
              "its %.0f s", names[i], closed_at[i], limit[i]);
        fprintf(stderr, "  (%s: closed after %.2f s; limit %.0f s)\n", names[i], closed_at[i], limit[i]);
        if (fd[i] >= 0) close(fd[i]);
    }
    (void)buf;
    honest_check(&c, job, "stages");
    kill(w, SIGTERM);
    util_wait(w, 10, NULL);
    coord_stop(&c);
}

/* The number in "job N" of a CLI answer, or -1. */
static int job_of(const char *out) {
    int job = -1;
    const char *p = strstr(out, "job ");
    if (p) sscanf(p, "job %d", &job);
    return job;
}

/* The time of day in seconds of the first line of log holding text (the
 * coordinator's "YYYY-MM-DDTHH:MM:SS.mmmZ" stamp), or -1. */
static double log_stamp(const char *log, const char *text) {
    FILE *f = fopen(log, "r");
    char line[1024];
    double t = -1;
    int h, m;
    double sec;
    while (f && fgets(line, sizeof line, f))
        if (strstr(line, text) && sscanf(line, "%*d-%*d-%*dT%d:%d:%lfZ", &h, &m, &sec) == 3) {
            t = h * 3600.0 + m * 60.0 + sec;
            break;
        }
    if (f) fclose(f);
    return t;
}

/* A memory budget: four 32768 x 32768 jobs (24 GiB each: a 12 GiB frame
 * and the saved image's copy) are not all admitted under --max-memory
 * 60G: two wait, queued, with the reason in status; a small job still
 * runs, byte-identical; when the admitted ones are cancelled the waiting
 * ones are admitted. A frame that could never fit is refused at submit
 * time naming the figures, and `tessera render` refuses one up front.
 * Under a sanitizer (whose shadow memory a 12 GiB frame would fill) the
 * same at 8192 x 8192 (1.5 GiB each) under 3840M. */
TEST(hostile_memory_budget_admits_what_fits) {
    int big_side = harness_slack() > 1 ? 8192 : 32768;
    const char *budget = big_side == 32768 ? "60G" : "3840M", *tight_budget = big_side == 32768 ? "16G" : "1G";
    const char *need = big_side == 32768 ? "24.0 GiB" : "1.5 GiB", *tight_s = big_side == 32768 ? "16.0 GiB" : "1.0 GiB";
    char side_args[128], frame[64], want[160];
    snprintf(side_args, sizeof side_args, "--width %d --height %d", big_side, big_side);
    snprintf(frame, sizeof frame, "%dx%d frame", big_side, big_side);
    coord c = {0};
    const char *extra[] = {"--max-memory", budget, NULL};
    if (coord_start(&c, "hostile-memory", extra)) {
        CHECK(0, "coordinator did not start; log %s", c.log);
        return;
    }
    pid_t w = worker_start(&c, "m1");
    int honest = honest_submit(&c), big[4], waiting = 0;
    char out[8192], args[600];
    CHECK(honest > 0, "the honest job was not submitted");
    for (int i = 0; i < 4; i++) {
        snprintf(args, sizeof args, "submit tests/scenes/cornell-small.json %s --tile-size 256 --spp 1 --priority -1",
                 side_args);
        int rc = cli(&c, out, sizeof out, args);
        big[i] = rc == 0 ? job_of(out) : -1;
        CHECK(big[i] > 0, "a %s job was refused under --max-memory %s: %s", frame, budget, out);
        waiting += strstr(out, "waiting for memory") != NULL;
    }
    CHECK(waiting == 2, "%d of four %s jobs were told they wait for memory (want 2 of 4 under %s)", waiting, frame,
          budget);
    int noted = 0;
    snprintf(want, sizeof want, "waiting for memory: needs %s for a %s", need, frame);
    for (int i = 0; i < 4; i++) {
        snprintf(args, sizeof args, "status %d --json", big[i]);
        noted += cli(&c, out, sizeof out, args) == 0 && strstr(out, "queued") && strstr(out, want);
    }
    CHECK(noted == 2, "status shows %d jobs queued with \"%s\" (want 2)", noted, want);
    int small = honest_submit(&c);
    CHECK(small > 0, "a small job was refused beside the waiting ones");
    honest_check(&c, honest, "memory");
    honest_check(&c, small, "memory-small");
    for (int i = 0; i < 2; i++) {
        snprintf(args, sizeof args, "cancel %d", big[i]);
        CHECK(cli(&c, out, sizeof out, args) == 0, "cancel: %s", out);
    }
    snprintf(want, sizeof want, "admitted: its %s fit", need);
    CHECK(util_wait_for_text(c.log, want, 10 * harness_slack()) == 0, "no waiting job was admitted once memory was freed; log %s",
          c.log);
    snprintf(args, sizeof args, "job %d cancelled", big[0]);
    double freed = log_stamp(c.log, args), admitted = log_stamp(c.log, want);
    CHECK(freed > 0 && admitted >= freed && admitted - freed < 0.25 * harness_slack(),
          "a waiting job was admitted %.3f s after memory was freed (at once expected); log %s", admitted - freed, c.log);
    for (int i = 2; i < 4; i++) {
        snprintf(args, sizeof args, "cancel %d", big[i]);
        cli(&c, out, sizeof out, args);
    }
    kill(w, SIGTERM);
    util_wait(w, 10, NULL);
    coord_stop(&c);

    coord small_c = {0}; /* a budget such a frame can never fit */
    const char *tight[] = {"--max-memory", tight_budget, NULL};
    if (coord_start(&small_c, "hostile-memory-tight", tight)) {
        CHECK(0, "coordinator did not start; log %s", small_c.log);
        return;
    }
    snprintf(args, sizeof args, "submit tests/scenes/cornell-small.json %s", side_args);
    int rc = cli(&small_c, out, sizeof out, args);
    snprintf(want, sizeof want, "job needs %s for a %s", need, frame);
    char is[64];
    snprintf(is, sizeof is, "--max-memory is %s", tight_s);
    CHECK(rc != 0 && strstr(out, want) && strstr(out, is),
          "a frame that can never fit was not refused at submit with the figures (%d): %s", rc, out);
    coord_stop(&small_c);
    char cmd[1024];
    double t0 = util_now();
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json %s --max-memory %s --workers 0 -o %s",
             harness_tessera(), side_args, tight_budget, util_temp_path("hostile-memory-render.pfm"));
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc != 0 && strstr(out, need) && strstr(out, is) && util_now() - t0 < 5 * harness_slack(),
          "render of a frame it cannot hold was not refused up front (%d, %.1f s): %s", rc, util_now() - t0, out);
}
