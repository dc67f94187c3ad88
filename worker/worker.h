/* worker.h - a farm worker: connects to a coordinator, renders the tiles it
 * is given on a pool of threads, sends them back, and reconnects with
 * backoff whenever the coordinator goes away (docs/protocol.md).
 *
 * Folder worker/: tessera-worker; may include common/job, render, net and the
 * base, never coordinator/ or cli/ (README "Where things are"). */
#ifndef TESSERA_WORKER_H
#define TESSERA_WORKER_H

#include "net/auth.h"

typedef struct {
    const char *host; /* coordinator name or address */
    int port;
    const char *name;   /* shown in the coordinator's logs */
    int threads;        /* render threads (>= 1) */
    int prefetch;       /* tiles asked for beyond one per thread */
    int once;           /* exit when the connection ends instead of reconnecting */
    int throttle_ms;    /* sleep after each tile (tests: a slow machine) */
    double retry_max_s; /* longest wait between connection attempts */
    double idle_exit_s; /* > 0: leave (status 0) after this long with no tile in hand */
    double keep_scene_s; /* keep a loaded scene this long after its last job (pool.h); 0: free it at once */
    int verbose;
    int quiet;          /* errors only (local farms) */
    auth_key auth;      /* enabled: prove the token, and make the coordinator prove it */
    /* A scene already loaded, intersector built, that the bundle of
     * preload_hash would load (a local farm's forked worker: the
     * coordinator's, shared page by page). worker_run takes it (frees it);
     * the hello claims it, so the coordinator does not send that bundle.
     * NULL: none. */
    struct scene *preload_scene;
    const char *preload_hash;
} worker_config;

/* tessera-worker's defaults: a thread per core, one tile of prefetch,
 * retries up to 5 s apart, a loaded scene kept 30 s after its last job;
 * no coordinator (host NULL). */
worker_config worker_config_default(void);

/* Run until SIGTERM/SIGINT, a refused handshake, (with once) the end of
 * the connection, or (with idle_exit_s) that long without a tile in hand,
 * whether no coordinator was reachable or it gave no work. Returns the process exit status: 0 after a clean stop,
 * 1 on a fatal error (printed on stderr). */
int worker_run(const worker_config *cfg);

#endif
