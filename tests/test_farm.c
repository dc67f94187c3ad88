/* test_farm.c - the farm end to end: a real coordinator (`tessera render
 * --listen`), real tessera-worker processes and fake workers on loopback.
 *
 * Every test checks that the image is bit-for-bit the single-process one,
 * whatever was done to the workers on the way: killed, stopped, joined late,
 * told to leave, outrun by a backup, or mixed with peers that send garbage.
 * "Mid-render" is an event, not a race: workers keep their finished tiles
 * while a hold file exists (TESSERA_TEST_HOLD_FILE, util.h) and the tests
 * act once a worker says it is holding; timeouts are generous and only hit
 * when something is broken. */
#include <arpa/inet.h>
#include <math.h>
#include <netinet/in.h>
#include <poll.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "job/job.h"
#include "net/protocol.h"
#include "net/wire.h"
#include "render/scene_bundle.h"
#include "harness.h"
#include "util.h"

#define SCENE "tests/scenes/cornell-small.json"
#define LONG 120.0 /* seconds: only hit when something is broken */

typedef struct {
    char path[256];
} tpath;

static tpath temp(const char *name) {
    tpath t;
    snprintf(t.path, sizeof t.path, "%s", util_temp_path(name));
    unlink(t.path);
    return t;
}

/* The single-process image every farm render must equal (64 spp). */
static const char *reference(const char *ext) {
    static char pfm[256], exr[256];
    char *path = strcmp(ext, "exr") == 0 ? exr : pfm;
    if (path[0]) return path;
    snprintf(path, 256, "%s", util_temp_path(strcmp(ext, "exr") == 0 ? "reference.exr" : "reference.pfm"));
    char cmd[1024], out[4096];
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 --threads 2 -o %s", harness_tessera(), path);
    if (util_run(cmd, out, sizeof out) != 0) {
        fprintf(stderr, "reference render failed: %s\n", out);
        path[0] = '\0';
        return "(no reference)";
    }
    return path;
}

/* Start a coordinator that waits for remote workers; returns its pid and
 * port (parsed from its log). extra: more arguments, NULL-terminated. */
static pid_t start_coordinator(const char *log, const char *out, int port, const char *const *extra, int *port_out) {
    const char *argv[40] = {harness_tessera(), "render", SCENE, "--tile-size", "8", "--no-progress", "-v", "-o", out,
                            "--listen"};
    int n = 10;
    char listen[64];
    snprintf(listen, sizeof listen, "127.0.0.1:%d", port);
    argv[n++] = listen;
    for (int i = 0; extra && extra[i] && n < 38; i++) argv[n++] = extra[i];
    argv[n] = NULL;
    pid_t pid = util_spawn(argv, log);
    *port_out = -1;
    if (pid < 0 || util_wait_for_text(log, "coordinator listening on 127.0.0.1:", LONG)) return pid;
    FILE *f = fopen(log, "r");
    char line[512];
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "tessera: coordinator listening on 127.0.0.1:%d", port_out) == 1) break;
    if (f) fclose(f);
    return pid;
}

/* A worker that keeps its finished tiles (after the first `after`) while
 * the file hold exists (no hold: NULL). */
static pid_t start_worker_held(const char *log, int port, const char *name, const char *throttle_ms, const char *hold,
                               int after) {
    char connect[64], hold_env[300], after_env[64];
    snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold ? hold : "");
    snprintf(after_env, sizeof after_env, "TESSERA_TEST_HOLD_AFTER=%d", after);
    const char *argv[] = {util_bin("tessera-worker"), "--connect", connect, "--threads", "1", "--name", name,
                          "--retry-max", "1", "--throttle-ms", throttle_ms, NULL};
    const char *env[] = {hold_env, after_env, NULL};
    return util_spawn_env(argv, log, hold ? env : NULL);
}

static pid_t start_worker(const char *log, int port, const char *name, const char *throttle_ms) {
    return start_worker_held(log, port, name, throttle_ms, NULL, 0);
}

/* Number of tiles the coordinator's -v table credits to worker name. */
static int tiles_of(const char *log, const char *name) {
    FILE *f = fopen(log, "r");
    char line[1024], who[128];
    int tiles = -1, threads, t;
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, " %127s %*s %d threads %d tiles", who, &threads, &t) == 3 && strcmp(who, name) == 0)
            tiles = tiles < 0 ? t : tiles + t;
    if (f) fclose(f);
    return tiles;
}

/* Stop a worker with SIGTERM and check that it exits cleanly. */
static void stop_worker(pid_t pid, const char *log) {
    kill(pid, SIGTERM);
    int st = util_wait(pid, LONG, NULL);
    CHECK(st == 0, "worker exited with %d after SIGTERM; log %s", st, log);
    CHECK(!util_file_count(log, "Sanitizer") && !util_file_count(log, "runtime error"), "sanitizer report in %s", log);
}

/* Wait for a coordinator and check that it succeeded without sanitizer
 * reports (from itself or local workers, which share its stderr). */
