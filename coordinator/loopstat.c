/* loopstat.c - the longest busy iteration of a libuv loop (loopstat.h). */
#define _GNU_SOURCE
#include "loopstat.h"

#include <time.h>

static uint64_t thread_cpu_ns(void) {
    struct timespec ts;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &ts);
    return (uint64_t)ts.tv_sec * 1000000000u + (uint64_t)ts.tv_nsec;
}

static void on_check(uv_check_t *h) {
    loopstat *ls = h->data;
    uint64_t now = uv_hrtime(), idle = uv_metrics_idle_time(h->loop), cpu = thread_cpu_ns();
    if (ls->last_ns) {
        double cpu_ms = (double)(cpu - ls->last_cpu_ns) / 1e6;
        if (cpu_ms > ls->longest_cpu_ms) ls->longest_cpu_ms = cpu_ms;
        uint64_t wall = now - ls->last_ns, slept = idle - ls->last_idle_ns;
        double busy = (double)(wall > slept ? wall - slept : 0) / 1e6;
        if (busy > ls->longest_ms) ls->longest_ms = busy;
        if (busy > ls->window_ms) ls->window_ms = busy;
    }
    ls->last_ns = now;
    ls->last_idle_ns = idle;
    ls->last_cpu_ns = cpu;
    ls->iterations++;
}

int loopstat_start(uv_loop_t *loop, loopstat *ls) {
    int rc = uv_loop_configure(loop, UV_METRICS_IDLE_TIME);
    if (rc == 0) rc = uv_check_init(loop, &ls->check);
    if (rc) return rc;
    ls->check.data = ls;
    uv_unref((uv_handle_t *)&ls->check); /* measuring alone never keeps the loop alive */
    return uv_check_start(&ls->check, on_check);
}

double loopstat_longest_ms(const loopstat *ls) { return ls->longest_ms; }

double loopstat_longest_cpu_ms(const loopstat *ls) { return ls->longest_cpu_ms; }

double loopstat_take_window(loopstat *ls) {
    double w = ls->window_ms;
    ls->window_ms = 0;
    return w;
}

void loopstat_stop(loopstat *ls) { uv_close((uv_handle_t *)&ls->check, NULL); }
