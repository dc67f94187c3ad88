/* jobstore.c - the job-record operations of the job service, timed on the
 * current store (one JSON file per job, written whole through a synced
 * temporary and renamed: file_write_atomic, as coordinator/jobstore.c) and
 * on SQLite in WAL mode (one row per job; synchronous=FULL, so each commit
 * is as durable as a synced file). A prototype for the decision in
 * docs/jobstore.md, not part of the product.
 *
 *   jobstore-bench DIR [JOBS] [DURABLE_JOBS]
 *
 * For each store: create DURABLE_JOBS jobs one commit each (submit), update
 * each one's state once (running -> done, as when a job ends), then with
 * JOBS records on disk: recover (open and read every record back, as at a
 * restart: what `status` lists), and expire half of them (retention). Prints
 * wall and CPU milliseconds per operation. Tiles are not part of it: they
 * stay in append-only synced journals either way. */
#define _GNU_SOURCE
#include <cjson/cJSON.h>
#include <dirent.h>
#include <inttypes.h>
#include <sqlite3.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>

#include "fileio.h"

typedef struct {
    uint32_t id;
    char name[64], scene[65], state[16], error[64];
    int width, height, spp, priority, tile_size;
    double submitted, finished;
} rec;

static double wall(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static double cpu(void) {
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)ru.ru_stime.tv_usec;
}

static void rec_make(rec *r, uint32_t id) {
    memset(r, 0, sizeof *r);
    r->id = id;
    snprintf(r->name, sizeof r->name, "scenes/job-%u.json", id);
    memset(r->scene, 'a' + (int)(id % 6), 64);
    snprintf(r->state, sizeof r->state, "running");
    r->width = 1920, r->height = 1080, r->spp = 256, r->tile_size = 32;
    r->submitted = 1.7e9 + id;
}

/* ---- the current store: jobs/ID.json, as store_save_job writes it ---- */

/* Write r as jobs/ID.json: synced and renamed (durable), or plainly (setup). */
static int file_save(const char *dir, const rec *r, int durable) {
    cJSON *m = cJSON_CreateObject();
    cJSON_AddNumberToObject(m, "job", r->id);
    cJSON_AddStringToObject(m, "name", r->name);
    cJSON_AddStringToObject(m, "scene", r->scene);
    cJSON_AddNumberToObject(m, "width", r->width);
    cJSON_AddNumberToObject(m, "height", r->height);
    cJSON_AddNumberToObject(m, "spp", r->spp);
    cJSON_AddNumberToObject(m, "max_depth", 8);
    cJSON_AddStringToObject(m, "seed", "1");
    cJSON_AddBoolToObject(m, "nee", 1);
    cJSON_AddBoolToObject(m, "mis", 1);
    cJSON_AddStringToObject(m, "sampler", "sobol");
    cJSON_AddNumberToObject(m, "priority", r->priority);
    cJSON_AddNumberToObject(m, "tile_size", r->tile_size);
    cJSON_AddStringToObject(m, "state", r->state);
    cJSON_AddStringToObject(m, "error", r->error);
    cJSON_AddNumberToObject(m, "submitted", r->submitted);
    cJSON_AddNumberToObject(m, "finished", r->finished);
    char *text = cJSON_Print(m), path[4096], err[512];
    cJSON_Delete(m);
    snprintf(path, sizeof path, "%s/%u.json", dir, r->id);
    FILE *f = durable || !text ? NULL : fopen(path, "w");
    int rc = !text ? -1
             : durable ? file_write_atomic(path, text, strlen(text), err, sizeof err)
                       : (!f || fputs(text, f) < 0) | (f && fclose(f) != 0);
    if (rc) fprintf(stderr, "jobstore-bench: %s\n", durable ? err : path);
    free(text);
    return rc;
}

/* Read every jobs/ID.json back (readdir, read, parse). Returns the count. */
static int file_recover(const char *dir, rec *out, int cap) {
    DIR *d = opendir(dir);
    struct dirent *e;
    int n = 0;
    while (d && (e = readdir(d)) != NULL && n < cap) {
        if (!strstr(e->d_name, ".json")) continue;
        char path[4400], err[256];
        size_t len;
        snprintf(path, sizeof path, "%.4000s/%s", dir, e->d_name);
        char *text = file_read_all(path, 1 << 20, &len, err, sizeof err);
        cJSON *m = text ? cJSON_Parse(text) : NULL;
        free(text);
        if (!m) continue;
        rec *r = &out[n++];
        r->id = (uint32_t)cJSON_GetObjectItem(m, "job")->valuedouble;
        snprintf(r->state, sizeof r->state, "%s", cJSON_GetStringValue(cJSON_GetObjectItem(m, "state")));
        r->finished = cJSON_GetObjectItem(m, "finished")->valuedouble;
        cJSON_Delete(m);
    }
    if (d) closedir(d);
    return n;
}