static void coordinator_done(pid_t pid, const char *log, long *rss_kb) {
    int st = util_wait(pid, LONG, rss_kb);
    CHECK(st == 0, "coordinator exited with %d; log %s", st, log);
    CHECK(!util_file_count(log, "Sanitizer") && !util_file_count(log, "runtime error"), "sanitizer report in %s", log);
}

TEST(farm_thread_same_image_any_workers_and_tiles) {
    const char *ref = reference("pfm");
    static const struct {
        const char *workers, *threads, *tile, *ext;
    } runs[] = {{"1", "1", "32", "pfm"}, {"3", "1", "5", "pfm"}, {"2", "2", "13", "exr"}, {"0", "1", "7", "exr"}};
    for (size_t i = 0; i < sizeof runs / sizeof runs[0]; i++) {
        char name[64], cmd[1024], out[8192];
        snprintf(name, sizeof name, "farm-%zu.%s", i, runs[i].ext);
        tpath img = temp(name);
        snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers %s --threads %s --tile-size %s -o %s",
                 harness_tessera(), runs[i].workers, runs[i].threads, runs[i].tile, img.path);
        int st = util_run(cmd, out, sizeof out);
        CHECK(st == 0, "%s failed (%d): %s", cmd, st, out);
        CHECK(!strstr(out, "Sanitizer") && !strstr(out, "runtime error"), "sanitizer report: %s", out);
        const char *want = strcmp(runs[i].ext, "exr") == 0 ? reference("exr") : ref;
        CHECK(util_same_file(img.path, want), "%s: %s differs from the single-process %s", cmd, img.path, want);
    }
}

/* --roulette-depth travels in the job: the farm's workers end paths where
 * the single process does (the same bytes), not where the default would. */
TEST(farm_roulette_depth_reaches_the_workers) {
    tpath one = temp("roulette-0.pfm"), farm = temp("roulette-2.pfm");
    char cmd[1024], out[8192];
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 --threads 2 --roulette-depth 1 -o %s",
             harness_tessera(), one.path);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 0, "%s failed (%d): %s", cmd, st, out);
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 2 --tile-size 11 --roulette-depth 1 -o %s",
             harness_tessera(), farm.path);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0, "%s failed (%d): %s", cmd, st, out);
    CHECK(util_same_file(one.path, farm.path), "--roulette-depth 1: the farm's %s differs from the process's %s",
          farm.path, one.path);
    CHECK(!util_same_file(one.path, reference("pfm")), "--roulette-depth 1 rendered the default's bytes");
}

TEST(farm_kill9_worker_mid_render) {
    tpath clog = temp("kill9-coord.log"), alog = temp("kill9-a.log"), blog = temp("kill9-b.log"),
          img = temp("kill9.pfm"), hold = temp("kill9.hold");
    int port;
    pid_t coord = start_coordinator(clog.path, img.path, 0, NULL, &port);
    CHECK(port > 0, "coordinator did not start; log %s", clog.path);
    util_touch(hold.path); /* both keep their tiles: the render cannot end */
    pid_t a = start_worker_held(alog.path, port, "A", "0", hold.path, 0);
    pid_t b = start_worker_held(blog.path, port, "B", "0", hold.path, 0);
    CHECK(util_wait_for_text(blog.path, UTIL_HOLDING, LONG) == 0, "B never held a tile; log %s", blog.path);
    kill(b, SIGKILL); /* B holds tiles now */
    util_wait(b, LONG, NULL);
    CHECK(util_wait_for_text(clog.path, "go back to the queue", LONG) == 0 &&
              util_file_count(clog.path, "worker B (127.0.0.1:"),
          "the coordinator did not notice B's death; log %s", clog.path);
    unlink(hold.path);
    coordinator_done(coord, clog.path, NULL);
    CHECK(util_same_file(img.path, reference("pfm")), "image differs after kill -9; log %s", clog.path);
    stop_worker(a, alog.path);
}

