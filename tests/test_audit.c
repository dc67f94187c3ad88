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

/* A tessera-worker NAME on 127.0.0.1:port with TESSERA_TEST_FAULT=fault
 * (NULL: honest) and, if hold is not NULL, keeping its finished tiles
 * while that file exists (util.h). */
static pid_t start_worker_held(const char *log, int port, const char *name, const char *fault, const char *hold) {
    char connect[64], env[128], hold_env[300];
    snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
    snprintf(env, sizeof env, "TESSERA_TEST_FAULT=%s", fault ? fault : "");
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold ? hold : "");
    const char *argv[] = {util_bin("tessera-worker"), "--connect", connect, "--threads", "1", "--name", name,
                          "--retry-max", "1", NULL};
    const char *envv[] = {env, hold_env, NULL};
    return util_spawn_env(argv, log, envv);
}

static pid_t start_worker(const char *log, int port, const char *name, const char *fault) {
    return start_worker_held(log, port, name, fault, NULL);
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
    /* The honest ones first: F's tiles can be checked from the start. They
     * keep their first tiles until F has joined (else, on a fast or a busy
     * machine, they may finish the job before F is in). */
    char hold[256];
    snprintf(name, sizeof name, "audit-%s.hold", tag);
    snprintf(hold, sizeof hold, "%s", util_temp_path(name));
    util_touch(hold);
    pid_t a = start_worker_held(alog, port, "A", NULL, hold), b = start_worker_held(blog, port, "B", NULL, hold);
    CHECK(util_wait_for_text(clog, "worker A (", LONG) == 0 && util_wait_for_text(clog, "worker B (", LONG) == 0,
          "A and B never joined; log %s", clog);
    pid_t f = start_worker(flog, port, "F", fault);
    CHECK(util_wait_for_text(clog, "worker F (", LONG) == 0, "F never joined; log %s", clog);
    unlink(hold);
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

/* One local worker: nothing to compare with, so no audit, and the command
 * says why (also when the audit is the default one, with -v). */
TEST(audit_one_worker_renders_and_says_why_no_audit) {
    char cmd[1024], out[4096], img[256];
    snprintf(img, sizeof img, "%s", util_temp_path("audit-one.pfm"));
    unlink(img);
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 1 --audit 0.1 --no-progress -o %s", harness_tessera(),
             img);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "no audit: one worker leaves no second one"), "expected a note, got %d: %s", st, out);
    CHECK(util_same_file(img, audit_reference(64)), "one worker: image differs from the single-process one");
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 1 -v --no-progress -o %s", harness_tessera(), img);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "no audit:"), "the default audit with one worker: no note with -v (%d): %s", st, out);
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 3 --audit 1.5 -o %s", harness_tessera(), img);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 2, "--audit 1.5 accepted (%d): %s", st, out);
}

/* A coordinator that listens (tessera render --listen) with --audit 1.0:
 * the workers in `fault` ("" for an honest one) join; returns the
 * coordinator's exit status, its log in clog. */
