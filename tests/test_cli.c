/* test_cli.c - the command line's manners: the usual spellings of help and
 * version, one-line usage errors with a "did you mean", options that do not
 * apply refused rather than ignored. */
#include <stdio.h>
#include <string.h>

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
