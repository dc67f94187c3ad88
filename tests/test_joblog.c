/* test_joblog.c - a job's event log kept in a file (coordinator/joblog.c):
 * lines appended on libuv's thread pool, read back after a "restart" (a
 * new joblog on the same file) once and in order, whether a write is in
 * flight or not, bounded by JOBLOG_FILE_MAX, and a log freed while its
 * write is in flight still writes and frees (ASan/LSan builds check the
 * memory). */
#include <stdio.h>
#include <string.h>
#include <dirent.h>
#include <sys/stat.h>
#include <unistd.h>

#include "harness.h"
#include "coordinator/joblog.h"
#include "util.h"

/* The log's lines as "text|text|...", the dropped count into *dropped. */
static void lines_of(joblog *l, char *out, size_t cap, double *dropped) {
    cJSON *o = cJSON_CreateObject();
    out[0] = 0;
    CHECK(joblog_to_json(l, o, 0) == 0, "joblog_to_json failed");
    *dropped = cJSON_GetObjectItem(o, "dropped")->valuedouble;
    const cJSON *x;
    cJSON_ArrayForEach(x, cJSON_GetObjectItem(o, "lines")) {
        size_t n = strlen(out);
        snprintf(out + n, cap - n, "%s%s", n ? "|" : "", cJSON_GetObjectItem(x, "text")->valuestring);
    }
    cJSON_Delete(o);
}

static long file_size(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 ? (long)st.st_size : -1;
}

/* The file's text (at most cap - 1 bytes). */
static void read_text(const char *path, char *out, size_t cap) {
    FILE *f = fopen(path, "rb");
    size_t n = f ? fread(out, 1, cap - 1, f) : 0;
    out[n] = 0;
    if (f) fclose(f);
}

TEST(joblog_file_outlives_the_process_once_and_in_order) {
    uv_loop_t loop;
    uv_loop_init(&loop);
    char path[256], err[600], got[4096], want[4096], text[4096];
    double dropped;
    snprintf(path, sizeof path, "%s", util_temp_path("joblog-restart.log"));
    FILE *stale = fopen(path, "w");
    if (stale) fputs("1.000 a line of an earlier job with this id\n", stale), fclose(stale);
    joblog *l = joblog_new();
    CHECK(joblog_persist(l, &loop, path, 0, err, sizeof err) == 0, "%s", err); /* a new job: emptied */
    joblog_add(l, 1000.5, "job submitted");
    joblog_add(l, 1001.25, "a worker name with\na newline");
    joblog_add(l, 1002, "tile 0 done");
    uv_run(&loop, UV_RUN_DEFAULT);
    joblog_add(l, 1003, "job done"); /* in flight at the free: its end frees */
    joblog_free(l);
    uv_run(&loop, UV_RUN_DEFAULT);
    read_text(path, text, sizeof text);
    CHECK(strcmp(text, "1000.500 job submitted\n1001.250 a worker name with a newline\n"
                       "1002.000 tile 0 done\n1003.000 job done\n") == 0,
          "the file holds: %s", text);
    snprintf(want, sizeof want, "job submitted|a worker name with a newline|tile 0 done|job done");
    for (int restart = 0; restart < 3; restart++) { /* a write in flight at the read-back, or landed */
        l = joblog_new();
        CHECK(joblog_persist(l, &loop, path, 1, err, sizeof err) == 0, "%s", err);
        joblog_add(l, 2000 + restart, "resumed %d", restart);
        if (restart == 1) uv_run(&loop, UV_RUN_DEFAULT);
        snprintf(want + strlen(want), sizeof want - strlen(want), "|resumed %d", restart);
        lines_of(l, got, sizeof got, &dropped);
        CHECK(strcmp(got, want) == 0 && dropped == 0, "restart %d: %s (dropped %g), expected %s", restart, got,
              dropped, want);
        joblog_add(l, 3000 + restart, "after %d", restart); /* from memory now: the file is read once */
        snprintf(want + strlen(want), sizeof want - strlen(want), "|after %d", restart);
        lines_of(l, got, sizeof got, &dropped);
        CHECK(strcmp(got, want) == 0, "restart %d, a line later: %s, expected %s", restart, got, want);
        joblog_free(l); /* perhaps with a write in flight: its end writes the rest and frees */
        uv_run(&loop, UV_RUN_DEFAULT);
    }
    CHECK(uv_loop_close(&loop) == 0, "requests left on the loop");
}

/* A damaged file (blank lines, no time, a line too long, no newline at
 * the end) reads back as the lines that parse, without reading past it. */
TEST(joblog_damaged_file_reads_back_what_parses) {
    uv_loop_t loop;
    uv_loop_init(&loop);
    char path[256], err[600], got[4096];
    double dropped;
    snprintf(path, sizeof path, "%s", util_temp_path("joblog-damaged.log"));
    FILE *f = fopen(path, "w");
    CHECK(f != NULL, "cannot write %s", path);
    if (!f) return;
    fputs("\n   \n12.5\nnot a line\n7 kept\n", f);
    for (int i = 0; i < 300; i++) fputc('9', f);
    fputs(" too long\n8 also kept\n\n   \t 3", f);
    fclose(f);
    joblog *l = joblog_new();
    CHECK(joblog_persist(l, &loop, path, 1, err, sizeof err) == 0, "%s", err);
    lines_of(l, got, sizeof got, &dropped);
    CHECK(strcmp(got, "kept|also kept") == 0, "read back: %s", got);
    joblog_free(l);
    CHECK(uv_loop_close(&loop) == 0, "requests left on the loop");
}

