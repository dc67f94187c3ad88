/* farm_internal.h - the farm's state, shared by its four files and no one
 * else (the public interface is farm.h; the protocol docs/protocol.md):
 *   farm.c        - the farm itself: create, listen, close, log;
 *   farm_peers.c  - connections, the handshake, control messages, heartbeats;
 *   farm_sched.c  - jobs, the tile queue, leases, assignment and backups;
 *   farm_tiles.c  - results: checked, stitched into the film, copies cancelled;
 *   farm_audit.c  - audited tiles (--audit): compared, quarantine;
 *   farm_block.c  - the per-job blocklist of workers that keep failing.
 *
 * State, all owned by the loop thread:
 *   job   - a render: its tiles, for each tile whether it is done, how many
 *           live leases it has, and whether it waits in the queue;
 *   peer  - a connected worker: its unfilled "ready" slots (credits), its
 *           leases, which scenes and jobs it has been sent;
 *   lease - one tile handed to one peer. A lease is "live" while the tile
 *           counts it as a holder; a revoked (stall, overrun) or cancelled
 *           (another copy won) lease stays on the peer's list until the peer
 *           answers for it, so a late result is recognised, not mistaken
 *           for a tile it was never given.
 * Invariant: a tile is queued iff it is not done and has no live lease. */
#ifndef TESSERA_FARM_INTERNAL_H
#define TESSERA_FARM_INTERNAL_H

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "farm.h"
#include "list.h"
#include "log.h"
#include "net/conn.h"
#include "net/wire.h"
#include "render/film.h"

#define FARM_TICK_MS 100

#define HELLO_TIMEOUT_S 10.0 /* default of farm_options.hello_timeout_s */
#define FARM_DEPARTED_MAX 256 /* departed workers remembered: 312 bytes each, not one per hello for ever */

#define MAX_CREDITS 4096

#define MAX_TILE_FAILURES 3   /* a tile that fails this often fails its job */

#define MAX_PEER_FAILURES 3   /* a worker that fails this often in a job is blocklisted for it (farm_block.c) */

#define BACKUP_AGE_FACTOR 1.5 /* back up tiles running this many times the mean */

#define BACKUP_MIN_AGE_S 0.5  /* ...and at least this long: younger copies gain nothing */

typedef struct job job;

typedef struct job_audit job_audit; /* farm_audit.c */

typedef struct peer peer;

typedef struct {
    char key[136];  /* "name@host": the same worker after it reconnects */
    int failures;   /* in this job, towards MAX_PEER_FAILURES */
    int strikes;    /* times blocklisted: each doubles the wait */
    double until;   /* farm_now() before which it gets none of the job's tiles (0: never blocklisted) */
    int announced;  /* the end of its wait has been logged */
} block_entry;

typedef struct lease {
    job *job;
    uint32_t tile;
    double start;
    int live; /* counts as a holder of the tile */
    LIST_ENTRY(lease) link; /* on its peer's leases */
} lease;

struct job {
    proto_job desc;
    conn_blob *scene; /* the 'S' frame */
    int tile_size, tile_count;
    tile_rect *rects;
    uint8_t *done, *holders, *queued, *failures;
    double *first_start; /* when the tile's oldest live lease began */
    uint32_t *queue;     /* ring of tile_count entries */
    int q_head, q_len;
    film film;             /* the caller's pixels; channels: 3 (means), or
                            * ADAPTIVE_CHANNELS (an adaptive round's sums) */
    const uint8_t *mask;   /* adaptive: the frame's pixels to render */
    uint32_t first, count; /* the sample range every assignment carries */
    farm_job_cb cb;
    farm_tile_cb on_tile;
    void (*on_first_assign)(void *ctx); /* cleared once called */
    void *ctx;
    int priority;
    uint64_t seq;        /* submission order among equal priorities */
    farm_report rep;
    double tile_seconds; /* sum of assign-to-result times, for the mean */
    int reported;        /* tiles_done at the last progress callback */
    int finished;
    farm *owner;           /* for farm_emit */
    job_audit *audit;    /* farm_audit.c; NULL: no tile is audited */
    block_entry *blocks; /* farm_block.c: workers that failed on this job */
    int block_count;
    TAILQ_ENTRY(job) link; /* on the farm's jobs, by priority then age */
};

