/* test_cli.c - the command line's manners: the usual spellings of help and
 * version, one-line usage errors with a "did you mean", options that do not
 * apply refused rather than ignored. */
#include <limits.h>
#include <signal.h>
#include <stdlib.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

#include "harness.h"
#include "util.h"

/* Run `tessera ARGS` (stdout and stderr into out); returns the exit status. */
static int tessera(const char *args, char *out, size_t cap) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "%s %s 2>&1", harness_tessera(), args);
    return util_run(cmd, out, cap);
}

/* Number of lines in s. */
static int lines(const char *s) {
    int n = 0;
    for (; *s; s++) n += *s == '\n';
    return n;
}

TEST(cli_version_and_help_have_the_usual_spellings) {
    char out[8192];
    static const char *const versions[] = {"version", "--version", "-V"};
    for (int i = 0; i < 3; i++) {
        int rc = tessera(versions[i], out, sizeof out);
        CHECK(rc == 0 && strncmp(out, "tessera ", 8) == 0, "tessera %s (%d): %s", versions[i], rc, out);
    }
    static const char *const helps[] = {"help", "--help", "-h", "render --help", "tonemap -h", "compare --help",
                                        "coordinator --help"};
    for (int i = 0; i < 7; i++) {
        int rc = tessera(helps[i], out, sizeof out);
        CHECK(rc == 0 && strstr(out, "usage"), "tessera %s (%d): %s", helps[i], rc, out);
    }
    char cmd[600];
    snprintf(cmd, sizeof cmd, "%s-coordinator --version 2>&1", harness_tessera());
    CHECK(util_run(cmd, out, sizeof out) == 0 && strncmp(out, "tessera ", 8) == 0, "coordinator --version: %s", out);
}

TEST(cli_usage_errors_are_one_line_with_did_you_mean) {
    char out[8192];
    int rc = tessera("rendr scenes/cornell-box.json", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "unknown command \"rendr\" (did you mean \"render\"?)") && lines(out) == 2,
          "rendr (%d): %s", rc, out);
    rc = tessera("render scenes/cornell-box.json --sppp 4", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "unknown option --sppp (did you mean --spp?)") &&
              strstr(out, "see tessera render --help") && lines(out) == 2,
          "--sppp (%d): %s", rc, out);
    rc = tessera("render scenes/cornell-box.json --seed -1", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "--seed: expected an integer"), "--seed -1 (%d): %s", rc, out);
    rc = tessera("render", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "expected exactly one scene file") && lines(out) == 2, "no scene (%d): %s", rc, out);
}

TEST(cli_options_that_do_not_apply_are_refused) {
    char out[8192];
    int rc = tessera("render scenes/cornell-box.json --png16 -o x.jpg", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "--png16 applies to .png output"), "--png16 with .jpg (%d): %s", rc, out);
    rc = tessera("render scenes/cornell-box.json --quality 50 -o x.png", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "--quality applies to .jpg output"), "--quality with .png (%d): %s", rc, out);
    rc = tessera("render scenes/cornell-box.json --exr-half -o x.pfm", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "apply to .exr output"), "--exr-half with .pfm (%d): %s", rc, out);
}

TEST(cli_tonemap_writes_16_bit_png_like_render) {
    char out[8192], pfm[512], png[512], args[1200];
    snprintf(pfm, sizeof pfm, "%s", util_temp_path("cli-tm.pfm"));
    snprintf(png, sizeof png, "%s", util_temp_path("cli-tm.png"));
    snprintf(args, sizeof args,
             "render tests/scenes/cornell-small.json --workers 0 --spp 2 --width 16 --height 16 -o %s", pfm);
    CHECK(tessera(args, out, sizeof out) == 0, "render: %s", out);
    snprintf(args, sizeof args, "tonemap %s -o %s --png16", pfm, png);
    CHECK(tessera(args, out, sizeof out) == 0, "tonemap --png16: %s", out);
    FILE *f = fopen(png, "rb");
    unsigned char head[26] = {0};
    size_t n = f ? fread(head, 1, sizeof head, f) : 0;
    if (f) fclose(f);
    CHECK(n == 26 && head[24] == 16, "%s is not a 16-bit PNG (bit depth %d)", png, n == 26 ? head[24] : -1);
}