/* Lines (newlines) in the file at path, or -1. */
static long count_lines(const char *path) {
    FILE *f = fopen(path, "rb");
    long n = f ? 0 : -1;
    for (int c; f && (c = getc(f)) != EOF;) n += c == '\n';
    if (f) fclose(f);
    return n;
}

TEST(joblog_file_is_bounded_and_memory_keeps_the_last_lines) {
    uv_loop_t loop;
    uv_loop_init(&loop);
    static char got[1 << 20];
    char path[256], err[600];
    double dropped;
    snprintf(path, sizeof path, "%s", util_temp_path("joblog-bounded.log"));
    joblog *l = joblog_new();
    CHECK(joblog_persist(l, &loop, path, 0, err, sizeof err) == 0, "%s", err);
    int lines = (int)(JOBLOG_FILE_MAX / 50); /* lines of about 95 bytes: past the bound */
    for (int i = 0; i < lines; i++) {
        joblog_add(l, 5000 + i, "line %07d of a long job's log, written to fill the file past its bound ........", i);
        if (i % 1000 == 0) uv_run(&loop, UV_RUN_NOWAIT);
    }
    uv_run(&loop, UV_RUN_DEFAULT);
    long size = file_size(path);
    CHECK(size > (long)JOBLOG_FILE_MAX - 200 && size <= (long)JOBLOG_FILE_MAX, "file of %ld bytes (bound %u)", size,
          JOBLOG_FILE_MAX);
    CHECK(joblog_count(l) == JOBLOG_MAX, "%d lines in memory", joblog_count(l));
    joblog_free(l);
    l = joblog_new(); /* restart: the file's last JOBLOG_MAX lines */
    CHECK(joblog_persist(l, &loop, path, 1, err, sizeof err) == 0, "%s", err);
    lines_of(l, got, sizeof got, &dropped);
    long in_file = count_lines(path);
    char first[64];
    snprintf(first, sizeof first, "line %07ld of", in_file - JOBLOG_MAX);
    CHECK(joblog_count(l) == JOBLOG_MAX && dropped == (double)(in_file - JOBLOG_MAX) && strncmp(got, first, 15) == 0,
          "%d lines read back, %g dropped, of %ld in the file; first %.30s, expected %s", joblog_count(l), dropped,
          in_file, got, first);
    joblog_free(l);
    /* A file larger than the bound (not one this code writes): its last
     * JOBLOG_FILE_MAX bytes are read, from the first whole line. */
    FILE *f = fopen(path, "a");
    CHECK(f != NULL, "cannot append to %s", path);
    for (int i = 0; f && i < 50000; i++) fprintf(f, "%d.000 line %07d appended past the bound\n", 9000 + i, i);
    if (f) fclose(f);
    l = joblog_new();
    CHECK(joblog_persist(l, &loop, path, 1, err, sizeof err) == 0, "%s", err);
    lines_of(l, got, sizeof got, &dropped);
    CHECK(joblog_count(l) == JOBLOG_MAX && strstr(got, "line 0049999 appended past the bound") &&
              !strstr(got, "|ne ") && got[0] != 'n',
          "%d lines read back from a file over the bound", joblog_count(l));
    joblog_free(l);
    CHECK(uv_loop_close(&loop) == 0, "requests left on the loop");
}

/* Descriptors open in this process now. */
static int open_fds(void) {
    DIR *d = opendir("/proc/self/fd");
    int n = 0;
    while (d && readdir(d)) n++;
    if (d) closedir(d);
    return n;
}

/* A kept log holds no file open: a coordinator with thousands of jobs must
 * not run out of descriptors (each batch opens, writes and closes). */
TEST(joblog_files_hold_no_descriptor_between_batches) {
    uv_loop_t loop;
    uv_loop_init(&loop);
    enum { LOGS = 200 };
    static joblog *logs[LOGS];
    char path[256], err[600];
    int before = open_fds();
    for (int i = 0; i < LOGS; i++) {
        char name[64];
        snprintf(name, sizeof name, "joblog-fd-%d.log", i);
        snprintf(path, sizeof path, "%s", util_temp_path(name));
        logs[i] = joblog_new();
        CHECK(joblog_persist(logs[i], &loop, path, 0, err, sizeof err) == 0, "%s", err);
        joblog_add(logs[i], 1, "job submitted");
    }
    uv_run(&loop, UV_RUN_DEFAULT);
    int during = open_fds();
    CHECK(during <= before + 2, "%d descriptors with %d logs kept, %d before", during, LOGS, before);
    long size = file_size(path);
    CHECK(size == (long)strlen("1.000 job submitted\n"), "the last log's file has %ld bytes", size);
    for (int i = 0; i < LOGS; i++) joblog_free(logs[i]);
    CHECK(uv_loop_close(&loop) == 0, "requests left on the loop");
}