enum { PEER_HELLO, PEER_ACTIVE, PEER_STALLED };

typedef struct {
    char name[64];
    char addr[64];
    int threads;
    uint64_t tiles, samples, bytes_in, bytes_out;
    double joined, left;
    char why[128];
    uint32_t serial; /* this connection's number in the farm (from 1) */
    int quarantined; /* jobs it was quarantined in (farm_audit.c) */
} peer_record;

/* How many bundles a worker holds when no live job needs more: past it,
 * the coordinator tells the worker to forget the one used longest ago
 * (`forget_scene`) before it sends another. */
#define FARM_PEER_SCENES 8

/* A scene bundle sent to a peer on this connection, and when a job of it
 * was last told (farm.scene_uses). */
typedef struct {
    char hash[SCENE_BUNDLE_HASH_HEX];
    uint64_t used;
} peer_scene;

struct peer {
    farm *f;
    conn *c;
    int state;
    int credits;
    int failures; /* tiles it reported failed, over this connection (the blocklist counts per job) */
    double joined, last_heard, last_sent;
    LIST_HEAD(lease_list, lease) leases;
    peer_scene *scenes; /* the bundles it holds, as this side told it (FARM_PEER_SCENES) */
    int scene_count;
    uint32_t *jobs; /* the ids of the jobs it was told of that the farm still holds */
    int job_count;
    uint32_t forgotten_max; /* the highest id of those it was told of that the farm has forgotten */
    peer_record rec;
    char nonce[AUTH_HEX]; /* the challenge this connection must answer */
    char label[200]; /* "worker NAME (ADDR)" */
    int limit_class; /* counted by f->limits as CONNLIMIT_OPEN or _WORKER; -1: not counted */
    LIST_ENTRY(peer) link; /* on the farm's peers */
};

struct farm {
    uv_loop_t *loop;
    farm_options opt;
    uv_tcp_t listener;
    uv_timer_t tick;
    int port;
    LIST_HEAD(peer_list, peer) peers;
    TAILQ_HEAD(job_list, job) jobs;
    peer_record *departed; /* the latest FARM_DEPARTED_MAX departures */
    int departed_count, departed_cap;
    unsigned long long departed_dropped; /* older ones, counted only */
    uint64_t closed_bytes_in, closed_bytes_out;
    uint32_t next_serial;
    uint64_t next_job_seq; /* job.seq of the last submission */
    uint64_t scene_uses;   /* jobs told to peers: peer_scene.used's clock */
    uint64_t audited, audit_mismatches, quarantined; /* over all jobs, for the workers table */
    uint64_t audit_unchecked;                        /* audited tiles nobody could check (farm_audit.c) */
    uint64_t blocklisted;                            /* blocklistings over all jobs (farm_block.c) */
    int closing, open_handles;
    void (*closed_cb)(void *);
    void *closed_ctx;
    void (*event_cb)(void *ctx, const farm_event *e); /* farm_set_event_cb */
    void *event_ctx;
    connlimit *limits; /* connection counts and caps (connlimit.h) */
};

static inline double farm_now(const farm *f) { return (double)uv_now(f->loop) / 1e3; }

/* Tell the watcher, if any (farm_set_event_cb). */
static inline void farm_emit(const farm *f, farm_event_kind kind, const job *j, uint32_t tile, const char *worker,
                             double seconds, uint64_t samples, int backup) {
    if (!f->event_cb) return;
    farm_event e = {kind, j ? j->desc.id : 0, tile, {0}, worker, seconds, samples, backup};
    if (j && (int)tile < j->tile_count) e.rect = j->rects[tile];
    f->event_cb(f->event_ctx, &e);
}

/* ---- shared between the farm's files ---------------------------------------- */