TEST(cli_client_commands_have_their_own_help_and_one_line_errors) {
    char out[8192];
    static const char *const cmds[][2] = {{"status --help", "usage: tessera status"},
                                          {"workers --help", "usage: tessera workers"},
                                          {"cancel --help", "usage: tessera cancel"},
                                          {"fetch -h", "usage: tessera fetch"},
                                          {"submit --help", "usage: tessera submit"}};
    for (int i = 0; i < 5; i++) {
        int rc = tessera(cmds[i][0], out, sizeof out);
        CHECK(rc == 0 && strncmp(out, cmds[i][1], strlen(cmds[i][1])) == 0, "tessera %s (%d): %s", cmds[i][0], rc, out);
    }
    int rc = tessera("status --jsn", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "tessera status: unknown option --jsn (did you mean --json?)") &&
              strstr(out, "see tessera status --help") && lines(out) == 2,
          "status --jsn (%d): %s", rc, out);
    rc = tessera("fetch 3", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "tessera fetch: -o OUT is required") && lines(out) == 2, "fetch 3 (%d): %s", rc, out);
    rc = tessera("cancel", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "expected one job number") && lines(out) == 2, "cancel (%d): %s", rc, out);
    rc = tessera("workers --wait", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "unknown option --wait") && lines(out) == 2, "workers --wait (%d): %s", rc, out);
    rc = tessera("fetch 3 -o x.jpg --png16", out, sizeof out);
    CHECK(rc == 2 && strstr(out, "--png16 applies to .png output"), "fetch --png16 with .jpg (%d): %s", rc, out);
}

TEST(cli_worker_usage_errors_are_one_line) {
    char out[8192], cmd[4096];
    snprintf(cmd, sizeof cmd, "%s --conect 127.0.0.1:1 2>&1", util_bin("tessera-worker"));
    int rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 2 && strstr(out, "unknown option --conect (did you mean --connect?)") && lines(out) == 2,
          "tessera-worker --conect (%d): %s", rc, out);
    snprintf(cmd, sizeof cmd, "%s 2>&1", util_bin("tessera-worker"));
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 2 && strstr(out, "--connect HOST:PORT is required") && lines(out) == 2, "no --connect (%d): %s", rc, out);
    snprintf(cmd, sizeof cmd, "%s -V 2>&1", util_bin("tessera-worker"));
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 0 && strncmp(out, "tessera-worker ", 15) == 0, "tessera-worker -V (%d): %s", rc, out);
}

/* A 64x32 scene: the Cornell box of tests/scenes, wider than tall. */
static const char *wide_scene(void) {
    static char path[512];
    char out[65536];
    util_run("sed 's/\"height\": 64/\"height\": 32/' tests/scenes/cornell-small.json", out, sizeof out);
    snprintf(path, sizeof path, "%s", util_write_temp("wide.json", out));
    return path;
}

/* Width and height of a PFM file, or 0x0. */
static void pfm_size(const char *path, int *w, int *h) {
    FILE *f = fopen(path, "rb");
    *w = *h = 0;
    if (f && fscanf(f, "PF %d %d", w, h) != 2) *w = *h = 0;
    if (f) fclose(f);
}

TEST(cli_one_side_keeps_the_aspect_ratio) {
    char out[8192], args[2048], pfm[512];
    int w, h;
    snprintf(pfm, sizeof pfm, "%s", util_temp_path("cli-aspect.pfm"));
    snprintf(args, sizeof args, "render %s --workers 0 --spp 1 --width 16 -v -o %s", wide_scene(), pfm);
    int rc = tessera(args, out, sizeof out);
    pfm_size(pfm, &w, &h);
    CHECK(rc == 0 && w == 16 && h == 8, "--width 16 of a 64x32 scene gave %dx%d (%d): %s", w, h, rc, out);
    CHECK(strstr(out, "size: 16x8: --width given alone, so the height keeps the scene's aspect ratio"),
          "-v does not say the height was derived: %s", out);
    snprintf(args, sizeof args, "render %s --workers 0 --spp 1 --height 8 -o %s", wide_scene(), pfm);
    rc = tessera(args, out, sizeof out);
    pfm_size(pfm, &w, &h);
    CHECK(rc == 0 && w == 16 && h == 8, "--height 8 of a 64x32 scene gave %dx%d (%d): %s", w, h, rc, out);
    snprintf(args, sizeof args, "render %s --workers 0 --spp 1 --width 10 --height 30 -o %s", wide_scene(), pfm);
    rc = tessera(args, out, sizeof out);
    pfm_size(pfm, &w, &h);
    CHECK(rc == 0 && w == 10 && h == 30, "both sides given: %dx%d (%d): %s", w, h, rc, out);
}

