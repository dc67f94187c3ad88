/* test_fileio.c - the one atomic write: replaces whole, leaves no temporary,
 * names the file when it cannot write. */
#include <dirent.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fileio.h"
#include "harness.h"
#include "util.h"

/* Number of entries in dir other than . and .. */
static int entries(const char *dir) {
    DIR *d = opendir(dir);
    int n = 0;
    for (struct dirent *e; d && (e = readdir(d));)
        if (strcmp(e->d_name, ".") && strcmp(e->d_name, "..")) n++;
    if (d) closedir(d);
    return n;
}

TEST(fileio_atomic_write_replaces_whole_and_leaves_no_temporary) {
    char dir[512], path[600], err[700];
    snprintf(dir, sizeof dir, "%s", util_temp_path("atomic"));
    mkdir(dir, 0755);
    snprintf(path, sizeof path, "%s/a.txt", dir);
    CHECK(file_write_atomic(path, "first version", 13, err, sizeof err) == 0, "write: %s", err);
    CHECK(file_write_atomic(path, "second", 6, err, sizeof err) == 0, "rewrite: %s", err);
    size_t len;
    char *text = file_read_all(path, 1 << 20, &len, err, sizeof err);
    CHECK(text && len == 6 && strcmp(text, "second") == 0, "read back \"%s\"", text ? text : err);
    free(text);
    CHECK(entries(dir) == 1, "%d files in %s: a temporary was left behind", entries(dir), dir);
    struct stat st;
    mode_t mask = umask(0);
    umask(mask);
    CHECK(stat(path, &st) == 0 && (st.st_mode & 0777) == (0666 & ~mask), "mode %o, expected %o", st.st_mode & 0777,
          0666 & ~mask);
}

TEST(fileio_atomic_write_names_the_file_it_cannot_write) {
    char err[700] = "";
    const char *path = "/nonexistent-folder-tessera/x.bin";
    CHECK(file_write_atomic(path, "x", 1, err, sizeof err) == -1, "a write into a missing folder succeeded");
    CHECK(strstr(err, path) && strstr(err, "cannot write") && strstr(err, "No such file"), "error: %s", err);
}
