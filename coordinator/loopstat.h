/* loopstat.h - how long the coordinator's libuv loop goes without waiting
 * for I/O: the busy time of each loop iteration (wall time between two
 * "check" phases less the time the loop spent idle in between, from
 * uv_metrics_idle_time). A long iteration is a stall: heartbeats, tile
 * hand-outs and every client wait for it. Exported for the log (-v) and
 * for a dashboard (loopstat_longest_ms). */
#ifndef TESSERA_LOOPSTAT_H
#define TESSERA_LOOPSTAT_H

#include <uv.h>

typedef struct {
    uv_check_t check;
    uint64_t last_ns, last_idle_ns, last_cpu_ns;
    double longest_cpu_ms;    /* CPU time of the loop thread in one iteration:
                                 the work the loop did, without the time the
                                 machine gave to others (a loaded host) */
    double longest_ms;        /* since start */
    double window_ms;         /* since the last loopstat_take_window */
    unsigned long iterations;
} loopstat;

/* Configure loop for idle-time metrics (call before uv_run) and start
 * measuring. Returns 0 or a libuv error code. */
int loopstat_start(uv_loop_t *loop, loopstat *ls);

/* The longest iteration since the start, in milliseconds. */
double loopstat_longest_ms(const loopstat *ls);

/* The most CPU time the loop thread spent in one iteration, in ms. */
double loopstat_longest_cpu_ms(const loopstat *ls);

/* The longest iteration since the last call (then reset). */
double loopstat_take_window(loopstat *ls);

/* Stop (the handle is closed on the loop). */
void loopstat_stop(loopstat *ls);

#endif
