/* test_audit.c - audited tiles (`--audit FRACTION`, coordinator/farm_audit.c)
 * end to end: a real coordinator (`tessera render --listen`), honest
 * tessera-worker processes and one made faulty on purpose with
 * TESSERA_TEST_FAULT (worker/pool.c: scale every value by 1 + 1e-6, or flip
 * one bit in one tile in 50, starting with its first tile).
 *
 * Checked: the faulty worker is quarantined every time with --audit 1.0,
 * and with 0.1 after delivering a bounded number of unchecked tiles; the
 * image is byte-identical to the single-process render either way (its
 * unchecked tiles are rendered again); an honest farm is never flagged. */
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"
#include "util.h"

#define SCENE "tests/scenes/cornell-small.json"
#define LONG 120.0 /* seconds: only hit when something is broken */

/* The single-process image for spp (static storage per spp value used). */
static const char *audit_reference(int spp) {
    static char paths[2][256];
    char *path = paths[spp == 64 ? 0 : 1];
    if (path[0]) return path;
    char name[64], cmd[1024], out[4096];
    snprintf(name, sizeof name, "audit-reference-%d.pfm", spp);
    snprintf(path, 256, "%s", util_temp_path(name));
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --spp %d --workers 0 --threads 2 -o %s", harness_tessera(), spp,
             path);
    if (util_run(cmd, out, sizeof out) != 0) fprintf(stderr, "reference render failed: %s\n", out);
    return path;
}

static pid_t start_worker(const char *log, int port, const char *name, const char *fault) {
    char connect[64], env[128];
    snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
    snprintf(env, sizeof env, "TESSERA_TEST_FAULT=%s", fault ? fault : "");
    const char *argv[] = {util_bin("tessera-worker"), "--connect", connect, "--threads", "1", "--name", name,
                          "--retry-max", "1", NULL};
    const char *envv[] = {env, NULL};
    return util_spawn_env(argv, log, fault ? envv : NULL);
}

/* The number in "; N tiles it alone delivered" on the quarantine line, or -1. */
static int redone_tiles(const char *log) {
    FILE *f = fopen(log, "r");
    char line[2048];
    int n = -1;
    while (f && fgets(line, sizeof line, f)) {
        const char *p = strstr(line, "is quarantined for this job; ");
        if (p && n < 0) sscanf(p, "is quarantined for this job; %d", &n);
    }
    if (f) fclose(f);
    return n;
}

/* Render SCENE at `tile` px tiles with --audit `fraction` on two honest
 * workers and one with `fault`; check F is quarantined, nobody else is, and
 * the image is the single-process one. Returns the tiles F had delivered
 * unchecked when it was caught (-1 if never). */
static int run_faulty_farm(const char *tag, const char *fault, const char *fraction, const char *tile) {
    char clog[256], flog[256], alog[256], blog[256], img[256], listen[64], name[96];
    snprintf(name, sizeof name, "audit-%s-coord.log", tag);
    snprintf(clog, sizeof clog, "%s", util_temp_path(name));
    snprintf(name, sizeof name, "audit-%s-f.log", tag);
    snprintf(flog, sizeof flog, "%s", util_temp_path(name));
    snprintf(name, sizeof name, "audit-%s-a.log", tag);
    snprintf(alog, sizeof alog, "%s", util_temp_path(name));
    snprintf(name, sizeof name, "audit-%s-b.log", tag);
    snprintf(blog, sizeof blog, "%s", util_temp_path(name));
    snprintf(name, sizeof name, "audit-%s.pfm", tag);
    snprintf(img, sizeof img, "%s", util_temp_path(name));
    unlink(clog);
    unlink(img);
    int port = util_free_port();
    snprintf(listen, sizeof listen, "127.0.0.1:%d", port);
    const char *argv[] = {harness_tessera(), "render", SCENE, "--tile-size", tile, "--no-progress", "-v", "-o", img,
                          "--listen", listen, "--audit", fraction, NULL};
    pid_t coord = util_spawn(argv, clog);
    CHECK(util_wait_for_text(clog, "coordinator listening on", LONG) == 0, "coordinator did not start; log %s", clog);
    /* The honest ones first: F's tiles can be checked from the start. */
    pid_t a = start_worker(alog, port, "A", NULL), b = start_worker(blog, port, "B", NULL);
    CHECK(util_wait_for_text(clog, "worker A (", LONG) == 0 && util_wait_for_text(clog, "worker B (", LONG) == 0,
          "A and B never joined; log %s", clog);
    pid_t f = start_worker(flog, port, "F", fault);
    int st = util_wait(coord, LONG, NULL);
    CHECK(st == 0, "coordinator exited with %d; log %s", st, clog);
    CHECK(!util_file_count(clog, "Sanitizer") && !util_file_count(clog, "runtime error"), "sanitizer report in %s",
          clog);
    CHECK(util_file_count(clog, "worker F (127.0.0.1:") && util_file_count(clog, "is quarantined for this job"),
          "%s: F was not quarantined; log %s", fault, clog);
    CHECK(util_file_count(clog, "is quarantined for this job") == 1 && util_file_count(clog, "QUARANTINED in") == 1,
          "%s: more than F was quarantined, or the table does not show it; log %s", fault, clog);
    CHECK(util_file_count(clog, "returned different pixels from") >= 1, "no evidence logged; log %s", clog);
    CHECK(util_same_file(img, audit_reference(64)), "%s: image differs from the single-process one; log %s", fault,
          clog);
    pid_t ws[] = {f, a, b};
    for (int i = 0; i < 3; i++) {
        kill(ws[i], SIGTERM);
        util_wait(ws[i], LONG, NULL);
    }
    return redone_tiles(clog);
}

