/* par.c - the ranges of par.h on POSIX threads. */
#include "par.h"

#include <pthread.h>
#include <stdlib.h>
#include <unistd.h>

typedef struct {
    par_fn fn;
    void *ctx;
    size_t begin, end;
    int part;
} par_job;

static void *par_thread(void *arg) {
    par_job *j = arg;
    j->fn(j->ctx, j->begin, j->end, j->part);
    return NULL;
}

/* The cores to use: TESSERA_LOAD_THREADS, else the online ones, within 1
 * to PAR_MAX_PARTS. */
static long par_cores(void) {
    const char *env = getenv("TESSERA_LOAD_THREADS");
    long cores = env ? atol(env) : sysconf(_SC_NPROCESSORS_ONLN);
    return cores < 1 ? 1 : cores > PAR_MAX_PARTS ? PAR_MAX_PARTS : cores;
}

/* `ranges` (1 to PAR_MAX_PARTS), but none shorter than min_per_part
 * elements of n, and at least 1. */
static int parts_within(long ranges, size_t n, size_t min_per_part) {
    size_t most = min_per_part ? n / min_per_part : n;
    return (size_t)ranges < most ? (int)ranges : most > 1 ? (int)most : 1;
}

int par_parts(size_t n, size_t min_per_part) { return parts_within(par_cores(), n, min_per_part); }

int par_parts_touch(size_t n, size_t min_per_part) {
    long ranges = par_cores() * PAR_TOUCH_PER_CORE;
    return parts_within(ranges < PAR_MAX_PARTS ? ranges : PAR_MAX_PARTS, n, min_per_part);
}

void par_range(size_t n, int parts, int part, size_t *begin, size_t *end) {
    *begin = n / (size_t)parts * (size_t)part + n % (size_t)parts * (size_t)part / (size_t)parts;
    *end = n / (size_t)parts * (size_t)(part + 1) + n % (size_t)parts * (size_t)(part + 1) / (size_t)parts;
}

void par_run(size_t n, int parts, par_fn fn, void *ctx) {
    par_job job[PAR_MAX_PARTS];
    pthread_t thread[PAR_MAX_PARTS];
    int started[PAR_MAX_PARTS] = {0};
    if (parts < 1) parts = 1;
    if (parts > PAR_MAX_PARTS) parts = PAR_MAX_PARTS;
    for (int k = 0; k < parts; k++) {
        job[k] = (par_job){fn, ctx, 0, 0, k};
        par_range(n, parts, k, &job[k].begin, &job[k].end);
    }
    int threads = par_cores() > 1;
    for (int k = 1; k < parts && threads; k++) started[k] = pthread_create(&thread[k], NULL, par_thread, &job[k]) == 0;
    par_thread(&job[0]);
    for (int k = 1; k < parts; k++) {
        if (started[k]) pthread_join(thread[k], NULL);
        else par_thread(&job[k]);
    }
}