TEST(farm_sigstop_worker_lease_expires) {
    tpath clog = temp("stop-coord.log"), alog = temp("stop-a.log"), blog = temp("stop-b.log"), img = temp("stop.pfm"),
          hold_a = temp("stop-a.hold"), hold_b = temp("stop-b.hold");
    const char *extra[] = {"--heartbeat", "0.1", "--worker-timeout", "0.6", NULL};
    int port;
    pid_t coord = start_coordinator(clog.path, img.path, 0, extra, &port);
    CHECK(port > 0, "coordinator did not start; log %s", clog.path);
    util_touch(hold_a.path);
    util_touch(hold_b.path);
    pid_t a = start_worker_held(alog.path, port, "A", "0", hold_a.path, 0);
    pid_t b = start_worker_held(blog.path, port, "B", "0", hold_b.path, 0);
    CHECK(util_wait_for_text(alog.path, UTIL_HOLDING, LONG) == 0 && util_wait_for_text(blog.path, UTIL_HOLDING, LONG) == 0,
          "A and B never held tiles; logs %s %s", alog.path, blog.path);
    kill(b, SIGSTOP); /* B holds a finished tile and is stopped */
    CHECK(util_wait_for_text(clog.path, "silent for", LONG) == 0, "B's stall was not noticed; log %s", clog.path);
    kill(b, SIGCONT); /* its late results must be ignored or used, never harmful */
    CHECK(util_wait_for_text(clog.path, "is responding again", LONG) == 0, "B's return not noticed; log %s", clog.path);
    unlink(hold_b.path); /* B sends the tile it kept; A still holds, so nobody else has finished it */
    CHECK(util_wait_for_text(clog.path, "late result for", LONG) == 0, "B's late result not used; log %s", clog.path);
    unlink(hold_a.path);
    coordinator_done(coord, clog.path, NULL);
    CHECK(util_file_count(clog.path, "worker B") && util_file_count(clog.path, "tiles go back to the queue"),
          "no requeue after the stall; log %s", clog.path);
    CHECK(util_file_count(clog.path, "is responding again") && !util_file_count(clog.path, "left: connection"),
          "B was not taken back after waking up; log %s", clog.path);
    CHECK(util_file_count(clog.path, "was already done; dropped") + util_file_count(clog.path, "late result for") >= 1,
          "B's late results were neither dropped nor used; log %s", clog.path);
    CHECK(util_same_file(img.path, reference("pfm")), "image differs after SIGSTOP; log %s", clog.path);
    stop_worker(a, alog.path);
    stop_worker(b, blog.path);
}

TEST(farm_worker_joins_mid_render_and_one_leaves) {
    tpath clog = temp("join-coord.log"), alog = temp("join-a.log"), blog = temp("join-b.log"), img = temp("join.pfm"),
          hold_a = temp("join-a.hold"), hold_b = temp("join-b.hold");
    int port;
    pid_t coord = start_coordinator(clog.path, img.path, 0, NULL, &port);
    CHECK(port > 0, "coordinator did not start; log %s", clog.path);
    util_touch(hold_a.path);
    util_touch(hold_b.path);
    pid_t a = start_worker_held(alog.path, port, "A", "0", hold_a.path, 3); /* 3 tiles, then it keeps them */
    CHECK(util_wait_for_text(alog.path, UTIL_HOLDING, LONG) == 0, "A never held a tile; log %s", alog.path);
    pid_t b = start_worker_held(blog.path, port, "B", "0", hold_b.path, 0); /* joins mid-render */
    CHECK(util_wait_for_text(blog.path, UTIL_HOLDING, LONG) == 0, "B never got work; log %s", blog.path);
    kill(a, SIGTERM); /* A gives its tiles back and leaves */
    CHECK(util_wait(a, LONG, NULL) == 0, "A did not exit cleanly on SIGTERM; log %s", alog.path);
    CHECK(util_wait_for_text(clog.path, "left: worker left", LONG) == 0, "A's departure not logged; log %s", clog.path);
    unlink(hold_b.path); /* B finishes the render */
    coordinator_done(coord, clog.path, NULL);
    CHECK(tiles_of(clog.path, "A") > 0 && tiles_of(clog.path, "B") > 0, "tiles: A %d, B %d; log %s",
          tiles_of(clog.path, "A"), tiles_of(clog.path, "B"), clog.path);
    CHECK(util_file_count(clog.path, "worker A (") && util_file_count(clog.path, "left: worker left"),
          "A's departure not logged; log %s", clog.path);
    CHECK(util_same_file(img.path, reference("pfm")), "image differs; log %s", clog.path);
    stop_worker(b, blog.path);
}

TEST(farm_backup_tasks_beat_a_slow_worker) {
    tpath clog = temp("backup-coord.log"), alog = temp("backup-a.log"), blog = temp("backup-b.log"),
          img = temp("backup.pfm"), hold = temp("backup.hold");
    const char *extra[] = {"--tile-size", "16", NULL};
    int port;
    pid_t coord = start_coordinator(clog.path, img.path, 0, extra, &port);
    CHECK(port > 0, "coordinator did not start; log %s", clog.path);
    util_touch(hold.path); /* "slow" never returns a tile while the render lasts */
    pid_t b = start_worker_held(blog.path, port, "slow", "0", hold.path, 0);
    CHECK(util_wait_for_text(blog.path, UTIL_HOLDING, LONG) == 0, "slow never got a tile; log %s", blog.path);
    pid_t a = start_worker(alog.path, port, "fast", "0");
    coordinator_done(coord, clog.path, NULL);
    int backups = 0;
    FILE *f = fopen(clog.path, "r");
    char line[1024];
    while (f && fgets(line, sizeof line, f)) {
        const char *p = strstr(line, " requeued, ");
        if (p) sscanf(p, " requeued, %d backups", &backups);
    }
    if (f) fclose(f);
    CHECK(backups >= 1, "no backup tasks were handed out; log %s", clog.path);
    CHECK(tiles_of(clog.path, "fast") == 16, "the fast worker stitched %d of 16 tiles; log %s",
          tiles_of(clog.path, "fast"), clog.path);
    CHECK(util_same_file(img.path, reference("pfm")), "image differs; log %s", clog.path);
    stop_worker(a, alog.path);
    stop_worker(b, blog.path);
    unlink(hold.path);
}