TEST(audit_full_catches_scaled_and_flipped_tiles) {
    run_faulty_farm("full-scale", "scale:1e-6", "1.0", "8");
    run_faulty_farm("full-flip", "flipbit:50", "1.0", "8");
}

TEST(audit_sampled_catches_a_scaled_worker_within_bounded_tiles) {
    /* 1024 tiles, F renders about a third; each is audited with p = 0.1, so
     * F is caught after more than 100 unchecked tiles with p < 0.9^100 ~ 3e-5. */
    int n = run_faulty_farm("sampled", "scale:1e-6", "0.1", "2");
    CHECK(n >= 0 && n <= 100, "F delivered %d unchecked tiles before it was caught (bound 100)", n);
}

TEST(audit_honest_farm_is_never_flagged) {
    const char *ref = audit_reference(16);
    static const char *const tiles[] = {"4", "7", "8", "13", "16", "5", "32", "9"};
    for (size_t i = 0; i < sizeof tiles / sizeof tiles[0]; i++) {
        char img[256], cmd[1024], out[16384];
        snprintf(img, sizeof img, "%s", util_temp_path("audit-honest.pfm"));
        unlink(img);
        snprintf(cmd, sizeof cmd, "%s render " SCENE " --spp 16 --workers 3 --tile-size %s --audit %s -v -o %s",
                 harness_tessera(), tiles[i], i % 2 ? "1.0" : "0.5", img);
        int st = util_run(cmd, out, sizeof out);
        CHECK(st == 0, "%s failed (%d): %s", cmd, st, out);
        CHECK(!strstr(out, "disagree") && !strstr(out, "quarantined for") && !strstr(out, "QUARANTINED") &&
                  strstr(out, " 0 mismatches, 0 workers quarantined"),
              "an honest farm was flagged: %s", out);
        CHECK(util_same_file(img, ref), "%s: image differs from the single-process one", cmd);
    }
}

TEST(audit_needs_two_workers) {
    char cmd[1024], out[4096];
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 1 --audit 0.1 -o %s", harness_tessera(),
             util_temp_path("audit-one.pfm"));
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 2 && strstr(out, "--audit needs two workers"), "expected a usage error, got %d: %s", st, out);
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 3 --audit 1.5 -o %s", harness_tessera(),
             util_temp_path("audit-one.pfm"));
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 2, "--audit 1.5 accepted (%d): %s", st, out);
}

/* The job service (tessera-coordinator --audit 1.0): F is quarantined, the
 * fetched image is the single-process one, `tessera workers` says so. */
TEST(audit_service_quarantines_and_tessera_workers_shows_it) {
    char dir[256], log[256], addr[64], coord[4096], cmd[1024], out[8192], img[256], wlog[3][256];
    snprintf(dir, sizeof dir, "%s", util_temp_path("audit-svc"));
    snprintf(log, sizeof log, "%s", util_temp_path("audit-svc.log"));
    snprintf(img, sizeof img, "%s", util_temp_path("audit-svc.pfm"));
    unlink(log);
    int port = util_free_port();
    snprintf(addr, sizeof addr, "127.0.0.1:%d", port);
    snprintf(coord, sizeof coord, "%s", util_bin("tessera-coordinator"));
    const char *argv[] = {coord, "--listen", addr, "--data-dir", dir, "--audit", "1.0", NULL};
    pid_t svc = util_spawn(argv, log);
    CHECK(util_wait_for_text(log, "listening on", LONG) == 0, "coordinator did not start; log %s", log);
    static const char *const names[] = {"A", "B", "F"};
    pid_t w[3];
    for (int i = 0; i < 3; i++) {
        char lname[64];
        snprintf(lname, sizeof lname, "audit-svc-%s.log", names[i]);
        snprintf(wlog[i], sizeof wlog[i], "%s", util_temp_path(lname));
        w[i] = start_worker(wlog[i], port, names[i], i == 2 ? "scale:1e-6" : NULL);
    }
    for (int i = 0; i < 3; i++) /* all three in before the job: F surely gets tiles */
        CHECK(util_wait_for_text(wlog[i], "joined the farm", LONG) == 0, "%s never joined; log %s", names[i], wlog[i]);
    snprintf(cmd, sizeof cmd, "TESSERA_COORDINATOR=%s %s submit " SCENE " --tile-size 8 --wait -o %s", addr,
             harness_tessera(), img);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 0, "submit --wait failed (%d): %s; log %s", st, out, log);
    CHECK(util_same_file(img, audit_reference(64)), "the fetched image differs from the single-process one; log %s",
          log);
    snprintf(cmd, sizeof cmd, "TESSERA_COORDINATOR=%s %s workers", addr, harness_tessera());
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "QUARANTINED in 1 jobs") && util_file_count(log, "worker F (127.0.0.1:"),
          "F not shown as quarantined (%d): %s; log %s", st, out, log);
    for (int i = 0; i < 3; i++) {
        kill(w[i], SIGTERM);
        util_wait(w[i], LONG, NULL);
    }
    kill(svc, SIGTERM);
    CHECK(util_wait(svc, LONG, NULL) == 0, "coordinator did not exit cleanly; log %s", log);
}
