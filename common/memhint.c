/* memhint.c - the first-touch probe behind memhint_huge_is_cheap (memhint.h):
 * which page size this host faults in faster, timed once per process. */
#include "memhint.h"

#include <pthread.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

static pthread_once_t probe_once = PTHREAD_ONCE_INIT;
static int probe_cheap;
static double probe_small_ms = -1.0, probe_huge_ms = -1.0;

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
    probe_cheap = probe_small_ms >= 0.0 && probe_huge_ms >= 0.0 && probe_huge_ms < 0.75 * probe_small_ms;
}

int memhint_huge_is_cheap(void) {
    const char *forced = getenv("TESSERA_HUGE_PAGES");
    if (forced && (!strcmp(forced, "0") || !strcmp(forced, "1"))) return forced[0] == '1';
    pthread_once(&probe_once, probe);
    return probe_cheap;
}

void memhint_probe_ms(double *small_pages, double *huge_pages) {
    *small_pages = probe_small_ms;
    *huge_pages = probe_huge_ms;
}