TEST(farm_workers_wait_for_and_survive_a_coordinator) {
    tpath c1 = temp("restart-coord1.log"), c2 = temp("restart-coord2.log"), wlog = temp("restart-w.log"),
          img1 = temp("restart1.pfm"), img2 = temp("restart2.pfm"), hold = temp("restart.hold");
    int port = util_free_port(), got;
    util_touch(hold.path);
    pid_t w = start_worker_held(wlog.path, port, "W", "0", hold.path, 0); /* nothing listens yet */
    CHECK(util_wait_for_text(wlog.path, "retrying", LONG) == 0, "worker does not say it retries; log %s", wlog.path);
    pid_t coord = start_coordinator(c1.path, img1.path, port, NULL, &got);
    CHECK(got == port, "coordinator 1 did not listen on %d; log %s", port, c1.path);
    CHECK(util_wait_for_text(wlog.path, UTIL_HOLDING, LONG) == 0, "W never got a tile from coordinator 1");
    kill(coord, SIGKILL); /* the coordinator dies mid-render */
    util_wait(coord, LONG, NULL);
    CHECK(util_wait_for_text(wlog.path, "lost the coordinator", LONG) == 0, "worker did not notice; log %s",
          wlog.path);
    unlink(hold.path);
    coord = start_coordinator(c2.path, img2.path, port, NULL, &got);
    CHECK(got == port, "coordinator 2 did not listen on %d; log %s", port, c2.path);
    coordinator_done(coord, c2.path, NULL);
    CHECK(tiles_of(c2.path, "W") == 64, "W rendered %d of 64 tiles for coordinator 2", tiles_of(c2.path, "W"));
    CHECK(util_same_file(img2.path, reference("pfm")), "image differs; log %s", c2.path);
    stop_worker(w, wlog.path);
}

/* ---- fake workers -------------------------------------------------------- */

static int dial(int port) {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port),
                            .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    if (fd >= 0 && connect(fd, (struct sockaddr *)&a, sizeof a) != 0) {
        close(fd);
        return -1;
    }
    return fd;
}

static void send_all(int fd, const void *buf, size_t len) {
    const char *p = buf;
    while (len > 0) {
        ssize_t n = send(fd, p, len, MSG_NOSIGNAL);
        if (n <= 0) return;
        p += n;
        len -= (size_t)n;
    }
}

static void send_json_text(int fd, const char *text) {
    size_t len;
    uint8_t *f = wire_frame_new(WIRE_KIND_JSON, strlen(text), &len);
    memcpy(f + WIRE_HEADER_BYTES, text, strlen(text));
    send_all(fd, f, len);
    free(f);
}

static void send_hello(int fd, const char *name, int protocol) {
    char text[512];
    snprintf(text, sizeof text, "{\"type\":\"hello\",\"protocol\":%d,\"build\":\"%s\",\"name\":\"%s\",\"threads\":1}",
             protocol, protocol_build_id(), name);
    send_json_text(fd, text);
}

/* Read exactly want bytes, waiting up to 60 s for each piece (only a broken
 * coordinator takes that long). */
static int read_exact(int fd, uint8_t *dst, size_t want) {
    size_t have = 0;
    while (have < want) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, 60000) <= 0) return -1;
        ssize_t n = recv(fd, dst + have, want - have, 0);
        if (n <= 0) return -1;
        have += (size_t)n;
    }
    return 0;
}

/* Read one frame; returns its kind with the body in buf, or -1. */
static int read_frame(int fd, uint8_t *buf, size_t cap, size_t *len) {
    uint8_t hdr[WIRE_HEADER_BYTES];
    if (read_exact(fd, hdr, sizeof hdr)) return -1;
    uint32_t l = wire_get_u32(hdr);
    if (l < 1 || l - 1 > cap || read_exact(fd, buf, l - 1)) return -1;
    *len = l - 1;
    return hdr[4];
}

/* Whether the coordinator closed fd (EOF within 60 s). */
static int closed_by_peer(int fd) {
    char b[4096];
    for (int i = 0; i < 600; i++) {
        struct pollfd p = {fd, POLLIN, 0};
        if (poll(&p, 1, 100) > 0) {
            ssize_t n = recv(fd, b, sizeof b, 0);
            if (n <= 0) return 1;
        }
    }
    return 0;
}