static int run_listen_farm(const char *tag, const char *const *faults, int n, char *clog, size_t clog_len,
                           const char *img) {
    char listen[64], name[96], wlog[4][256];
    snprintf(name, sizeof name, "audit-%s-coord.log", tag);
    snprintf(clog, clog_len, "%s", util_temp_path(name));
    unlink(clog);
    unlink(img);
    int port = util_free_port();
    snprintf(listen, sizeof listen, "127.0.0.1:%d", port);
    const char *argv[] = {harness_tessera(), "render", SCENE, "--tile-size", "16", "--no-progress", "-v", "-o", img,
                          "--listen", listen, "--audit", "1.0", NULL};
    pid_t coord = util_spawn(argv, clog);
    CHECK(util_wait_for_text(clog, "coordinator listening on", LONG) == 0, "coordinator did not start; log %s", clog);
    pid_t w[4];
    char hold[256], hold_env[300], connect[64];
    snprintf(name, sizeof name, "audit-%s.hold", tag);
    snprintf(hold, sizeof hold, "%s", util_temp_path(name));
    util_touch(hold); /* nobody returns a tile before all have joined */
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold);
    snprintf(connect, sizeof connect, "127.0.0.1:%d", port);
    for (int i = 0; i < n && i < 4; i++) {
        char wname[8] = {(char)('A' + i), 0}, fault_env[128];
        snprintf(name, sizeof name, "audit-%s-%s.log", tag, wname);
        snprintf(wlog[i], sizeof wlog[i], "%s", util_temp_path(name));
        snprintf(fault_env, sizeof fault_env, "TESSERA_TEST_FAULT=%s", faults[i]);
        const char *wargv[] = {util_bin("tessera-worker"), "--connect", connect, "--threads", "1", "--name", wname,
                               "--retry-max", "1", NULL};
        const char *env[] = {hold_env, fault_env, NULL};
        w[i] = util_spawn_env(wargv, wlog[i], env);
    }
    for (int i = 0; i < n && i < 4; i++) {
        char joined[32];
        snprintf(joined, sizeof joined, "worker %c (", 'A' + i);
        CHECK(util_wait_for_text(clog, joined, LONG) == 0, "%s never joined; log %s", joined, clog);
    }
    unlink(hold);
    int st = util_wait(coord, LONG, NULL);
    for (int i = 0; i < n && i < 4; i++) {
        kill(w[i], SIGTERM);
        util_wait(w[i], LONG, NULL);
    }
    return st;
}

/* One remote worker: its audited tiles cannot be checked; the job still
 * finishes, with a log line saying they were taken unchecked. */
TEST(audit_one_remote_worker_finishes_unchecked) {
    char clog[256], img[256];
    snprintf(img, sizeof img, "%s", util_temp_path("audit-solo.pfm"));
    static const char *const faults[] = {""};
    int st = run_listen_farm("solo", faults, 1, clog, sizeof clog, img);
    CHECK(st == 0, "coordinator exited with %d; log %s", st, clog);
    CHECK(util_file_count(clog, "no other worker is connected to render audited tile ") == 1 &&
              util_file_count(clog, " 0 tiles checked by two workers, 0 mismatches, 0 workers quarantined, 16 accepted "
                                    "unchecked (no second worker)"),
          "no line saying the audited tiles were taken unchecked, or not all 16; log %s", clog);
    CHECK(util_same_file(img, audit_reference(64)), "one remote worker: image differs; log %s", clog);
}

/* Two workers that disagree and no third to decide: the job fails with a
 * message saying so (it does not hang). */
