/* elapsed.h - wall time since a mark on the monotonic clock: the figures a
 * build reports (an intersector's build time, printed by -v), never an
 * input to a result. */
#ifndef TESSERA_ELAPSED_H
#define TESSERA_ELAPSED_H

#include <time.h>

/* Now, as a mark for elapsed_seconds. Can't fail. */
static inline struct timespec elapsed_mark(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t;
}

/* Seconds from mark t0 to now. Can't fail. */
static inline double elapsed_seconds(const struct timespec *t0) {
    struct timespec t1 = elapsed_mark();
    return (double)(t1.tv_sec - t0->tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0->tv_nsec);
}

#endif