/* Hello, ready, and wait for an assignment; returns the tile rect. */
static int fake_get_tile(int fd, const char *name, proto_assign *a) {
    static uint8_t buf[1 << 20];
    size_t len;
    send_hello(fd, name, PROTOCOL_VERSION);
    send_json_text(fd, "{\"type\":\"ready\",\"slots\":1}");
    for (int i = 0; i < 1000; i++) { /* heartbeats may come first */
        int kind = read_frame(fd, buf, sizeof buf, &len);
        if (kind < 0) return -1;
        if (kind != WIRE_KIND_JSON) continue; /* the scene */
        const char *type;
        char err[256];
        cJSON *m = proto_parse_json(buf, len, &type, err, sizeof err);
        int rc = m && strcmp(type, "assign") == 0 ? proto_assign_parse(m, "test", a, err, sizeof err) : 1;
        cJSON_Delete(m);
        if (rc == 0) return 0;
    }
    return -1;
}

static void send_tile(int fd, uint32_t job, uint32_t tile, int w, int h, float value) {
    float *rgb = calloc((size_t)w * (size_t)h * 3, sizeof(float));
    rgb[0] = value;
    proto_tile t = {job, tile, (uint32_t)w, (uint32_t)h, {0, 0, 0, 0}, 3};
    size_t len;
    uint8_t *f = proto_tile_frame(&t, rgb, &len);
    send_all(fd, f, len);
    free(f);
    free(rgb);
}

TEST(farm_bad_peers_are_dropped_and_the_render_goes_on) {
    tpath clog = temp("bad-coord.log"), wlog = temp("bad-w.log"), img = temp("bad.pfm");
    int port;
    pid_t coord = start_coordinator(clog.path, img.path, 0, NULL, &port);
    CHECK(port > 0, "coordinator did not start; log %s", clog.path);
    int fd;
    /* Not our protocol at all: "GET " read as a length. */
    fd = dial(port);
    send_all(fd, "GET / HTTP/1.1\r\n\r\n", 18);
    CHECK(closed_by_peer(fd), "HTTP request not dropped");
    close(fd);
    /* A frame claiming 4 GiB, followed by a flood: nothing is buffered. */
    fd = dial(port);
    uint8_t huge[4] = {0xff, 0xff, 0xff, 0xff};
    send_all(fd, huge, 4);
    static char flood[1 << 20];
    for (int i = 0; i < 64; i++) send_all(fd, flood, sizeof flood);
    CHECK(closed_by_peer(fd), "4 GiB frame not dropped");
    close(fd);
    /* Wrong protocol version: refused, with both versions named. */
    fd = dial(port);
    send_hello(fd, "old", 99);
    CHECK(closed_by_peer(fd), "version mismatch not refused");
    close(fd);
    /* Malformed JSON after a good hello. */
    fd = dial(port);
    send_hello(fd, "badjson", PROTOCOL_VERSION);
    send_json_text(fd, "{\"type\": \"ready\", slots");
    CHECK(closed_by_peer(fd), "bad JSON not dropped");
    close(fd);
    /* A truncated frame, then the peer hangs up. */
    fd = dial(port);
    send_hello(fd, "truncated", PROTOCOL_VERSION);
    uint8_t part[14] = {100, 0, 0, 0, 'J', '{'};
    send_all(fd, part, sizeof part);
    shutdown(fd, SHUT_WR); /* a clean end of stream inside the frame */
    CHECK(closed_by_peer(fd), "truncated frame not noticed");
    close(fd);
    /* A tile for a job it was never given. */
    fd = dial(port);
    send_hello(fd, "wrongjob", PROTOCOL_VERSION);
    send_tile(fd, 99, 0, 8, 8, 0.5f);
    CHECK(closed_by_peer(fd), "tile of an unknown job not dropped");
    close(fd);
    /* Given a tile: answers with NaN, with the wrong size, or another tile. */
    static const char *const names[] = {"nan", "wrongsize", "othertile"};
    for (int k = 0; k < 3; k++) {
        proto_assign a;
        fd = dial(port);
        CHECK(fake_get_tile(fd, names[k], &a) == 0, "fake worker %s got no tile", names[k]);
        int w = tile_width(&a.rect), h = tile_height(&a.rect);
        if (k == 0) send_tile(fd, a.job, a.tile, w, h, NAN);
        if (k == 1) send_tile(fd, a.job, a.tile, w + 1, h, 0.5f);
        if (k == 2) send_tile(fd, a.job, a.tile + 1, w, h, 0.5f);
        CHECK(closed_by_peer(fd), "fake worker %s not dropped", names[k]);
        close(fd);
    }
    /* A real worker finishes the job. */
    pid_t w = start_worker(wlog.path, port, "real", "0");
    long rss_kb = 0;
    coordinator_done(coord, clog.path, &rss_kb);
    static const char *const expect[] = {
        "frame of 542393671 bytes exceeds the limit",
        "frame of 4294967295 bytes exceeds the limit",
        "worker old (127.0.0.1:",
        "version mismatch: worker speaks protocol 99, build ",
        "worker badjson (127.0.0.1:",
        "malformed JSON message",
        "worker truncated (127.0.0.1:",
        "closed in the middle of a frame",
        "worker wrongjob (127.0.0.1:",
        "sent tile 0 of job 99, a job it was not given",
        "worker nan (127.0.0.1:",
        "with a NaN, infinite or negative value",
        "worker wrongsize (127.0.0.1:",
        "pixels; it is",
        "worker othertile (127.0.0.1:",
        "which was not assigned to it",
    };
    for (size_t i = 0; i < sizeof expect / sizeof expect[0]; i++)
        CHECK(util_file_count(clog.path, expect[i]), "log lacks \"%s\"; log %s", expect[i], clog.path);
    CHECK(util_same_file(img.path, reference("pfm")), "image differs; log %s", clog.path);
    CHECK(rss_kb > 0 && rss_kb < 64 * 1024, "coordinator peak memory %ld KiB after a 64 MiB flood", rss_kb);
    stop_worker(w, wlog.path);
}

