/* memhint.c - the figures behind memhint_huge_is_cheap (memhint.h): what
 * a first touch costs on each page size, from a probe timed once per
 * process and, for huge pages, from the big buffers put on them since. */
#include "memhint.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#ifndef MADV_POPULATE_WRITE
#define MADV_POPULATE_WRITE 23 /* Linux 5.14 */
#endif

static pthread_once_t probe_once = PTHREAD_ONCE_INIT;
static double probe_small_ms = -1.0, probe_huge_ms = -1.0;
/* Huge pages' figure from the latest sampled buffer, -1 for none. */
static _Atomic double sampled_ms = -1.0;

static double now_ms(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return (double)t.tv_sec * 1e3 + (double)t.tv_nsec * 1e-6;
}

/* Milliseconds to write one byte per 4 KiB page of MEMHINT_PROBE_BYTES of
 * a fresh, 2 MiB-aligned mapping, asking for huge pages or not; -1 when
 * the mapping or the hint is refused. */
static double first_touch_ms(int huge) {
    size_t align = (size_t)2 << 20, map_bytes = MEMHINT_PROBE_BYTES + align;
    char *map = mmap(NULL, map_bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (map == MAP_FAILED) return -1.0;
    volatile char *p = (volatile char *)(((uintptr_t)map + align - 1) & ~(uintptr_t)(align - 1));
    double ms = -1.0;
#ifdef MADV_HUGEPAGE
    int hinted = !huge || madvise((void *)p, MEMHINT_PROBE_BYTES, MADV_HUGEPAGE) == 0;
#else
    int hinted = !huge;
#endif
    if (hinted) {
        double t0 = now_ms();
        for (size_t i = 0; i < MEMHINT_PROBE_BYTES; i += 4096) p[i] = 1;
        ms = now_ms() - t0;
    }
    munmap(map, map_bytes);
    return ms;
}

static void probe(void) {
    probe_small_ms = first_touch_ms(0);
    probe_huge_ms = first_touch_ms(1);
}

/* TESSERA_HUGE_PAGES: 1 or 0 when it decides, else -1. */
static int forced(void) {
    const char *f = getenv("TESSERA_HUGE_PAGES");
    return f && (!strcmp(f, "0") || !strcmp(f, "1")) ? f[0] == '1' : -1;
}

/* Huge pages' figure: the latest buffer's, else the probe's. */
static double huge_figure(void) {
    double s = atomic_load(&sampled_ms);
    return s >= 0.0 ? s : probe_huge_ms;
}

int memhint_rule_cheap(double small_ms, double huge_ms) {
    return small_ms >= 0.0 && huge_ms >= 0.0 && huge_ms < 0.75 * small_ms;
}

int memhint_huge_is_cheap(void) {
    int f = forced();
    if (f >= 0) return f;
    pthread_once(&probe_once, probe);
    return memhint_rule_cheap(probe_small_ms, huge_figure());
}

void memhint_probe_ms(double *small_pages, double *huge_pages) {
    *small_pages = probe_small_ms;
    *huge_pages = probe_huge_ms;
}

double memhint_sampled_ms(void) { return atomic_load(&sampled_ms); }

void memhint_set_figures(double small_ms, double huge_ms, double sampled) {
    pthread_once(&probe_once, probe);
    probe_small_ms = small_ms, probe_huge_ms = huge_ms;
    atomic_store(&sampled_ms, sampled);
}

/* Whether none of the 4 KiB pages of [p, p + bytes) (page-aligned, at
 * most MEMHINT_PROBE_BYTES) is resident yet: a first touch there is a
 * fresh fault, worth timing. */
static int none_resident(void *p, size_t bytes) {
    unsigned char v[MEMHINT_PROBE_BYTES / 4096];
    if (bytes > MEMHINT_PROBE_BYTES || mincore(p, bytes, v) != 0) return 0;
    for (size_t i = 0; i < bytes / 4096; i++)
        if (v[i] & 1) return 0;
    return 1;
}

/* Sample a buffer of at least MEMHINT_SAMPLE_MIN_BYTES (memhint.h): its
 * front on huge pages, faulted in and timed into sampled_ms. Nothing when
 * its front is resident or the populate is refused. */
static void sample(void *p, size_t bytes) {
    uintptr_t huge = (uintptr_t)2 << 20, lo = ((uintptr_t)p + huge - 1) & ~(huge - 1),
              hi = ((uintptr_t)p + bytes) & ~(huge - 1);
    if (hi < lo + MEMHINT_PROBE_BYTES || !none_resident((void *)lo, MEMHINT_PROBE_BYTES)) return;
    memhint_huge((void *)lo, MEMHINT_PROBE_BYTES);
    double t0 = now_ms();
    if (madvise((void *)lo, MEMHINT_PROBE_BYTES, MADV_POPULATE_WRITE) != 0) return;
    atomic_store(&sampled_ms, now_ms() - t0);
}

int memhint_fresh_huge(void *p, size_t bytes) {
    if (!p || !memhint_fresh_wants_huge(bytes)) return 0;
    if (bytes >= MEMHINT_SAMPLE_MIN_BYTES && forced() < 0) {
        sample(p, bytes);
        if (!memhint_huge_is_cheap()) return 0;
    }
    memhint_huge(p, bytes);
    return 1;
}