TEST(cli_render_reads_the_scene_from_stdin_and_quiet_prints_one_line) {
    char out[8192], cmd[4096], pfm[512];
    int w, h;
    snprintf(pfm, sizeof pfm, "%s", util_temp_path("cli-stdin.pfm"));
    snprintf(cmd, sizeof cmd, "%s render - --spp 1 --workers 1 -q -o %s < %s 2>&1", harness_tessera(), pfm,
             wide_scene());
    int rc = util_run(cmd, out, sizeof out);
    pfm_size(pfm, &w, &h);
    CHECK(rc == 0 && w == 64 && h == 32, "render - from stdin (%d, %dx%d): %s", rc, w, h, out);
    CHECK(lines(out) == 1 && strncmp(out, "rendered <stdin>: ", 18) == 0, "-q printed more than the summary: %s", out);
    snprintf(cmd, sizeof cmd, "sed 's/\"width\"/\"widht\"/' %s | %s render - --workers 0 -o %s 2>&1", wide_scene(),
             harness_tessera(), pfm);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 1 && strstr(out, "<stdin>: render.widht: unknown field (did you mean render.width?)"),
          "a misspelt field from stdin (%d): %s", rc, out);
}

TEST(cli_progress_is_plain_lines_when_stderr_is_not_a_terminal) {
    char out[16384], cmd[4096], pfm[512];
    snprintf(pfm, sizeof pfm, "%s", util_temp_path("cli-progress.pfm"));
    static const char *const modes[] = {"--workers 0 --threads 1", "--workers 1"};
    for (int i = 0; i < 2; i++) {
        snprintf(cmd, sizeof cmd,
                 "TESSERA_PROGRESS_SECONDS=0.001 %s render tests/scenes/cornell-small.json --spp 2 --tile-size 8 %s "
                 "-o %s 2>&1",
                 harness_tessera(), modes[i], pfm);
        int rc = util_run(cmd, out, sizeof out);
        CHECK(rc == 0 && strstr(out, "progress: ") && strstr(out, "progress: 64/64 tiles (100%)") && !strchr(out, '\r'),
              "%s: no plain progress lines (%d): %s", modes[i], rc, out);
        snprintf(cmd, sizeof cmd,
                 "TESSERA_PROGRESS_SECONDS=0.001 %s render tests/scenes/cornell-small.json --spp 2 --tile-size 8 %s "
                 "-q -o %s 2>&1",
                 harness_tessera(), modes[i], pfm);
        rc = util_run(cmd, out, sizeof out);
        CHECK(rc == 0 && !strstr(out, "progress: ") && lines(out) == 1, "%s -q (%d): %s", modes[i], rc, out);
    }
}

TEST(cli_sigint_stops_a_farm_render_with_130_and_no_image) {
    char hold[512], log[512], png[512], bin[4096], hold_env[600];
    snprintf(hold, sizeof hold, "%s", util_temp_path("cli-sigint.hold"));
    snprintf(log, sizeof log, "%s", util_temp_path("cli-sigint.log"));
    snprintf(png, sizeof png, "%s", util_temp_path("cli-sigint.png"));
    snprintf(bin, sizeof bin, "%s", harness_tessera());
    snprintf(hold_env, sizeof hold_env, "TESSERA_TEST_HOLD_FILE=%s", hold);
    unlink(png);
    util_touch(hold);
    const char *argv[] = {bin, "render", "tests/scenes/cornell-small.json", "--workers", "2", "-o", png, NULL};
    const char *env[] = {hold_env, NULL};
    pid_t pid = util_spawn_env(argv, log, env);
    CHECK(util_wait_for_text(log, UTIL_HOLDING, 120) == 0, "no tile was held; log %s", log);
    kill(pid, SIGINT);
    int st = util_wait(pid, 60, NULL);
    unlink(hold);
    CHECK(st == 130, "render exited with %d after SIGINT, not 130; log %s", st, log);
    CHECK(util_file_count(log, "interrupted by SIGINT: the workers were stopped; no image written"),
          "no message saying what happened; log %s", log);
    CHECK(!util_file_count(log, "killing them") && !util_file_count(log, "starting local-"),
          "the workers did not stop cleanly; log %s", log);
    CHECK(access(png, F_OK) != 0, "%s was written after SIGINT", png);
}

/* An image with nowhere to go is refused before the render; one that
 * cannot be written at the end (here: OUT is a folder, so the final rename
 * fails) is kept as a linear EXR in $TMPDIR, the same bytes a render to
 * .exr gives, and the command says where and fails. */