/* Dial, say hello claiming `scenes` (JSON text for the hello's "scenes"
 * field), ask for a tile and read up to its assignment: 0 with *a filled
 * and *sent_scene saying whether the scene's bundle came first, or -1. */
static int fake_claim_and_get_tile(int port, const char *name, const char *scenes, proto_assign *a, int *sent_scene) {
    static uint8_t buf[1 << 20];
    char text[4096];
    size_t len;
    int fd = dial(port);
    snprintf(text, sizeof text,
             "{\"type\":\"hello\",\"protocol\":%d,\"build\":\"%s\",\"name\":\"%s\",\"threads\":1,\"scenes\":%s}",
             PROTOCOL_VERSION, protocol_build_id(), name, scenes);
    send_json_text(fd, text);
    send_json_text(fd, "{\"type\":\"ready\",\"slots\":1}");
    *sent_scene = 0;
    int rc = -1;
    for (int i = 0; i < 1000 && rc < 0; i++) { /* heartbeats may come first */
        int kind = read_frame(fd, buf, sizeof buf, &len);
        if (kind < 0) break;
        if (kind == WIRE_KIND_SCENE) *sent_scene = 1;
        if (kind != WIRE_KIND_JSON) continue;
        const char *type;
        char err[256];
        cJSON *m = proto_parse_json(buf, len, &type, err, sizeof err);
        if (m && strcmp(type, "assign") == 0 && proto_assign_parse(m, "test", a, err, sizeof err) == 0) rc = 0;
        cJSON_Delete(m);
    }
    close(fd); /* its tile goes back to the queue */
    return rc;
}

/* A hello's "scenes" (a local farm's forked worker claims the bundle it
 * was forked with): a claim of the job's bundle hash means the bundle is
 * not sent; claims that are not bundle hashes (numbers, short or
 * uppercase strings, a string instead of an array, too many) are ignored,
 * and the bundle is sent. The render ends with the right image. */
TEST(farm_hello_scene_claims) {
    tpath clog = temp("claims-coord.log"), wlog = temp("claims-w.log"), img = temp("claims.pfm");
    scene_bundle b;
    char err[256], hash[SCENE_BUNDLE_HASH_HEX], claim[256], upper[SCENE_BUNDLE_HASH_HEX];
    CHECK(scene_bundle_read(SCENE, &b, err, sizeof err) == 0, "%s", err);
    size_t len;
    uint8_t *bytes = scene_bundle_serialise(&b, &len);
    scene_bundle_hash(bytes, len, hash);
    free(bytes);
    scene_bundle_free(&b);
    for (int i = 0; hash[i]; i++) upper[i] = (char)(hash[i] >= 'a' && hash[i] <= 'f' ? hash[i] - 32 : hash[i]);
    upper[SCENE_BUNDLE_HASH_HEX - 1] = '\0';
    int port;
    pid_t coord = start_coordinator(clog.path, img.path, 0, NULL, &port);
    CHECK(port > 0, "coordinator did not start; log %s", clog.path);
    proto_assign a;
    int sent;
    snprintf(claim, sizeof claim, "[\"%s\"]", hash);
    CHECK(fake_claim_and_get_tile(port, "claims", claim, &a, &sent) == 0 && !sent,
          "a worker claiming the job's scene: %s; log %s", sent ? "was sent the bundle" : "got no tile", clog.path);
    free(a.mask);
    char junk[2048];
    snprintf(junk, sizeof junk, "[5, \"abc\", \"%s\", null, {\"h\": \"%s\"}]", upper, hash);
    CHECK(fake_claim_and_get_tile(port, "junk", junk, &a, &sent) == 0 && sent,
          "a worker with junk claims: %s; log %s", sent ? "got no tile" : "was not sent the bundle", clog.path);
    free(a.mask);
    snprintf(junk, sizeof junk, "\"%s\"", hash); /* not an array */
    CHECK(fake_claim_and_get_tile(port, "notarray", junk, &a, &sent) == 0 && sent,
          "a worker claiming by a string: %s; log %s", sent ? "got no tile" : "was not sent the bundle", clog.path);
    free(a.mask);
    size_t off = (size_t)snprintf(junk, sizeof junk, "[");
    for (int i = 0; i < PROTOCOL_HELLO_SCENES; i++) /* the real one comes after the limit */
        off += (size_t)snprintf(junk + off, sizeof junk - off, "\"%064d\",", i);
    snprintf(junk + off, sizeof junk - off, "\"%s\"]", hash);
    CHECK(fake_claim_and_get_tile(port, "toomany", junk, &a, &sent) == 0 && sent,
          "a worker claiming past the limit: %s; log %s", sent ? "got no tile" : "was not sent the bundle", clog.path);
    free(a.mask);
    pid_t w = start_worker(wlog.path, port, "real", "0");
    coordinator_done(coord, clog.path, NULL);
    CHECK(util_same_file(img.path, reference("pfm")), "image differs; log %s", clog.path);
    stop_worker(w, wlog.path);
}

