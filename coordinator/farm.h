/* farm.h - the coordinator's farm: accepts workers, hands out tiles under
 * leases, takes back and checks results, stitches them into the frame.
 *
 * Runs entirely on one libuv loop (the caller's). Workers may join and leave
 * at any time. A tile is handed out on a worker's request ("ready" slots);
 * it goes back to the queue when its worker disconnects, falls silent for
 * timeout_s, or holds it past lease_s; when the queue is empty an idle
 * worker may take a copy of a tile that is running long (a backup task) and
 * the first result wins. A peer that breaks the protocol is disconnected
 * with a log line naming it and why; the render goes on.
 *
 * Folder coordinator/: the farm, the local farm and the job service; may
 * include common/ and its layers, never cli/ (README "Where things are"). */
#ifndef TESSERA_FARM_H
#define TESSERA_FARM_H

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>
#include <uv.h>

#include "net/auth.h"
#include "job/job.h"
#include "net/protocol.h"
#include "connlimit.h"

struct conn;
#include "net/conn.h"

typedef struct farm farm;

typedef struct {
    const char *host;   /* listen address ("127.0.0.1", "0.0.0.0", "::") */
    int port;           /* 0: any free port (see farm_port) */
    double heartbeat_s; /* how often each side says it is alive */
    double timeout_s;   /* a worker silent this long loses its tiles */
    double drop_s;      /* ...and this long is disconnected */
    double lease_s;     /* longest a worker may hold a tile */
    int max_tile_side;  /* bounds the frames accepted from workers */
    int verbose;        /* log every join, assignment problem and requeue */
    FILE *log;          /* where log lines go (stderr if NULL) */
    /* A peer whose hello says "role": "client" is handed over: the farm
     * forgets it and calls this with its connection and hello message; the
     * callee must take the connection (conn_set_callbacks) or close it.
     * NULL: clients are refused. */
    /* cls is the credential the client proved (AUTH_NONE without tokens). */
    void (*on_client)(void *ctx, struct conn *c, const cJSON *hello, const char *addr, auth_class cls);
    void *client_ctx;
    auth_keyring auth; /* any key enabled: every peer must prove the token of its class */
    double audit;  /* fraction of tiles (0 to 1) rendered by two workers and compared (farm_audit.c) */
    /* Connection caps (connlimit.h), refused at accept or at a worker's
     * hello with an "error" naming the cap; 0 fields: no cap. */
    connlimit_caps limits;
    double hello_timeout_s; /* a connection without a hello this long is closed (0: 10 s) */
    double blocklist_s; /* a worker that keeps failing on a job waits this long before it may retry (farm_block.c) */
} farm_options;

#define FARM_AUDIT_DEFAULT 0.02    /* --audit: 2% of the tiles are checked unless told otherwise */
#define FARM_BLOCKLIST_DEFAULT 60.0 /* --blocklist-retry, seconds */

/* Fill o with the defaults (heartbeat 1 s, timeout 5 s, drop 30 s, lease
 * 300 s, tiles up to 256 px, 127.0.0.1 port 0, audit FARM_AUDIT_DEFAULT,
 * blocklist wait FARM_BLOCKLIST_DEFAULT). Can't fail. */
void farm_options_default(farm_options *o);

/* Listen on o->host:o->port. Returns the farm, or NULL with the reason in
 * err ("cannot listen on 127.0.0.1:7000: address already in use"). */
farm *farm_new(uv_loop_t *loop, const farm_options *o, char *err, size_t err_len);

/* The port actually listened on. Can't fail. */
int farm_port(const farm *f);

/* What a render's caller learns when it ends and as it goes. */
typedef struct {
    int tiles_total, tiles_done;
    trace_stats stats;      /* summed over the tiles stitched */
    int workers;            /* connected and not stalled now */
    uint64_t duplicates;    /* results dropped because the tile was done */
    uint64_t requeued;      /* tiles put back after a loss, stall or lease */
    uint64_t backups;       /* copies handed out near the end */
    uint64_t bytes_in, bytes_out; /* over every connection, so far */
    uint64_t audited;          /* tiles two workers agreed on (--audit) */
    uint64_t audit_mismatches; /* audited tiles on which two workers disagreed */
    int quarantined;           /* workers quarantined for this job */
    int blocklisted;           /* times a worker was blocklisted for this job */
    int failed;             /* the job cannot finish (error says why) */
    int cancelled;          /* farm_cancel ended it */
    char error[512];
} farm_report;

/* Called on the loop thread: every 100 ms while tiles are being stitched
 * (done = 0), and once at the end (done = 1, the job complete or failed). */
typedef void (*farm_job_cb)(void *ctx, const farm_report *r, int done);

/* Called when a checked tile is about to count as done, with its pixels
 * already in the frame. Return 0 (it counts now); FARM_TILE_PENDING (it
 * counts when the caller says so with farm_tile_durable, e.g. once its
 * journal record is synced; meanwhile it is neither handed out again nor
 * counted); or -1, which fails the job with the message the callee wrote
 * into err (e.g. the journal could not be written). */
typedef int (*farm_tile_cb)(void *ctx, uint32_t tile, const tile_rect *rect, char *err, size_t err_len);
#define FARM_TILE_PENDING 1