/* ---- SQLite, WAL ---- */

static sqlite3 *db_open(const char *path) {
    sqlite3 *db;
    if (sqlite3_open(path, &db) != SQLITE_OK) return NULL;
    sqlite3_exec(db,
                 "PRAGMA journal_mode=WAL; PRAGMA synchronous=FULL;"
                 "CREATE TABLE IF NOT EXISTS jobs (id INTEGER PRIMARY KEY, name TEXT, scene TEXT, width INT, height INT,"
                 " spp INT, max_depth INT, seed TEXT, nee INT, mis INT, sampler TEXT, priority INT, tile_size INT,"
                 " state TEXT, error TEXT, submitted REAL, finished REAL);"
                 "CREATE INDEX IF NOT EXISTS jobs_finished ON jobs(finished);",
                 NULL, NULL, NULL);
    return db;
}

static int db_save(sqlite3 *db, sqlite3_stmt *ins, const rec *r) {
    sqlite3_reset(ins);
    sqlite3_bind_int64(ins, 1, r->id);
    sqlite3_bind_text(ins, 2, r->name, -1, SQLITE_STATIC);
    sqlite3_bind_text(ins, 3, r->scene, -1, SQLITE_STATIC);
    sqlite3_bind_int(ins, 4, r->width);
    sqlite3_bind_int(ins, 5, r->height);
    sqlite3_bind_int(ins, 6, r->spp);
    sqlite3_bind_int(ins, 7, r->priority);
    sqlite3_bind_int(ins, 8, r->tile_size);
    sqlite3_bind_text(ins, 9, r->state, -1, SQLITE_STATIC);
    sqlite3_bind_text(ins, 10, r->error, -1, SQLITE_STATIC);
    sqlite3_bind_double(ins, 11, r->submitted);
    sqlite3_bind_double(ins, 12, r->finished);
    int rc = sqlite3_step(ins) == SQLITE_DONE ? 0 : -1; /* autocommit: one synced transaction */
    if (rc) fprintf(stderr, "jobstore-bench: sqlite: %s\n", sqlite3_errmsg(db));
    return rc;
}

static int db_recover(sqlite3 *db, rec *out, int cap) {
    sqlite3_stmt *q;
    int n = 0;
    sqlite3_prepare_v2(db, "SELECT id, state, finished FROM jobs ORDER BY id", -1, &q, NULL);
    while (n < cap && sqlite3_step(q) == SQLITE_ROW) {
        rec *r = &out[n++];
        r->id = (uint32_t)sqlite3_column_int64(q, 0);
        snprintf(r->state, sizeof r->state, "%s", (const char *)sqlite3_column_text(q, 1));
        r->finished = sqlite3_column_double(q, 2);
    }
    sqlite3_finalize(q);
    return n;
}

#define INSERT_SQL                                                                                                 \
    "INSERT OR REPLACE INTO jobs (id, name, scene, width, height, spp, max_depth, seed, nee, mis, sampler, "       \
    "priority, tile_size, state, error, submitted, finished) VALUES (?1, ?2, ?3, ?4, ?5, ?6, 8, '1', 1, 1, 'sobol', " \
    "?7, ?8, ?9, ?10, ?11, ?12)"

typedef struct {
    double wall, cpu;
} span;

static span t0(void) { return (span){wall(), cpu()}; }

static void report(const char *store, const char *op, int n, span s) {
    double w = (wall() - s.wall) * 1e3, c = (cpu() - s.cpu) * 1e3;
    printf("%-7s %-34s %6d records: %9.1f ms wall (%7.3f ms each), %8.1f ms CPU\n", store, op, n, w, w / n, c);
}