TEST(farm_ships_scene_and_meshes_to_workers) {
    /* A mesh of 7200 triangles (about 200 KB of OBJ: more than a control
     * frame), in a folder deleted before the worker starts: the worker can
     * only have it from the scene bundle. */
    static char obj[1 << 20];
    size_t n = 0;
    const int g = 60;
    for (int z = 0; z <= g; z++)
        for (int x = 0; x <= g; x++)
            n += (size_t)snprintf(obj + n, sizeof obj - n, "v %g %g %g\n", -1.0 + 2.0 * x / g,
                                  0.1 * sin(x * 0.7) * cos(z * 0.5), -1.0 + 2.0 * z / g);
    for (int z = 0; z < g; z++)
        for (int x = 0; x < g; x++) {
            int a = z * (g + 1) + x + 1, b = a + 1, c = a + g + 1, d = c + 1;
            n += (size_t)snprintf(obj + n, sizeof obj - n, "f %d %d %d\nf %d %d %d\n", a, c, b, b, c, d);
        }
    CHECK(n > 100000 && n < sizeof obj - 100, "OBJ is %zu bytes", n);
    util_write_temp("bumps.obj", obj);
    const char *scene_path = util_write_temp(
        "bumps.json",
        "{\"render\": {\"width\": 40, \"height\": 30, \"spp\": 8, \"max_depth\": 8, \"seed\": 5},"
        " \"camera\": {\"type\": \"perspective\", \"position\": [0, 1.5, -3], \"look_at\": [0, 0, 0], \"fov\": 45},"
        " \"materials\": {\"white\": {\"type\": \"diffuse\", \"albedo\": [0.7, 0.7, 0.7]}},"
        " \"shapes\": [{\"type\": \"mesh\", \"file\": \"bumps.obj\", \"material\": \"white\"},"
        "  {\"type\": \"sphere\", \"center\": [0, 3, 0], \"radius\": 0.5, \"emission\": [20, 20, 20]}]}");
    char scene[256], cmd[1024], out[4096];
    snprintf(scene, sizeof scene, "%s", scene_path);
    tpath ref = temp("bumps-ref.exr"), img = temp("bumps.exr"), clog = temp("bumps-coord.log"),
          wlog = temp("bumps-w.log");
    snprintf(cmd, sizeof cmd, "%s render %s --workers 0 -o %s", harness_tessera(), scene, ref.path);
    CHECK(util_run(cmd, out, sizeof out) == 0, "in-process render failed: %s", out);
    const char *argv[] = {harness_tessera(), "render", scene, "--listen", "127.0.0.1:0", "--no-progress", "-v",
                          "-o", img.path, NULL};
    pid_t coord = util_spawn(argv, clog.path);
    CHECK(util_wait_for_text(clog.path, "coordinator listening on 127.0.0.1:", LONG) == 0, "no coordinator");
    int port = -1;
    FILE *f = fopen(clog.path, "r");
    char line[512];
    while (f && fgets(line, sizeof line, f))
        if (sscanf(line, "tessera: coordinator listening on 127.0.0.1:%d", &port) == 1) break;
    if (f) fclose(f);
    unlink(util_temp_path("bumps.obj"));
    unlink(scene);
    pid_t w = start_worker(wlog.path, port, "meshes", "0");
    coordinator_done(coord, clog.path, NULL);
    CHECK(util_same_file(img.path, ref.path), "farm image of a mesh scene differs; log %s", clog.path);
    stop_worker(w, wlog.path);
}

TEST(farm_local_workers_that_fail_end_the_render_with_an_error) {
    char cmd[1024], out[8192];
    /* A worker program that exits at once: restarted 3 times per slot, then
     * a clear error, never a hang. */
    snprintf(cmd, sizeof cmd, "TESSERA_WORKER=/bin/false %s render " SCENE " --workers 2 -o %s", harness_tessera(),
             temp("never.pfm").path);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 1 && strstr(out, "every local worker failed") && strstr(out, "local worker local-1 exited with status 1"),
          "status %d: %s", st, out);
    snprintf(cmd, sizeof cmd, "TESSERA_WORKER=/nonexistent/worker %s render " SCENE " --workers 2 -o %s",
             harness_tessera(), temp("never.pfm").path);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 1 && strstr(out, "cannot run the worker program /nonexistent/worker"), "status %d: %s", st, out);
    CHECK(access(temp("never.pfm").path, F_OK) != 0, "an image was written by a failed render");
}