/* A log line (log.h) from the coordinator, to opt.log or stderr. */
void farm_log(const farm *f, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

void peer_send_json(peer *p, cJSON *m);

/* {"type": TYPE, "job": J[, "tile": T]} */
void peer_send_ids(peer *p, const char *type, uint32_t job, long tile);

/* Disconnect p over a protocol violation, telling it why. Returns 1 (for
 * on_frame). */
int peer_violation(peer *p, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

void farm_on_connection(uv_stream_t *server, int status);

void farm_on_tick(uv_timer_t *t);

/* A lease stops counting as a holder; the tile is queued if nobody else
 * holds it. */
void farm_lease_release(lease *l);

job *farm_find_job(const farm *f, uint32_t id);

void farm_job_free(job *j);

void farm_report_fill(const farm *f, const job *j, farm_report *r);

/* The job is complete or has failed: tell its workers and the caller. */
void farm_job_finish(farm *f, job *j);

void farm_job_fail(farm *f, job *j, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Whether p was told of job id, or may have been: an id no higher than
 * one it was told of that the farm has forgotten since (a tile of it is a
 * late result, not a violation). */
int peer_told_job(const peer *p, uint32_t id);

lease *peer_find_lease(peer *p, uint32_t job_id, uint32_t tile);

/* Use p's credits on queued tiles, then on backups. */
void peer_schedule(peer *p);

void farm_schedule_all(farm *f);

int farm_on_tile(peer *p, const uint8_t *body, size_t len);

/* Queue tile t unless it is done, held, pending an audit or queued. */
void farm_requeue_tile(job *j, uint32_t t);

/* How long a tile of j may run before a backup copy pays: BACKUP_AGE_FACTOR
 * times the job's mean tile time, at least BACKUP_MIN_AGE_S. Needs at least
 * one tile done (farm_sched.c). */
double job_backup_age(const job *j);

/* ---- audited tiles (farm_audit.c) -------------------------------------------- */

enum { AUDIT_ACCEPT, AUDIT_HOLD, AUDIT_DROP, AUDIT_FAILED };

/* Choose the job's audited tiles with a fresh secret seed (fraction <= 0:
 * none, j->audit stays NULL). Returns 0, or -1 when out of memory (what was
 * made is freed by audit_free). */
int audit_new(job *j, double fraction);

void audit_free(job *j);

/* The worker with this serial is quarantined for the job. */
int audit_is_barred(const job *j, uint32_t serial);

/* Tile t has results waiting for an audit copy (it stays out of the queue). */
int audit_is_pending(const job *j, uint32_t t);

/* The worker may render tile t (not barred, no result of its own pending). */
int audit_may_take(const job *j, uint32_t serial, uint32_t t);

/* A pending tile nobody holds that p may render: 1 with *out, or 0. */
int audit_pick(const job *j, const peer *p, uint32_t *out);

/* Tile t was stitched: verified by two workers, or taken from serial alone. */
void audit_accepted(job *j, uint32_t t, uint32_t serial, int verified);

/* See farm_audit.c. */
int audit_on_result(farm *f, job *j, peer *p, uint32_t t, float **px, const trace_stats *stats, double took,
                    int *verified);

/* Accept the pending results no connected worker can check, or fail the
 * job on a mismatch nobody can settle (see farm_audit.c); called on every
 * tick. May end the job, and its owner free it. */
void audit_settle(farm *f, job *j);

/* ---- the per-job blocklist (farm_block.c) ------------------------------------- */

/* p is blocklisted for j now (an expired wait is logged once). */
int block_is_blocked(const farm *f, job *j, const peer *p);

/* Seconds until p may take j's tiles again (0: it may now). */
double block_remaining(const farm *f, const job *j, const peer *p);

/* Count one failure of p on j (what happened, printf-style, for the log);
 * the MAX_PEER_FAILURES-th blocklists p for the job. Ignored once the job
 * has ended or the farm is closing. */
void block_note_failure(farm *f, job *j, peer *p, const char *fmt, ...) __attribute__((format(printf, 4, 5)));

/* p loses its live leases (why: "left (reason)", "silent for 5.2 s"): one
 * failure for each job it held tiles of. Call before releasing them. */
void block_note_lost_leases(farm *f, peer *p, const char *why);

/* The unfinished jobs p is blocklisted in now, and the soonest it may
 * retry one of them (seconds). */
void block_list_peer(const farm *f, const peer *p, int *jobs, double *retry_s);

/* A tile result accepted by the audit (or not audited): into the film,
 * counted, its other copies cancelled, the job finished if it was the last.
 * from: the peer that sent it, or NULL when it has left (serial and name
 * then say who). px stays the caller's. */
void farm_tile_land(farm *f, job *j, peer *from, const char *name, uint32_t serial, uint32_t t, const float *px,
                    double took, const trace_stats *stats, int verified);

#endif