static int bench_files(const char *root, int jobs, int durable, rec *buf) {
    char dir[4096];
    snprintf(dir, sizeof dir, "%s/files", root);
    mkdir(dir, 0755);
    rec r;
    span s = t0();
    for (int i = 1; i <= durable; i++) {
        rec_make(&r, (uint32_t)i);
        if (file_save(dir, &r, 1)) return -1;
    }
    report("files", "create (one synced write each)", durable, s);
    s = t0();
    for (int i = 1; i <= durable; i++) {
        rec_make(&r, (uint32_t)i);
        snprintf(r.state, sizeof r.state, "done");
        r.finished = r.submitted + 60;
        if (file_save(dir, &r, 1)) return -1;
    }
    report("files", "update state (rewrite, synced)", durable, s);
    /* The rest of the JOBS records, unsynced (setup only). */
    for (int i = durable + 1; i <= jobs; i++) {
        rec_make(&r, (uint32_t)i);
        snprintf(r.state, sizeof r.state, "done");
        r.finished = r.submitted + 60;
        if (file_save(dir, &r, 0)) return -1;
    }
    sync();
    s = t0();
    int n = file_recover(dir, buf, jobs);
    report("files", "recover / list all (readdir+parse)", n, s);
    s = t0();
    int gone = 0;
    for (int i = 0; i < n; i++)
        if (buf[i].finished < 1.7e9 + jobs / 2 + 60) {
            char path[4200];
            snprintf(path, sizeof path, "%s/%u.json", dir, buf[i].id);
            gone += unlink(path) == 0;
        }
    report("files", "expire half (unlink each)", gone, s);
    return 0;
}

static int bench_sqlite(const char *root, int jobs, int durable, rec *buf) {
    char path[4096];
    snprintf(path, sizeof path, "%s/jobs.db", root);
    sqlite3 *db = db_open(path);
    sqlite3_stmt *ins;
    if (!db || sqlite3_prepare_v2(db, INSERT_SQL, -1, &ins, NULL) != SQLITE_OK) return -1;
    rec r;
    span s = t0();
    for (int i = 1; i <= durable; i++) {
        rec_make(&r, (uint32_t)i);
        if (db_save(db, ins, &r)) return -1;
    }
    report("sqlite", "create (one synced commit each)", durable, s);
    sqlite3_stmt *up;
    sqlite3_prepare_v2(db, "UPDATE jobs SET state = 'done', finished = ?2 WHERE id = ?1", -1, &up, NULL);
    s = t0();
    for (int i = 1; i <= durable; i++) {
        sqlite3_reset(up);
        sqlite3_bind_int64(up, 1, i);
        sqlite3_bind_double(up, 2, 1.7e9 + i + 60);
        if (sqlite3_step(up) != SQLITE_DONE) return -1;
    }
    report("sqlite", "update state (UPDATE, synced)", durable, s);
    sqlite3_exec(db, "BEGIN", NULL, NULL, NULL);
    for (int i = durable + 1; i <= jobs; i++) {
        rec_make(&r, (uint32_t)i);
        snprintf(r.state, sizeof r.state, "done");
        r.finished = r.submitted + 60;
        if (db_save(db, ins, &r)) return -1;
    }
    sqlite3_exec(db, "COMMIT", NULL, NULL, NULL);
    sqlite3_finalize(ins);
    sqlite3_finalize(up);
    sqlite3_close(db);
    sync();
    s = t0();
    db = db_open(path);
    int n = db_recover(db, buf, jobs);
    report("sqlite", "recover / list all (open+SELECT)", n, s);
    s = t0();
    sqlite3_stmt *del;
    sqlite3_prepare_v2(db, "DELETE FROM jobs WHERE finished < ?1", -1, &del, NULL);
    sqlite3_bind_double(del, 1, 1.7e9 + jobs / 2 + 60);
    sqlite3_step(del);
    sqlite3_finalize(del);
    report("sqlite", "expire half (one DELETE)", sqlite3_changes(db), s);
    sqlite3_close(db);
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 2) {
        fprintf(stderr, "usage: jobstore-bench DIR [JOBS] [DURABLE_JOBS]\n");
        return 2;
    }
    int jobs = argc > 2 ? atoi(argv[2]) : 10000, durable = argc > 3 ? atoi(argv[3]) : 1000;
    if (jobs < 2 || durable < 1 || durable > jobs) return 2;
    mkdir(argv[1], 0755);
    rec *buf = calloc((size_t)jobs, sizeof *buf);
    printf("SQLite %s, WAL, synchronous=FULL; %d records, %d of them created and updated one durable commit each\n",
           sqlite3_libversion(), jobs, durable);
    int rc = buf ? bench_files(argv[1], jobs, durable, buf) || bench_sqlite(argv[1], jobs, durable, buf) : 1;
    free(buf);
    return rc;
}
