/* test_blocklist.c - the per-job blocklist (coordinator/farm_block.c) end
 * to end: a real job service, an honest worker and one made to crash on
 * every tile it starts (TESSERA_TEST_FAULT=crash, worker/pool.c), started
 * again by the test each time it dies, as a supervisor would.
 *
 * Checked: after three crashes the worker is blocklisted for the job
 * (logged with the evidence, shown by `tessera workers`); it gets none of
 * the job's tiles until the retry time is over, then gets work again (and,
 * crashing again, is blocklisted again for twice as long); the job
 * finishes with the honest worker and its image is the single-process one;
 * the honest worker is never blocklisted. */
#include <signal.h>
#include <stdio.h>
#include <sys/wait.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"
#include "util.h"

#define SCENE "tests/scenes/cornell-small.json"
#define LONG 120.0 /* seconds: only hit when something is broken */
#define RETRY "3"  /* --blocklist-retry: long enough to see, short enough to wait for */

/* Start the crashing worker F; its log is appended to flog. */
static pid_t start_crasher(const char *addr, const char *flog) {
    const char *argv[] = {util_bin("tessera-worker"), "--connect", addr, "--threads", "1", "--name", "F",
                          "--retry-max", "1", NULL};
    const char *env[] = {"TESSERA_TEST_FAULT=crash", NULL};
    return util_spawn_env(argv, flog, env);
}

/* Lines of the log saying worker F left. */
static int count_departures(const char *log) {
    FILE *f = fopen(log, "r");
    char line[2048];
    int n = 0;
    while (f && fgets(line, sizeof line, f)) n += strstr(line, "worker F (") && strstr(line, ") left: ");
    if (f) fclose(f);
    return n;
}

/* Every "is blocklisted" line of the log names worker F. */
static int only_f_blocklisted(const char *log) {
    FILE *f = fopen(log, "r");
    char line[2048];
    int ok = f != NULL;
    while (f && fgets(line, sizeof line, f))
        if (strstr(line, "is blocklisted") && !strstr(line, "worker F (")) ok = 0;
    if (f) fclose(f);
    return ok;
}

TEST(blocklist_crashing_worker_waits_then_retries_and_the_job_finishes) {
    char dir[256], log[256], alog[256], flog[256], hold[256], hold_env[300], addr[64], coord[4096], out[8192];
    snprintf(dir, sizeof dir, "%s", util_temp_path("block-svc"));
    snprintf(log, sizeof log, "%s", util_temp_path("block-svc.log"));
    snprintf(alog, sizeof alog, "%s", util_temp_path("block-A.log"));
    snprintf(flog, sizeof flog, "%s", util_temp_path("block-F.log"));
    snprintf(hold, sizeof hold, "%s", util_temp_path("block.hold"));
    unlink(log);
    unlink(flog);
    snprintf(addr, sizeof addr, "127.0.0.1:%d", util_free_port());
    snprintf(coord, sizeof coord, "%s", util_bin("tessera-coordinator"));
    const char *argv[] = {coord, "--listen", addr, "--data-dir", dir, "--audit", "0", "--blocklist-retry", RETRY,
                          NULL};
    pid_t svc = util_spawn(argv, log);
    CHECK(util_wait_for_text(log, "listening on", LONG) == 0, "coordinator did not start; log %s", log);
    /* A keeps its first tile while the hold file exists: the job cannot end
     * before F has been blocklisted twice. */
    util_touch(hold);
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold);
    const char *aargv[] = {util_bin("tessera-worker"), "--connect", addr, "--threads", "1", "--name", "A",
                           "--retry-max", "1", NULL};
    const char *aenv[] = {hold_env, NULL};
    pid_t a = util_spawn_env(aargv, alog, aenv);
    CHECK(util_wait_for_text(alog, "joined the farm", LONG) == 0, "A never joined; log %s", alog);
    int st = util_cli(addr, out, sizeof out, "submit " SCENE " --tile-size 8");
    CHECK(st == 0, "submit (%d): %s", st, out);
    CHECK(util_wait_for_text(alog, UTIL_HOLDING, LONG) == 0, "A never held a tile; log %s", alog);
    /* F crashes on every tile; start it again each time, as a supervisor
     * would, until it has been blocklisted twice. While it is connected and
     * blocklisted, `tessera workers` must say so. */
    int shown = 0, starts = 0;
    while (util_file_count(log, "is blocklisted for this job") < 2 && starts < 12) {
        pid_t f = start_crasher(addr, flog);
        starts++;
        int exited = 0;
        for (int i = 0; i < (int)(LONG * 20) && !exited; i++) {
            if (!shown && util_file_count(log, "is blocklisted for this job") == 1) {
                util_cli(addr, out, sizeof out, "workers");
                shown = strstr(out, "BLOCKLISTED in 1 jobs") != NULL;
            }
            int ws;
            exited = waitpid(f, &ws, WNOHANG) == f;
            if (!exited) util_sleep(0.05);
        }
        if (!exited) util_wait(f, 0, NULL); /* stuck: killed, and the checks below fail */
        /* F's exit can come before the coordinator has seen it: wait for
         * its departure (logged after any blocklisting) before counting. */
        for (int i = 0; i < (int)(LONG * 20) && util_file_count(log, "worker F (127.0.0.1:") &&
                        count_departures(log) < starts;
             i++)
            util_sleep(0.05);
    }
    CHECK(util_file_count(log, "is blocklisted for this job") == 2, "F not blocklisted twice in %d starts; log %s",
          starts, log);
    CHECK(only_f_blocklisted(log), "a worker other than F was blocklisted; log %s", log);
    CHECK(shown, "`tessera workers` never showed F as BLOCKLISTED while it waited: %s", out);
    CHECK(util_file_count(log, "may try again"), "the end of F's wait was not logged; log %s", log);
    CHECK(util_file_count(log, "for this job for " RETRY " s (3 failures; last: left ("),
          "first blocklisting: wrong wait or no evidence; log %s", log);
    CHECK(util_file_count(log, "for this job for 6 s (failed again after its wait; last: left ("),
          "second blocklisting (after the retry, twice as long) missing; log %s", log);
    CHECK(util_file_count(flog, "test fault crash: exiting on tile") == starts,
          "F crashed %d times in %d starts: it got no work once", util_file_count(flog, "test fault crash"), starts);
    unlink(hold);
    CHECK(util_wait_for_text(log, "job 1 done (", LONG) == 0, "the job never finished without F; log %s", log);
    char img[256], args[512], ref[256], cmd[1024];
    snprintf(img, sizeof img, "%s", util_temp_path("block.pfm"));
    snprintf(args, sizeof args, "fetch 1 -o %s", img);
    st = util_cli(addr, out, sizeof out, args);
    snprintf(ref, sizeof ref, "%s", util_temp_path("block-ref.pfm"));
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 -o %s", harness_tessera(), ref);
    util_run(cmd, out, sizeof out);
    CHECK(st == 0 && util_same_file(img, ref), "image differs from the single-process one; log %s", log);
    kill(a, SIGTERM);
    util_wait(a, LONG, NULL);
    kill(svc, SIGTERM);
    CHECK(util_wait(svc, LONG, NULL) == 0, "coordinator did not exit cleanly; log %s", log);
}