TEST(audit_mismatch_without_a_third_worker_fails_the_job) {
    char clog[256], img[256];
    snprintf(img, sizeof img, "%s", util_temp_path("audit-pair.pfm"));
    static const char *const faults[] = {"", "scale:1e-6"};
    int st = run_listen_farm("pair", faults, 2, clog, sizeof clog, img);
    CHECK(st != 0 && st != -1, "coordinator exited with %d; log %s", st, clog);
    CHECK(util_file_count(clog, "returned different pixels and no third worker is connected to decide"),
          "no message saying a third worker is needed; log %s", clog);
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

/* tiles_done of job 1 by `tessera status 1 --json`, or -1. */
static int audit_tiles_done(const char *addr) {
    char out[8192];
    int done = -1;
    util_cli(addr, out, sizeof out, "status 1 --json");
    const char *p = strstr(out, "\"tiles_done\":");
    if (p) sscanf(p, "\"tiles_done\":\t%d", &done);
    return done;
}

/* The job service with --audit 1.0 is killed (kill -9) while results wait
 * for their audit copy, and restarted on the same data dir: the tiles that
 * were journaled are kept, the results that were waiting are rendered
 * again (two workers each), and the image is the single-process one. */
TEST(audit_service_restart_with_audits_pending) {
    char dir[256], log[256], addr[64], coord[4096], hold[256], hold_env[300], after_env[2][64], wlog[2][256];
    snprintf(dir, sizeof dir, "%s", util_temp_path("audit-restart"));
    snprintf(log, sizeof log, "%s", util_temp_path("audit-restart.log"));
    snprintf(hold, sizeof hold, "%s", util_temp_path("audit-restart.hold"));
    unlink(log);
    util_touch(hold);
    snprintf(addr, sizeof addr, "127.0.0.1:%d", util_free_port());
    snprintf(coord, sizeof coord, "%s", util_bin("tessera-coordinator"));
    const char *argv[] = {coord, "--listen", addr, "--data-dir", dir, "--audit", "1.0", "--heartbeat", "0.2",
                          "--worker-timeout", "2", NULL};
    pid_t svc = util_spawn(argv, log);
    CHECK(util_wait_for_text(log, "listening on", LONG) == 0, "coordinator did not start; log %s", log);
    /* A returns 10 tiles, B 4, then each keeps what it renders: at most 4
     * tiles can have both results, so at least 6 results wait for a copy. */
    static const char *const names[] = {"A", "B"};
    static const int after[] = {10, 4};
    pid_t w[2];
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold);
    for (int i = 0; i < 2; i++) {
        char lname[64];
        snprintf(lname, sizeof lname, "audit-restart-%s.log", names[i]);
        snprintf(wlog[i], sizeof wlog[i], "%s", util_temp_path(lname));
        snprintf(after_env[i], sizeof after_env[i], "TESSERA_TEST_HOLD_AFTER=%d", after[i]);
        const char *wargv[] = {util_bin("tessera-worker"), "--connect", addr, "--threads", "1", "--name", names[i],
                               "--retry-max", "1000", NULL};
        const char *env[] = {hold_env, after_env[i], NULL};
        w[i] = util_spawn_env(wargv, wlog[i], env);
    }
    for (int i = 0; i < 2; i++)
        CHECK(util_wait_for_text(wlog[i], "joined the farm", LONG) == 0, "%s never joined; log %s", names[i], wlog[i]);
    char out[8192], img[256];
    int st = util_cli(addr, out, sizeof out, "submit " SCENE " --tile-size 8");
    CHECK(st == 0, "submit (%d): %s", st, out);
    for (int i = 0; i < 2; i++)
        CHECK(util_wait_for_text(wlog[i], UTIL_HOLDING, LONG) == 0, "%s never held a tile; log %s", names[i], wlog[i]);
    int done = 0;
    for (int i = 0; i < (int)(LONG * 20) && done < 1; i++) { /* at least one tile agreed on and journaled */
        done = audit_tiles_done(addr);
        if (done < 1) util_sleep(0.05);
    }
    CHECK(done >= 1 && done <= 4, "%d tiles done before the kill; 1 to 4 expected", done);
    kill(svc, SIGKILL);
    util_wait(svc, LONG, NULL);
    unlink(hold);
    svc = util_spawn(argv, log);
    CHECK(util_wait_for_text(log, "job 1 done (", LONG) == 0, "resumed job never finished; log %s", log);
    int resumed, again, rendered;
    util_resume_counts(log, &resumed, &again, &rendered);
    CHECK(resumed >= 1 && again == resumed && resumed + rendered == 64,
          "resumed %d, then %d from the journal and %d rendered: 64 in all expected; log %s", resumed, again, rendered,
          log);
    CHECK(!util_file_count(log, "disagree") && !util_file_count(log, "quarantined for"), "honest workers flagged; log %s",
          log);
    snprintf(img, sizeof img, "%s", util_temp_path("audit-restart.pfm"));
    char args[512];
    snprintf(args, sizeof args, "fetch 1 -o %s", img);
    st = util_cli(addr, out, sizeof out, args);
    CHECK(st == 0 && util_same_file(img, audit_reference(64)), "image after a restart differs (%d): %s; log %s", st,
          out, log);
    for (int i = 0; i < 2; i++) {
        kill(w[i], SIGTERM);
        util_wait(w[i], LONG, NULL);
    }
    kill(svc, SIGTERM);
    CHECK(util_wait(svc, LONG, NULL) == 0, "coordinator did not exit cleanly; log %s", log);
}
