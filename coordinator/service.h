/* service.h - the long-running coordinator (`tessera-coordinator`): a job
 * queue rendered by every connected worker, clients that submit, watch,
 * cancel and fetch, and a journal in the data dir so that nothing is lost
 * when the process dies (docs/protocol.md, "Clients" and "Journal"). */
#ifndef TESSERA_SERVICE_H
#define TESSERA_SERVICE_H

#include <stddef.h>
#include <stdint.h>

#include "farm.h"
#include "dashboard.h"

typedef struct {
    farm_options farm;    /* where to listen, timeouts */
    const char *data_dir; /* journal, scenes and results; created if missing */
    int tile_size;
    size_t max_upload;    /* largest scene bundle a client may send */
    int max_jobs;         /* queued and running jobs at once */
    double keep_s;        /* finished jobs are deleted after this long */
    const dashboard_options *http; /* --http: serve the dashboard (dashboard.h), or NULL */
    int keep_jobs;        /* at most this many finished jobs are kept (0: no cap) */
    double client_timeout_s; /* a client that sends nothing this long is closed (0: 30 s) */
    uint64_t max_memory;  /* bytes admitted jobs may hold (0: membudget_default) */
} service_options;

/* Run the service until SIGINT or SIGTERM. Returns the exit status: 0
 * after a signal, 1 when it cannot start (message on stderr). */
int service_run(const service_options *o);

#endif
