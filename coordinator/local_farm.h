/* local_farm.h - render one scene on a farm driven from this process: the
 * coordinator (farm.c) on a private event loop, `workers` tessera-worker
 * processes spawned on loopback, and optionally remote workers dialling in
 * on a --listen address. This is what `tessera render` does by default. */
#ifndef TESSERA_LOCAL_FARM_H
#define TESSERA_LOCAL_FARM_H

#include <stddef.h>
#include <stdint.h>

#include "job/job.h"
#include "net/protocol.h"
#include "farm.h"
#include "dashboard.h"

/* A local worker the caller started before the farm (a fork of this
 * process holding the loaded scene): it waits to read, from fd, the
 * address to dial ("HOST:PORT", then end of file). */
typedef struct {
    int pid, fd;
} local_farm_forked;

typedef struct {
    int workers;            /* local worker processes to spawn (may be 0 with a listen address) */
    /* NULL, or `workers` of them already started (local_farm_forked): the
     * farm sends each its address and closes fd, watches and stops them
     * as it would the ones it spawns, and spawns tessera-worker only to
     * restart one that dies. */
    const local_farm_forked *forked;
    int threads_per_worker; /* their --threads */
    int tile_size;
    farm_options farm;      /* host/port: where to listen (port 0: any) */
    int listening;          /* farm.host/port were given: say where, wait for remote workers */
    /* Called on the farm's loop at most every 0.1 s and once more with
     * final = 1 when the last tile is stitched (NULL: nothing shown). The
     * command line draws its bar here; the farm knows nothing of terminals. */
    void (*progress)(void *ctx, int done, int total, double samples_per_s, int workers, double eta_s, int final);
    void *progress_ctx;
    int verbose;            /* per-worker table and farm figures at the end */
    const char *token_file; /* handed to the local workers, or NULL */
    double noise_threshold; /* > 0: adaptive sampling in rounds (adaptive.h) */
    int min_spp;            /* adaptive: samples every pixel takes first */
    float *samples;         /* adaptive: per-pixel sample counts out, or NULL */
    const dashboard_options *http; /* serve the dashboard while rendering (dashboard.h), or NULL */
} local_farm_options;

typedef struct {
    trace_stats stats;
    double coordinator_cpu_s; /* user + system time of this process during the render */
    uint64_t bytes_in, bytes_out;
    int tiles;
    uint64_t duplicates, requeued, backups;
    int interrupted; /* the signal (SIGINT, SIGTERM) that stopped the render, or 0 */
} local_farm_report;

/* Let forked[0 .. n) go without a farm (each reads end of file and exits)
 * and reap them; local_farm_render does this itself when it fails before
 * taking them over. */
void local_farm_release_forked(const local_farm_forked *forked, int n);

/* Render job over the farm; bundle is the serialised scene bundle (sent to
 * the workers), rgb the caller's width * height * 3 floats. Returns 0, or
 * -1 with the reason in err (no worker program, cannot listen, every local
 * worker died, interrupted, a tile failed repeatedly). */
int local_farm_render(const local_farm_options *o, const proto_job *job, const uint8_t *bundle, size_t bundle_len,
                      float *rgb, local_farm_report *rep, char *err, size_t err_len);

#endif
