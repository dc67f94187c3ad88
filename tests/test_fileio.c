/* test_fileio.c - the one atomic write (replaces whole, leaves no temporary,
 * names the file when it cannot write) and reads into the caller's memory. */
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

/* file_read_with's room: 8 bytes of header then the file (ctx: a buffer of
 * 64 bytes), counting its calls in the buffer's first byte. */
static void *room_behind_header(size_t len, void *ctx) {
    unsigned char *b = ctx;
    b[0]++;
    return len <= 56 ? b + 8 : NULL;
}

/* file_read_with reads the file into the caller's room once, in place (what
 * admission uses to read a scene straight into its frame), and refuses
 * what file_read_all refuses, naming the file. */
TEST(fileio_read_with_reads_into_the_callers_room) {
    char path[300], err[700] = "";
    unsigned char buf[64] = {0};
    snprintf(path, sizeof path, "%s", util_write_temp("read-with.txt", "scene bytes"));
    CHECK(file_read_with(path, 100, room_behind_header, buf, err, sizeof err) == 11 && buf[0] == 1 &&
              memcmp(buf + 8, "scene bytes", 11) == 0,
          "read: %d calls, %.11s; %s", buf[0], (const char *)buf + 8, err);
    CHECK(file_read_with(path, 10, room_behind_header, buf, err, sizeof err) == -1 && strstr(err, path) &&
              strstr(err, "more than the limit of 10") && buf[0] == 1,
          "a file over the limit: %s (%d calls)", err, buf[0]);
    char big[100];
    memset(big, 'x', sizeof big - 1);
    big[sizeof big - 1] = '\0';
    snprintf(path, sizeof path, "%s", util_write_temp("read-with-big.txt", big));
    CHECK(file_read_with(path, 1000, room_behind_header, buf, err, sizeof err) == -1 && strstr(err, "out of memory") &&
              strstr(err, path),
          "no room: %s", err);
    CHECK(file_read_with("/", 1000, room_behind_header, buf, err, sizeof err) == -1 &&
              strstr(err, "not a regular file"),
          "a folder: %s", err);
}

/* A file big enough to be read in ranges on threads (fileio.c,
 * READ_PART_MIN: 32 MiB a range, so 3 here), read with 1, 2 and 3 threads
 * (TESSERA_LOAD_THREADS, par.h): every byte where it belongs, the length
 * exact, the NUL after it. A range put at the wrong offset, or one left
 * unread, changes the pattern. */
TEST(fileio_reads_a_big_file_in_parts_on_threads) {
    size_t n = ((size_t)96 << 20) + 7;
    unsigned char *pattern = malloc(n);
    CHECK(pattern != NULL, "out of memory");
    if (!pattern) return;
    for (size_t i = 0; i < n; i++) pattern[i] = (unsigned char)((i * 2654435761u) >> 24 ^ i >> 20);
    const char *path = util_temp_path("big.bin");
    char err[700];
    CHECK(file_write_atomic(path, pattern, n, err, sizeof err) == 0, "write: %s", err);
    static const char *const threads[] = {"1", "2", "3"};
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        setenv("TESSERA_LOAD_THREADS", threads[t], 1);
        size_t len = 0;
        char *text = file_read_all(path, n, &len, err, sizeof err);
        CHECK(text != NULL, "%s threads: read: %s", threads[t], err);
        if (!text) continue;
        CHECK(len == n && memcmp(text, pattern, n) == 0 && text[n] == '\0', "%s threads: read %zu bytes of %zu, %s",
              threads[t], len, n, len == n && memcmp(text, pattern, n) == 0 ? "no NUL after them" : "not the bytes written");
        free(text);
    }
    unsetenv("TESSERA_LOAD_THREADS");
    remove(path);
    free(pattern);
}
