/* test_install.c - `make install`: the three programs land in
 * $(DESTDIR)$(PREFIX)/bin (PREFIX /usr/local by default), the coordinator
 * as a link to tessera, and the installed tessera finds the installed
 * worker: a local-farm render from there is the single-process image. */
#include <limits.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "harness.h"
#include "util.h"

#define SCENE "tests/scenes/cornell-small.json"

TEST(install_puts_the_programs_under_prefix) {
    char from[1024], dest[256], bin[512], cmd[4096], out[8192], path[1024], link[64];
    snprintf(from, sizeof from, "%.1000s", util_bin("tessera"));
    *strrchr(from, '/') = '\0';
    snprintf(dest, sizeof dest, "%s", util_temp_path("install-root"));
    /* The default prefix, without installing anything. */
    snprintf(cmd, sizeof cmd, "make -s --no-print-directory -n install INSTALL_FROM=%s DESTDIR=%s", from, dest);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "/usr/local/bin"), "make -n install (%d): %s", st, out);
    snprintf(cmd, sizeof cmd, "make -s --no-print-directory install INSTALL_FROM=%s DESTDIR=%s PREFIX=/opt/t", from,
             dest);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0, "%s (%d): %s", cmd, st, out);
    snprintf(bin, sizeof bin, "%s/opt/t/bin", dest);
    static const char *const progs[] = {"tessera", "tessera-worker"};
    for (int i = 0; i < 2; i++) {
        struct stat sb;
        snprintf(path, sizeof path, "%s/%s", bin, progs[i]);
        CHECK(stat(path, &sb) == 0 && S_ISREG(sb.st_mode) && (sb.st_mode & 0111), "%s is not an installed program",
              path);
        snprintf(cmd, sizeof cmd, "%.1000s/%s", from, progs[i]);
        CHECK(util_same_file(path, cmd), "%s differs from %s", path, cmd);
    }
    snprintf(path, sizeof path, "%s/tessera-coordinator", bin);
    ssize_t n = readlink(path, link, sizeof link - 1);
    if (n >= 0) link[n] = '\0';
    CHECK(n > 0 && strcmp(link, "tessera") == 0, "%s is not a link to tessera", path);
    snprintf(cmd, sizeof cmd, "%s --help", path);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "tessera-coordinator"), "%s --help (%d): %s", path, st, out);
    /* The installed tessera starts the installed worker (not the build's). */
    char img[256], ref[256];
    snprintf(img, sizeof img, "%s", util_temp_path("installed.pfm"));
    snprintf(ref, sizeof ref, "%s", util_temp_path("installed-ref.pfm"));
    snprintf(cmd, sizeof cmd, "env -u TESSERA_WORKER %s/tessera render " SCENE " --workers 2 --no-progress -o %s", bin,
             img);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0, "installed render (%d): %s", st, out);
    snprintf(cmd, sizeof cmd, "%s render " SCENE " --workers 0 --no-progress -o %s", harness_tessera(), ref);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && util_same_file(img, ref), "the installed farm's image differs (%d): %s", st, out);
    snprintf(cmd, sizeof cmd, "make -s --no-print-directory uninstall DESTDIR=%s PREFIX=/opt/t", dest);
    st = util_run(cmd, out, sizeof out);
    snprintf(path, sizeof path, "%s/tessera", bin);
    CHECK(st == 0 && access(path, F_OK) != 0, "make uninstall (%d): %s", st, out);
}