typedef struct {
    int tile_size;
    int priority;          /* higher first; equal priorities in submission order */
    const uint8_t *done;   /* tiles already in rgb (resumed jobs), one byte each, or NULL */
    farm_tile_cb on_tile;  /* may be NULL */
    /* Called (with the job's ctx) when the job's first tile is handed out,
     * so the caller can tell queued from rendering; may be NULL. */
    void (*on_first_assign)(void *ctx);
    /* Adaptive rounds (desc->adaptive): the pixels to render (one byte per
     * pixel of the frame, the caller's, kept until the job ends) and the
     * sample range; rgb then receives ADAPTIVE_CHANNELS sums per pixel. */
    const uint8_t *mask;
    uint32_t first, count;
    /* The bundle already framed (a WIRE_KIND_SCENE frame, e.g. built off
     * the loop, or shared by an adaptive job's rounds): the farm takes a
     * reference, and farm_submit's bundle is not read (it may be NULL).
     * NULL: bundle is copied. */
    conn_blob *scene;
} farm_job_options;

/* Render job desc over the farm: bundle (serialised scene bundle, copied)
 * is sent once to each worker that needs it; finished tiles are stitched
 * into rgb (width * height * 3 floats, the caller's, top row first).
 * cb, on_tile and the callbacks' ctx stay the caller's. Returns 0, or -1
 * when out of memory. */
int farm_submit(farm *f, const proto_job *desc, const uint8_t *bundle, size_t bundle_len,
                const farm_job_options *o, float *rgb, farm_job_cb cb, void *ctx);

/* A tile whose on_tile returned FARM_TILE_PENDING is durable (error NULL:
 * it counts now, and may finish the job) or could not be made so (error:
 * the job fails with it). Ignored for a job that ended or was forgotten. */
void farm_tile_durable(farm *f, uint32_t job, uint32_t tile, const char *error);

/* Stop a job: its workers are told to drop it, its callback runs with
 * cancelled set. Returns 0, or -1 if no such job is running. */
int farm_cancel(farm *f, uint32_t job);

/* Change a running job's priority: its tiles not yet handed out are
 * scheduled before those of lower-priority jobs (and after equal ones
 * submitted earlier); tiles out with workers stay there. Returns 0, or -1
 * if no such job is running. */
int farm_set_priority(farm *f, uint32_t job, int priority);

/* Free a job that has finished (complete, failed or cancelled). Late
 * results for it are then dropped quietly. Returns 0 or -1 (unknown or
 * still running). */
int farm_forget(farm *f, uint32_t job);

/* One line of `tessera workers`. */
typedef struct {
    char name[64], addr[64];
    int threads;
    int stalled;
    uint64_t tiles, samples;
    double connected_s, silent_s; /* since it joined; since it last spoke */
    int quarantined;              /* jobs it was quarantined in: its tiles failed an audit */
    int failures;                 /* tiles it reported as failed */
    int blocklisted;              /* running jobs it is blocklisted in now (it failed too often) */
    double retry_s;               /* ...and when it may try the first of them again */
} farm_worker_info;

/* Fill out with up to max connected workers; returns how many there are.
 * Can't fail. */
int farm_list_workers(const farm *f, farm_worker_info *out, int max);

/* The current figures of the job with this id (0 if known). */
int farm_job_report(const farm *f, uint32_t job, farm_report *r);

/* What happens on the farm, for watchers (the dashboard): a tile handed
 * out (backup set for a copy), done (seconds since it was handed out,
 * samples traced), put back in the queue, a worker joining or leaving.
 * worker is the worker's name, or NULL when not known (a requeue). */
typedef enum { FARM_EV_ASSIGN, FARM_EV_DONE, FARM_EV_REQUEUE, FARM_EV_JOIN, FARM_EV_LEAVE } farm_event_kind;
typedef struct {
    farm_event_kind kind;
    uint32_t job, tile;
    tile_rect rect;
    const char *worker;
    double seconds;
    uint64_t samples;
    int backup;
} farm_event;

/* Call cb(ctx, event) on the loop thread for every farm_event (one
 * watcher; NULL stops). cb must not call back into the farm. */
void farm_set_event_cb(farm *f, void (*cb)(void *ctx, const farm_event *e), void *ctx);

/* Farm-wide figures for /metrics: bytes over every connection so far,
 * tiles waiting in the queues, jobs not finished. Can't fail. */
typedef struct {
    uint64_t bytes_in, bytes_out;
    int queued, running_jobs;
} farm_totals;
void farm_get_totals(const farm *f, farm_totals *t);

/* A client handed over by on_client (addr as given to it) closed: its
 * connection no longer counts against the caps. Can't fail. */
void farm_client_closed(farm *f, const char *addr);

/* Add to welcome the coordinator's proof, with the key of class cls, for
 * the nonce the peer sent in hello (when a token is configured and the peer
 * asked). Can't fail. */
void farm_add_proof(const farm *f, auth_class cls, const cJSON *hello, cJSON *welcome);

/* Use these credentials for connections from now on (SIGHUP re-reads the
 * token files): links already sealed keep their session keys. Can't fail. */
void farm_set_auth(farm *f, const auth_keyring *r);

/* Print one line per worker, current and departed: name, address,
 * threads, tiles, bytes. Can't fail. */
void farm_print_workers(const farm *f, FILE *out);

/* The farm's work is over but it stays open a moment (the local farm, for
 * its workers to leave): from now on a peer's departure is neither logged
 * (unless verbose) nor a reason to reschedule, as after farm_close. Can't
 * fail. */
void farm_wind_down(farm *f);

/* Stop listening and disconnect every worker; cb runs once everything is
 * closed, after which farm_free may be called. */
void farm_close(farm *f, void (*cb)(void *ctx), void *ctx);

/* Free a closed farm and its jobs. */
void farm_free(farm *f);

#endif