/* A worker that answers "failed" for every tile (TESSERA_TEST_FAULT=fail)
 * is blocklisted after its third, with the reason as evidence, and the
 * render (tessera render --listen) finishes on the honest one. */
TEST(blocklist_failing_worker_and_the_render_finishes) {
    char clog[256], alog[256], flog[256], hold[256], hold_env[300], listen[64], img[256], ref[256], cmd[1024],
        out[4096];
    snprintf(clog, sizeof clog, "%s", util_temp_path("block-fail-coord.log"));
    snprintf(alog, sizeof alog, "%s", util_temp_path("block-fail-A.log"));
    snprintf(flog, sizeof flog, "%s", util_temp_path("block-fail-F.log"));
    snprintf(hold, sizeof hold, "%s", util_temp_path("block-fail.hold"));
    snprintf(img, sizeof img, "%s", util_temp_path("block-fail.pfm"));
    unlink(clog);
    snprintf(listen, sizeof listen, "127.0.0.1:%d", util_free_port());
    const char *argv[] = {harness_tessera(), "render", SCENE, "--tile-size", "8", "--no-progress", "-v", "-o", img,
                          "--listen", listen, "--audit", "0", "--blocklist-retry", "1000", NULL};
    pid_t coord = util_spawn(argv, clog);
    CHECK(util_wait_for_text(clog, "coordinator listening on", LONG) == 0, "coordinator did not start; log %s", clog);
    util_touch(hold); /* A keeps its first tile until F has failed three */
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold);
    const char *aargv[] = {util_bin("tessera-worker"), "--connect", listen, "--threads", "1", "--name", "A",
                           "--retry-max", "1", NULL};
    const char *aenv[] = {hold_env, NULL};
    pid_t a = util_spawn_env(aargv, alog, aenv);
    const char *fargv[] = {util_bin("tessera-worker"), "--connect", listen, "--threads", "1", "--name", "F",
                           "--retry-max", "1", NULL};
    const char *fenv[] = {"TESSERA_TEST_FAULT=fail", NULL};
    pid_t f = util_spawn_env(fargv, flog, fenv);
    CHECK(util_wait_for_text(clog, "is blocklisted for this job for 1000 s (3 failures; last: tile ", LONG) == 0,
          "F was not blocklisted after 3 failed tiles; log %s", clog);
    unlink(hold);
    int st = util_wait(coord, LONG, NULL);
    CHECK(st == 0, "coordinator exited with %d; log %s", st, clog);
    CHECK(only_f_blocklisted(clog) && util_file_count(clog, "test fault: tile ") >= 3 &&
              util_file_count(clog, "blocklist: 1 times a worker was blocklisted"),
          "blocklisting not logged as expected; log %s", clog);
    snprintf(ref, sizeof ref, "%s", util_temp_path("block-ref.pfm"));
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 -o %s", harness_tessera(), ref);
    util_run(cmd, out, sizeof out);
    CHECK(util_same_file(img, ref), "image differs from the single-process one; log %s", clog);
    pid_t ws[] = {a, f};
    for (int i = 0; i < 2; i++) {
        kill(ws[i], SIGTERM);
        util_wait(ws[i], LONG, NULL);
    }
}