/* A render of fewer tiles than local workers can end before the last has
 * joined. That worker is told to leave (SIGTERM) while the port is still
 * open, and leaves without a word: before, it found the port closed and
 * printed "cannot reach the coordinator ... connection refused" in about
 * half of such renders (3 of 6 at 8x8 pixels), and telling it to leave
 * while it connected could hang it (test_idle_exit.c). 8 renders; each
 * prints its "rendered" line and nothing else, and no worker is left. */
TEST(farm_tiny_render_ends_quietly_with_every_worker_gone) {
    for (int i = 0; i < 8; i++) {
        char cmd[1024], out[8192];
        snprintf(cmd, sizeof cmd, "%s render " SCENE " --width 8 --height 8 --spp 1 --workers 2 --no-progress -o %s",
                 harness_tessera(), temp("tiny.pfm").path);
        int st = util_run(cmd, out, sizeof out);
        const char *nl = strchr(out, '\n');
        CHECK(st == 0 && strncmp(out, "rendered ", 9) == 0 && nl && nl[1] == '\0',
              "render %d: status %d, want only the rendered line: %s", i, st, out);
    }
    char out[256] = "";
    util_run("pgrep -f 'tessera-worker --connect 127.0.0.1:[0-9]* --threads 1 --name local-' | wc -l", out, sizeof out);
    CHECK(atoi(out) == 0, "%d local workers are still running", atoi(out));
}

/* One job across CPU generations: a coordinator and a native worker (AVX2
 * or AVX-512 here) with a second worker under qemu emulating a Nehalem
 * (SSE4.2, no AVX: the flat kernel's 4 lanes, the SSE walk over leaves of
 * 4), each rendering some of the tiles: the image is the native single
 * process's, byte for byte, on the box (flat kernel) and the icospheres
 * (wide BVH). The emulated worker runs with --once and is never signalled:
 * under qemu-user a signal reaching libuv's handler kills the process
 * (2026-12-03: also why a local farm's coordinator cannot itself run under
 * qemu), so it leaves when the coordinator closes its connection. */
TEST(farm_one_job_across_cpu_generations_same_bytes) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    return;
#else
    if (!util_have_qemu()) return;
    const char *scenes[] = {SCENE, "tests/scenes/icospheres.json"};
    for (int k = 0; k < 2; k++) {
        tpath clog = temp("gen-coord.log"), nlog = temp("gen-native.log"), qlog = temp("gen-qemu.log"),
              img = temp("gen.pfm"), ref = temp("gen-ref.pfm");
        char cmd[1024], out[4096], connect[64];
        snprintf(cmd, sizeof cmd, "%s render %s --workers 0 --spp 8 --no-progress -o %s", harness_tessera(),
                 scenes[k], ref.path);
        CHECK(util_run(cmd, out, sizeof out) == 0, "reference: %s", out);
        const char *argv[] = {harness_tessera(), "render", scenes[k], "--spp", "8", "--tile-size", "8",
                              "--no-progress", "-v", "-o", img.path, "--listen", "127.0.0.1:0", NULL};
        pid_t coord = util_spawn(argv, clog.path);
        int port = -1;
        if (coord > 0 && util_wait_for_text(clog.path, "coordinator listening on 127.0.0.1:", LONG) == 0) {
            FILE *f = fopen(clog.path, "r");
            char line[512];
            while (f && fgets(line, sizeof line, f))
                if (sscanf(line, "tessera: coordinator listening on 127.0.0.1:%d", &port) == 1) break;
            if (f) fclose(f);
        }
        CHECK(port > 0, "coordinator did not start; log %s", clog.path);
        snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
        const char *qargv[] = {"/usr/bin/qemu-x86_64", "-cpu", "Nehalem-v1", util_bin("tessera-worker"), "--connect",
                               connect, "--threads", "1", "--name", "nehalem", "--once", NULL};
        pid_t q = util_spawn(qargv, qlog.path);
        /* The native worker sleeps after each tile, so the emulated one
         * (tens of times slower) gets some of them. */
        pid_t n = start_worker(nlog.path, port, "native", "100");
        coordinator_done(coord, clog.path, NULL);
        int qst = util_wait(q, LONG, NULL);
        CHECK(qst == 0, "%s: the emulated worker exited with %d; log %s", scenes[k], qst, qlog.path);
        stop_worker(n, nlog.path);
        int tq = tiles_of(clog.path, "nehalem"), tn = tiles_of(clog.path, "native");
        CHECK(tq > 0 && tn > 0, "%s: tiles by the emulated worker %d, the native one %d; log %s", scenes[k], tq, tn,
              clog.path);
        CHECK(util_same_file(img.path, ref.path), "%s: one job across CPU generations differs from one process; log %s",
              scenes[k], clog.path);
    }
#endif
}