TEST(cli_render_checks_the_output_first_and_keeps_an_unsaved_image) {
    char out[8192], cmd[4096], dir[512], exr[600], kept[700];
    snprintf(dir, sizeof dir, "%s", util_temp_path("cli-unsaved"));
    snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir -p %s/rescue %s/blocked.exr/inside", dir, dir, dir);
    CHECK(util_run(cmd, out, sizeof out) == 0, "setup: %s", out);
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json --spp 2 --workers 1 -o %s/missing/x.png 2>&1",
             harness_tessera(), dir);
    int rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 1 && strstr(out, "/missing/x.png: cannot write: No such file or directory (nothing rendered)") &&
              !strstr(out, "progress"),
          "an output folder that does not exist (%d): %s", rc, out);
    snprintf(cmd, sizeof cmd, "TMPDIR=%s/rescue %s render tests/scenes/cornell-small.json --spp 2 --workers 1 -o %s/x.bmp "
             "2>&1", dir, harness_tessera(), dir);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 1 && strstr(out, "x.bmp: unknown image format \"bmp\"") && strstr(out, "(nothing rendered)") &&
              !strstr(out, "progress"),
          "an unknown output format (%d): %s", rc, out);
    snprintf(cmd, sizeof cmd,
             "TMPDIR=%s/rescue %s render tests/scenes/cornell-small.json --spp 2 --workers 1 -o %s/blocked.exr 2>&1",
             dir, harness_tessera(), dir);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 1 && strstr(out, "blocked.exr: cannot write: ") && strstr(out, "the render is kept in "),
          "an image that cannot be saved (%d): %s", rc, out);
    snprintf(cmd, sizeof cmd, "ls %s/rescue/blocked-unsaved-*.exr", dir);
    CHECK(util_run(cmd, kept, sizeof kept) == 0, "no kept image in $TMPDIR: %s", kept);
    kept[strcspn(kept, "\n")] = 0;
    snprintf(exr, sizeof exr, "%s/normal.exr", dir);
    snprintf(cmd, sizeof cmd, "%s render tests/scenes/cornell-small.json --spp 2 --workers 1 -q -o %s 2>&1",
             harness_tessera(), exr);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 0 && util_same_file(kept, exr), "the kept image %s differs from a render to .exr (%d): %s", kept, rc,
          out);
}

/* A scene may come through a pipe (the shell's <(...), a FIFO): read to its
 * end like stdin, its meshes relative to the current folder. A mesh that
 * is a FIFO is refused at once, not waited on. */
TEST(cli_render_reads_a_scene_from_a_pipe_and_refuses_a_fifo_mesh) {
    char out[8192], cmd[8192], dir[512], a[600], b[600], bin[PATH_MAX];
    CHECK(realpath(harness_tessera(), bin) != NULL, "cannot resolve %s", harness_tessera());
    snprintf(dir, sizeof dir, "%s", util_temp_path("cli-pipe"));
    snprintf(a, sizeof a, "%s/file.pfm", dir);
    snprintf(b, sizeof b, "%s/pipe.pfm", dir);
    snprintf(cmd, sizeof cmd, "rm -rf %s && mkdir -p %s/meshes && mkfifo %s/meshes/fifo.obj", dir, dir, dir);
    CHECK(util_run(cmd, out, sizeof out) == 0, "setup: %s", out);
    snprintf(cmd, sizeof cmd, "cd scenes && %s render features.json --spp 1 --width 24 --workers 0 -q -o %s 2>&1", bin, a);
    int rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 0, "features.json (%d): %s", rc, out);
    snprintf(cmd, sizeof cmd,
             "cd scenes && bash -c '%s render <(cat features.json) --spp 1 --width 24 --workers 0 -q -o %s' 2>&1", bin, b);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 0 && util_same_file(a, b), "the scene through <(...) (%d): %s", rc, out);
    snprintf(cmd, sizeof cmd,
             "sed 's|meshes/tetrahedron.obj|meshes/fifo.obj|' scenes/features.json > %s/f.json && timeout 20 %s render "
             "%s/f.json --spp 1 --width 24 --workers 0 -q -o %s 2>&1",
             dir, harness_tessera(), dir, b);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 1 && strstr(out, "shapes[4].file: ") && strstr(out, "meshes/fifo.obj: not a regular file"),
          "a FIFO as a mesh (%d): %s", rc, out);
}
