/* farm.c - workers, leases and stitching on the coordinator (see farm.h and
 * docs/protocol.md).
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
#include "farm.h"

#include <math.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

#include "net/conn.h"
#include "net/wire.h"

#define FARM_TICK_MS 100
#define HELLO_TIMEOUT_S 10.0
#define MAX_CREDITS 4096
#define MAX_TILE_FAILURES 3   /* a tile that fails this often fails its job */
#define MAX_PEER_FAILURES 3   /* a worker that fails this often gets no more work */
#define BACKUP_AGE_FACTOR 1.5 /* back up tiles running this many times the mean */
#define BACKUP_MIN_AGE_S 0.5  /* ...and at least this long: younger copies gain nothing */

typedef struct job job;
typedef struct peer peer;

typedef struct lease {
    job *job;
    uint32_t tile;
    double start;
    int live; /* counts as a holder of the tile */
    struct lease *next;
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
    float *rgb;            /* channels floats per pixel */
    int channels;          /* 3 (means), or ADAPTIVE_CHANNELS (an adaptive round's sums) */
    const uint8_t *mask;   /* adaptive: the frame's pixels to render */
    uint32_t first, count; /* the sample range every assignment carries */
    farm_job_cb cb;
    farm_tile_cb on_tile;
    void *ctx;
    int priority;
    farm_report rep;
    double tile_seconds; /* sum of assign-to-result times, for the mean */
    int reported;        /* tiles_done at the last progress callback */
    int finished;
    job *next;
};

enum { PEER_HELLO, PEER_ACTIVE, PEER_STALLED };

typedef struct {
    char name[64];
    char addr[64];
    int threads;
    uint64_t tiles, samples, bytes_in, bytes_out;
    double joined, left;
    char why[128];
} peer_record;

struct peer {
    farm *f;
    conn *c;
    int state;
    int blocked; /* failed too often: no more work */
    int credits;
    int failures;
    double joined, last_heard, last_sent;
    lease *leases;
    char (*scenes)[SCENE_BUNDLE_HASH_HEX];
    int scene_count;
    uint32_t *jobs;
    int job_count;
    peer_record rec;
    char nonce[AUTH_HEX]; /* the challenge this connection must answer */
    char label[200]; /* "worker NAME (ADDR)" */
    peer *next;
};

struct farm {
    uv_loop_t *loop;
    farm_options opt;
    uv_tcp_t listener;
    uv_timer_t tick;
    int port;
    peer *peers;
    job *jobs;
    peer_record *departed;
    int departed_count, departed_cap;
    uint64_t closed_bytes_in, closed_bytes_out;
    int closing, open_handles;
    void (*closed_cb)(void *);
    void *closed_ctx;
};

/* ---- helpers -------------------------------------------------------------- */

static double farm_now(const farm *f) { return (double)uv_now(f->loop) / 1e3; }

static void farm_log(const farm *f, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void farm_log(const farm *f, const char *fmt, ...) {
    FILE *out = f->opt.log ? f->opt.log : stderr;
    va_list ap;
    va_start(ap, fmt);
    fputs("tessera: ", out);
    vfprintf(out, fmt, ap);
    fputc('\n', out);
    fflush(out);
    va_end(ap);
}

void farm_options_default(farm_options *o) {
    memset(o, 0, sizeof *o);
    o->host = "127.0.0.1";
    o->heartbeat_s = 1.0;
    o->timeout_s = 5.0;
    o->drop_s = 30.0;
    o->lease_s = 300.0;
    o->max_tile_side = 256;
}

static void peer_send(peer *p, uint8_t *frame, size_t len) {
    if (!frame) return;
    conn_send(p->c, frame, len);
    p->last_sent = farm_now(p->f);
}

static void peer_send_json(peer *p, cJSON *m) {
    size_t len;
    uint8_t *f = m ? wire_frame_json(m, &len) : NULL;
    cJSON_Delete(m);
    peer_send(p, f, len);
}

/* {"type": TYPE, "job": J[, "tile": T]} */
static void peer_send_ids(peer *p, const char *type, uint32_t job, long tile) {
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", type);
    cJSON_AddNumberToObject(m, "job", job);
    if (tile >= 0) cJSON_AddNumberToObject(m, "tile", (double)tile);
    peer_send_json(p, m);
}

/* Send {"type": type, "reason": reason} and close once it is written.
 * Returns 1 (for on_frame). */
static int peer_refuse(peer *p, const char *type, const char *reason) {
    size_t len;
    uint8_t *frame = proto_frame_reason(type, reason, &len);
    peer_send(p, frame, len);
    conn_close(p->c, reason, 1);
    return 1;
}

/* Disconnect p over a protocol violation, telling it why. Returns 1 (for
 * on_frame). */
static int peer_violation(peer *p, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int peer_violation(peer *p, const char *fmt, ...) {
    char reason[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(reason, sizeof reason, fmt, ap);
    va_end(ap);
    farm_log(p->f, "%s: %s; disconnecting", p->label, reason);
    return peer_refuse(p, "error", reason);
}

/* ---- jobs and the tile queue ------------------------------------------------ */

static void job_enqueue(job *j, uint32_t t) {
    if (j->done[t] || j->holders[t] || j->queued[t] || j->finished) return;
    j->queue[(j->q_head + j->q_len) % j->tile_count] = t;
    j->q_len++;
    j->queued[t] = 1;
}

static int job_dequeue(job *j, uint32_t *t) {
    while (j->q_len > 0) {
        uint32_t x = j->queue[j->q_head];
        j->q_head = (j->q_head + 1) % j->tile_count;
        j->q_len--;
        j->queued[x] = 0;
        if (!j->done[x] && !j->holders[x]) {
            *t = x;
            return 1;
        }
    }
    return 0;
}

/* A lease stops counting as a holder; the tile is queued if nobody else
 * holds it. */
static void lease_release(lease *l) {
    if (!l->live) return;
    l->live = 0;
    job *j = l->job;
    if (j->holders[l->tile] > 0) j->holders[l->tile]--;
    if (!j->done[l->tile] && j->holders[l->tile] == 0) {
        job_enqueue(j, l->tile);
        j->rep.requeued++;
    }
}

static job *farm_find_job(const farm *f, uint32_t id) {
    for (job *j = f->jobs; j; j = j->next)
        if (j->desc.id == id) return j;
    return NULL;
}

static void job_free(job *j) {
    conn_blob_unref(j->scene);
    free(j->rects);
    free(j->done);
    free(j->holders);
    free(j->queued);
    free(j->failures);
    free(j->first_start);
    free(j->queue);
    free(j);
}

static void farm_report_fill(const farm *f, const job *j, farm_report *r) {
    *r = j->rep;
    r->tiles_total = j->tile_count;
    r->workers = 0;
    r->bytes_in = f->closed_bytes_in;
    r->bytes_out = f->closed_bytes_out;
    for (const peer *p = f->peers; p; p = p->next) {
        if (p->state == PEER_ACTIVE && !p->blocked) r->workers++;
        r->bytes_in += conn_bytes_in(p->c);
        r->bytes_out += conn_bytes_out(p->c);
    }
}

/* The job is complete or has failed: tell its workers and the caller. */
static void job_finish(farm *f, job *j) {
    j->finished = 1;
    for (peer *p = f->peers; p; p = p->next)
        for (int i = 0; i < p->job_count; i++)
            if (p->jobs[i] == j->desc.id && !conn_is_closing(p->c)) peer_send_ids(p, "job_end", j->desc.id, -1);
    farm_report r;
    farm_report_fill(f, j, &r);
    if (j->cb) j->cb(j->ctx, &r, 1);
}

static void job_fail(farm *f, job *j, const char *fmt, ...) __attribute__((format(printf, 3, 4)));
static void job_fail(farm *f, job *j, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(j->rep.error, sizeof j->rep.error, fmt, ap);
    va_end(ap);
    j->rep.failed = 1;
    farm_log(f, "job %u failed: %s", j->desc.id, j->rep.error);
    job_finish(f, j);
}

/* ---- assignment -------------------------------------------------------------- */

/* Make sure p has the job's scene and description. */
static void peer_tell_job(peer *p, job *j) {
    for (int i = 0; i < p->job_count; i++)
        if (p->jobs[i] == j->desc.id) return;
    int have_scene = 0;
    for (int i = 0; i < p->scene_count; i++) have_scene |= strcmp(p->scenes[i], j->desc.scene_hash) == 0;
    if (!have_scene) {
        void *s = realloc(p->scenes, (size_t)(p->scene_count + 1) * sizeof *p->scenes);
        if (s) {
            p->scenes = s;
            memcpy(p->scenes[p->scene_count++], j->desc.scene_hash, SCENE_BUNDLE_HASH_HEX);
        }
        conn_send_blob(p->c, j->scene);
    }
    uint32_t *js = realloc(p->jobs, (size_t)(p->job_count + 1) * sizeof *p->jobs);
    if (js) {
        p->jobs = js;
        p->jobs[p->job_count++] = j->desc.id;
    }
    peer_send_json(p, proto_job_json(&j->desc));
}

static int peer_told_job(const peer *p, uint32_t id) {
    for (int i = 0; i < p->job_count; i++)
        if (p->jobs[i] == id) return 1;
    return 0;
}

static lease *peer_find_lease(peer *p, uint32_t job_id, uint32_t tile, lease ***link) {
    for (lease **pp = &p->leases; *pp; pp = &(*pp)->next)
        if ((*pp)->job->desc.id == job_id && (*pp)->tile == tile) {
            if (link) *link = pp;
            return *pp;
        }
    return NULL;
}

/* A tile worth backing up for p: not done, held once, not by p, running
 * longer than BACKUP_AGE_FACTOR times the mean tile time. Oldest first. */
static int job_pick_backup(const farm *f, job *j, peer *p, uint32_t *out) {
    int done = j->rep.tiles_done;
    if (done == 0) return 0;
    double mean = j->tile_seconds / done, now = farm_now(f), best_age = BACKUP_AGE_FACTOR * mean;
    if (best_age < BACKUP_MIN_AGE_S) best_age = BACKUP_MIN_AGE_S;
    int found = 0;
    for (int t = 0; t < j->tile_count; t++) {
        if (j->done[t] || j->holders[t] != 1 || now - j->first_start[t] <= best_age) continue;
        if (peer_find_lease(p, j->desc.id, (uint32_t)t, NULL)) continue;
        best_age = now - j->first_start[t];
        *out = (uint32_t)t;
        found = 1;
    }
    return found;
}

/* The part of the job's mask under tile t, row-major (the caller frees), or
 * NULL when out of memory. */
static uint8_t *job_tile_mask(const job *j, uint32_t t) {
    const tile_rect *r = &j->rects[t];
    uint8_t *m = malloc((size_t)tile_width(r) * (size_t)tile_height(r)), *out = m;
    for (int y = r->y0; m && y < r->y1; y++, out += tile_width(r))
        memcpy(out, j->mask + (size_t)y * (size_t)j->desc.width + (size_t)r->x0, (size_t)tile_width(r));
    return m;
}

static int peer_assign(peer *p, job *j, uint32_t t, int backup) {
    proto_assign a = {j->desc.id, t, j->rects[t], j->first, j->count, NULL};
    lease *l = calloc(1, sizeof *l);
    if (!l || (j->mask && !(a.mask = job_tile_mask(j, t)))) {
        farm_log(p->f, "out of memory assigning tile %u of job %u; it stays queued", t, j->desc.id);
        free(l);
        job_enqueue(j, t);
        return -1;
    }
    double now = farm_now(p->f);
    *l = (lease){j, t, now, 1, p->leases};
    p->leases = l;
    if (j->holders[t]++ == 0) j->first_start[t] = now;
    if (backup) j->rep.backups++;
    p->credits--;
    peer_tell_job(p, j);
    peer_send_json(p, proto_assign_json(&a));
    free(a.mask);
    return 0;
}

/* Use p's credits on queued tiles, then on backups. */
static void peer_schedule(peer *p) {
    farm *f = p->f;
    if (p->state != PEER_ACTIVE || p->blocked || conn_is_closing(p->c)) return;
    for (job *j = f->jobs; j && p->credits > 0; j = j->next) {
        uint32_t t;
        while (!j->finished && p->credits > 0 && job_dequeue(j, &t))
            if (peer_assign(p, j, t, 0)) return;
        while (!j->finished && p->credits > 0 && j->q_len == 0 && job_pick_backup(f, j, p, &t))
            if (peer_assign(p, j, t, 1)) return;
    }
}

static void farm_schedule_all(farm *f) {
    for (peer *p = f->peers; p; p = p->next)
        if (p->credits > 0) peer_schedule(p);
}

/* ---- results ------------------------------------------------------------------ */

/* Check pixels: finite, not negative. Returns the index of the first bad
 * float, or -1. */
static long tile_first_bad(const uint8_t *px, size_t floats) {
    for (size_t i = 0; i < floats; i++) {
        float v = wire_get_f32(px + 4 * i);
        if (!isfinite(v) || v < 0) return (long)i;
    }
    return -1;
}

static void job_stitch(job *j, const proto_tile *h, const uint8_t *px) {
    const tile_rect *r = &j->rects[h->tile];
    size_t w = (size_t)tile_width(r), ch = (size_t)j->channels;
    for (int y = r->y0; y < r->y1; y++) {
        float *row = j->rgb + ch * ((size_t)y * (size_t)j->desc.width + (size_t)r->x0);
        const uint8_t *src = px + 4 * ch * (size_t)(y - r->y0) * w;
        for (size_t i = 0; i < ch * w; i++) row[i] = wire_get_f32(src + 4 * i);
    }
}

/* Another copy of tile t won: tell the other holders to stop. */
static void job_cancel_copies(farm *f, job *j, uint32_t t, peer *winner) {
    for (peer *p = f->peers; p; p = p->next) {
        if (p == winner) continue;
        lease *l = peer_find_lease(p, j->desc.id, t, NULL);
        if (!l || !l->live) continue;
        l->live = 0;
        j->holders[t]--;
        peer_send_ids(p, "cancel", j->desc.id, t);
    }
}

static int on_tile(peer *p, const uint8_t *body, size_t len) {
    farm *f = p->f;
    char err[256];
    proto_tile h;
    if (proto_tile_parse(body, len, &h, err, sizeof err)) return peer_violation(p, "%s", err);
    job *j = farm_find_job(f, h.job);
    if (!peer_told_job(p, h.job))
        return peer_violation(p, "sent tile %u of job %u, a job it was not given", h.tile, h.job);
    if (!j) return 0; /* a job that ended and was forgotten: a late result */
    lease **link, *l = peer_find_lease(p, h.job, h.tile, &link);
    if (!l) return peer_violation(p, "sent tile %u of job %u, which was not assigned to it", h.tile, h.job);
    const tile_rect *r = &j->rects[h.tile];
    if (h.width != (uint32_t)tile_width(r) || h.height != (uint32_t)tile_height(r))
        return peer_violation(p, "sent tile %u of job %u as %ux%u pixels; it is %dx%d", h.tile, h.job, h.width,
                              h.height, tile_width(r), tile_height(r));
    if (h.channels != (uint32_t)j->channels)
        return peer_violation(p, "sent tile %u of job %u with %u values per pixel; the job needs %d", h.tile, h.job,
                              h.channels, j->channels);
    const uint8_t *px = body + PROTO_TILE_HEADER_BYTES;
    long bad = tile_first_bad(px, (size_t)h.width * h.height * h.channels);
    if (bad >= 0)
        return peer_violation(p, "sent tile %u of job %u with a NaN, infinite or negative value (float %ld)",
                              h.tile, h.job, bad);
    double took = farm_now(f) - l->start;
    int was_live = l->live;
    *link = l->next;
    free(l);
    if (was_live) j->holders[h.tile]--;
    if (j->finished || j->done[h.tile]) {
        j->rep.duplicates++;
        if (f->opt.verbose) farm_log(f, "%s: tile %u of job %u was already done; dropped", p->label, h.tile, h.job);
        return 0;
    }
    if (!was_live && f->opt.verbose)
        farm_log(f, "%s: late result for tile %u of job %u used (nobody had finished it)", p->label, h.tile, h.job);
    job_stitch(j, &h, px);
    if (j->on_tile && j->on_tile(j->ctx, h.tile, &j->rects[h.tile], err, sizeof err)) {
        job_fail(f, j, "%s", err);
        return 0;
    }
    j->done[h.tile] = 1;
    j->rep.tiles_done++;
    j->tile_seconds += took;
    trace_stats_add(&j->rep.stats, &h.stats);
    p->rec.tiles++;
    p->rec.samples += h.stats.samples;
    if (j->holders[h.tile]) job_cancel_copies(f, j, h.tile, p);
    if (j->rep.tiles_done == j->tile_count) job_finish(f, j);
    return 0;
}

/* ---- control messages ---------------------------------------------------------- */

static void peer_unlink(farm *f, peer *p) {
    for (peer **pp = &f->peers; *pp; pp = &(*pp)->next)
        if (*pp == p) {
            *pp = p->next;
            break;
        }
}

/* Give a client's connection to opt.on_client and forget the peer. */
static void peer_hand_over(peer *p, const cJSON *hello) {
    farm *f = p->f;
    conn *c = p->c;
    char addr[64];
    snprintf(addr, sizeof addr, "%s", p->rec.addr);
    peer_unlink(f, p);
    free(p->scenes);
    free(p->jobs);
    free(p);
    f->opt.on_client(f->opt.client_ctx, c, hello, addr);
}

void farm_add_proof(const farm *f, const cJSON *hello, cJSON *welcome) {
    const cJSON *nonce = cJSON_GetObjectItemCaseSensitive(hello, "nonce");
    if (!f->opt.auth.enabled || !cJSON_IsString(nonce)) return;
    char proof[AUTH_HEX];
    auth_proof(&f->opt.auth, nonce->valuestring, "coordinator", proof);
    cJSON_AddStringToObject(welcome, "proof", proof);
}

static int on_hello(peer *p, const cJSON *m) {
    farm *f = p->f;
    const cJSON *proto = cJSON_GetObjectItemCaseSensitive(m, "protocol");
    const cJSON *build = cJSON_GetObjectItemCaseSensitive(m, "build");
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(m, "name");
    const cJSON *threads = cJSON_GetObjectItemCaseSensitive(m, "threads");
    if (!cJSON_IsNumber(proto) || !cJSON_IsString(build) || !cJSON_IsString(name) || !cJSON_IsNumber(threads) ||
        !(threads->valuedouble >= 1 && threads->valuedouble <= 4096))
        return peer_violation(p, "hello: expected protocol, build, name and threads (1 to 4096)");
    snprintf(p->rec.name, sizeof p->rec.name, "%s", name->valuestring);
    snprintf(p->label, sizeof p->label, "worker %s (%s)", p->rec.name, p->rec.addr);
    const cJSON *role = cJSON_GetObjectItemCaseSensitive(m, "role");
    int is_client = cJSON_IsString(role) && strcmp(role->valuestring, "client") == 0;
    if (f->opt.auth.enabled) {
        char who[128];
        snprintf(who, sizeof who, "%s:%s", is_client ? "client" : "worker", name->valuestring);
        const cJSON *proof = cJSON_GetObjectItemCaseSensitive(m, "proof");
        if (!auth_check(&f->opt.auth, p->nonce, who, cJSON_IsString(proof) ? proof->valuestring : NULL)) {
            /* Says nothing else: an outsider learns no version, job or worker. */
            farm_log(f, "peer %s (calling itself %s %.60s): authentication failed (%s token); refused", p->rec.addr,
                     is_client ? "client" : "worker", name->valuestring, cJSON_IsString(proof) ? "wrong" : "no");
            p->rec.name[0] = '\0';
            return peer_refuse(p, "refused", "authentication failed");
        }
    }
    if (is_client) {
        if (!f->opt.on_client) return peer_violation(p, "this coordinator takes no clients (it renders one scene)");
        if (proto->valuedouble != PROTOCOL_VERSION)
            return peer_violation(p, "version mismatch: client speaks protocol %g; coordinator speaks protocol %d",
                                  proto->valuedouble, PROTOCOL_VERSION);
        peer_hand_over(p, m);
        return 0; /* the connection lives on with the client's callbacks */
    }
    if (proto->valuedouble != PROTOCOL_VERSION || strcmp(build->valuestring, protocol_build_id()) != 0) {
        char reason[400];
        snprintf(reason, sizeof reason,
                 "version mismatch: worker speaks protocol %g, build %.100s; coordinator speaks protocol %d, "
                 "build %s",
                 proto->valuedouble, build->valuestring, PROTOCOL_VERSION, protocol_build_id());
        farm_log(f, "%s refused: %s", p->label, reason);
        return peer_refuse(p, "refused", reason);
    }
    p->rec.threads = (int)threads->valuedouble;
    p->state = PEER_ACTIVE;
    size_t max_frame = proto_tile_frame_max(f->opt.max_tile_side);
    conn_set_max_frame(p->c, max_frame > WIRE_JSON_MAX + 1 ? max_frame : WIRE_JSON_MAX + 1);
    cJSON *w = cJSON_CreateObject();
    cJSON_AddStringToObject(w, "type", "welcome");
    cJSON_AddNumberToObject(w, "protocol", PROTOCOL_VERSION);
    cJSON_AddStringToObject(w, "build", protocol_build_id());
    cJSON_AddNumberToObject(w, "heartbeat_ms", f->opt.heartbeat_s * 1e3);
    cJSON_AddNumberToObject(w, "timeout_ms", f->opt.timeout_s * 1e3);
    farm_add_proof(f, m, w);
    peer_send_json(p, w);
    if (f->opt.verbose) farm_log(f, "%s joined with %d threads", p->label, p->rec.threads);
    return 0;
}

static int read_tile_ids(peer *p, const cJSON *m, const char *type, uint32_t *job, uint32_t *tile) {
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(m, "job"), *t = cJSON_GetObjectItemCaseSensitive(m, "tile");
    if (!cJSON_IsNumber(j) || !cJSON_IsNumber(t) || j->valuedouble < 0 || t->valuedouble < 0 ||
        j->valuedouble > UINT32_MAX || t->valuedouble > UINT32_MAX) {
        peer_violation(p, "%s: expected job and tile numbers", type);
        return -1;
    }
    *job = (uint32_t)j->valuedouble;
    *tile = (uint32_t)t->valuedouble;
    return 0;
}

/* "cancelled" or "failed": p gives a tile back. */
static int on_give_back(peer *p, const cJSON *m, int failed) {
    farm *f = p->f;
    uint32_t job_id, tile;
    if (read_tile_ids(p, m, failed ? "failed" : "cancelled", &job_id, &tile)) return 1;
    lease **link, *l = peer_find_lease(p, job_id, tile, &link);
    if (!l) return 0; /* its result or an earlier answer already settled it */
    job *j = l->job;
    *link = l->next;
    if (failed) {
        const cJSON *r = cJSON_GetObjectItemCaseSensitive(m, "reason");
        const char *why = cJSON_IsString(r) ? r->valuestring : "no reason given";
        farm_log(f, "%s: tile %u of job %u failed: %.300s", p->label, tile, job_id, why);
        if (++p->failures >= MAX_PEER_FAILURES && !p->blocked) {
            p->blocked = 1;
            farm_log(f, "%s failed %d tiles; it gets no more work", p->label, p->failures);
        }
        if (!j->finished && ++j->failures[tile] >= MAX_TILE_FAILURES) {
            lease_release(l);
            free(l);
            job_fail(f, j, "tile %u failed %d times, last on %s: %.300s", tile, MAX_TILE_FAILURES, p->label, why);
            return 0;
        }
    }
    lease_release(l);
    free(l);
    farm_schedule_all(f);
    return 0;
}

static int on_json(peer *p, const uint8_t *body, size_t len) {
    char err[256];
    const char *type;
    cJSON *m = proto_parse_json(body, len, &type, err, sizeof err);
    if (!m) return peer_violation(p, "%s", err);
    int rc = 0;
    if (p->state == PEER_HELLO) {
        rc = strcmp(type, "hello") == 0 ? on_hello(p, m) : peer_violation(p, "expected hello, got \"%.40s\"", type);
    } else if (strcmp(type, "ready") == 0) {
        const cJSON *s = cJSON_GetObjectItemCaseSensitive(m, "slots");
        if (!cJSON_IsNumber(s) || s->valuedouble < 1 || p->credits + s->valuedouble > MAX_CREDITS) {
            rc = peer_violation(p, "ready: slots must be a number from 1 to %d in all", MAX_CREDITS);
        } else {
            p->credits += (int)s->valuedouble;
            peer_schedule(p);
        }
    } else if (strcmp(type, "cancelled") == 0 || strcmp(type, "failed") == 0) {
        rc = on_give_back(p, m, type[0] == 'f');
    } else if (strcmp(type, "bye") == 0) {
        conn_close(p->c, "worker left", 0);
        rc = 1;
    } else if (strcmp(type, "heartbeat") != 0) {
        rc = peer_violation(p, "unknown message type \"%.40s\"", type);
    }
    cJSON_Delete(m);
    return rc;
}

static int on_frame(conn *c, int kind, const uint8_t *body, size_t len) {
    peer *p = conn_data(c);
    farm *f = p->f;
    p->last_heard = farm_now(f);
    if (p->state == PEER_STALLED) {
        p->state = PEER_ACTIVE;
        farm_log(f, "%s is responding again", p->label);
    }
    if (kind == WIRE_KIND_JSON) return on_json(p, body, len);
    if (kind == WIRE_KIND_TILE && p->state != PEER_HELLO) return on_tile(p, body, len);
    return peer_violation(p, "unexpected frame kind 0x%02x%s", kind, p->state == PEER_HELLO ? " before hello" : "");
}

/* ---- connections --------------------------------------------------------------- */

static void peer_record_departure(farm *f, peer *p, const char *why) {
    p->rec.bytes_in = conn_bytes_in(p->c);
    p->rec.bytes_out = conn_bytes_out(p->c);
    p->rec.left = farm_now(f);
    snprintf(p->rec.why, sizeof p->rec.why, "%s", why);
    f->closed_bytes_in += p->rec.bytes_in;
    f->closed_bytes_out += p->rec.bytes_out;
    if (p->state == PEER_HELLO && p->rec.name[0] == '\0') return; /* never introduced itself */
    if (f->departed_count == f->departed_cap) {
        int cap = f->departed_cap ? 2 * f->departed_cap : 16;
        peer_record *d = realloc(f->departed, (size_t)cap * sizeof *d);
        if (!d) return;
        f->departed = d;
        f->departed_cap = cap;
    }
    f->departed[f->departed_count++] = p->rec;
}

static void on_conn_close(conn *c, const char *reason) {
    peer *p = conn_data(c);
    farm *f = p->f;
    int requeued = 0;
    while (p->leases) {
        lease *l = p->leases;
        p->leases = l->next;
        requeued += l->live;
        lease_release(l);
        free(l);
    }
    if (conn_malformed(c))
        farm_log(f, "%s: %s; disconnecting", p->label, reason);
    else if ((p->state != PEER_HELLO && !f->closing) || f->opt.verbose)
        farm_log(f, "%s left: %s (%llu tiles done%s)", p->label, reason, (unsigned long long)p->rec.tiles,
                 requeued ? ", its unfinished tiles go back to the queue" : "");
    peer_record_departure(f, p, reason);
    peer_unlink(f, p);
    free(p->scenes);
    free(p->jobs);
    memset(p, 0xdb, sizeof *p);
    free(p);
    if (requeued && !f->closing) farm_schedule_all(f);
}

static const conn_callbacks farm_conn_cb = {on_frame, on_conn_close};

static void on_connection(uv_stream_t *server, int status) {
    farm *f = server->data;
    if (status < 0) {
        farm_log(f, "accept failed: %s", uv_strerror(status));
        return;
    }
    peer *p = calloc(1, sizeof *p);
    conn *c = p ? conn_new(f->loop, &farm_conn_cb, p, WIRE_JSON_MAX + 1) : NULL;
    if (!c) {
        free(p);
        farm_log(f, "out of memory for a new connection");
        return;
    }
    p->f = f;
    p->c = c;
    p->joined = p->last_heard = p->last_sent = farm_now(f);
    p->rec.joined = p->joined;
    if (uv_accept(server, (uv_stream_t *)conn_tcp(c)) != 0 || conn_start(c) != 0) {
        snprintf(p->label, sizeof p->label, "connection");
        p->next = f->peers;
        f->peers = p;
        conn_close(c, "accept failed", 0);
        return;
    }
    uv_tcp_nodelay(conn_tcp(c), 1);
    conn_peer_address(c, p->rec.addr, sizeof p->rec.addr);
    snprintf(p->label, sizeof p->label, "peer %s", p->rec.addr);
    p->next = f->peers;
    f->peers = p;
    auth_nonce(p->nonce);
    cJSON *ch = cJSON_CreateObject();
    cJSON_AddStringToObject(ch, "type", "challenge");
    cJSON_AddStringToObject(ch, "nonce", p->nonce);
    peer_send_json(p, ch);
}

/* ---- the clock: heartbeats, stalls, leases --------------------------------------- */

static void peer_stall(peer *p, double silent) {
    p->state = PEER_STALLED;
    int n = 0;
    for (lease *l = p->leases; l; l = l->next) {
        n += l->live;
        lease_release(l);
    }
    farm_log(p->f, "%s silent for %.1f s: %d tiles go back to the queue", p->label, silent, n);
}

static void peer_check(peer *p, double now) {
    farm *f = p->f;
    double silent = now - p->last_heard;
    if (p->state == PEER_HELLO && silent > HELLO_TIMEOUT_S) {
        conn_close(p->c, "no hello within 10 s", 0);
        return;
    }
    if (p->state == PEER_HELLO) return;
    if (silent > f->opt.drop_s) {
        char why[96];
        snprintf(why, sizeof why, "silent for %.1f s", silent);
        conn_close(p->c, why, 0);
        return;
    }
    if (p->state == PEER_ACTIVE && silent > f->opt.timeout_s) peer_stall(p, silent);
    for (lease *l = p->leases; l; l = l->next)
        if (l->live && now - l->start > f->opt.lease_s) {
            farm_log(f, "%s held tile %u of job %u for %.0f s, past its lease; it goes back to the queue", p->label,
                     l->tile, l->job->desc.id, now - l->start);
            lease_release(l);
        }
    if (now - p->last_sent >= f->opt.heartbeat_s) {
        size_t len;
        uint8_t *frame = proto_frame_simple("heartbeat", &len);
        peer_send(p, frame, len);
    }
}

static void on_tick(uv_timer_t *t) {
    farm *f = t->data;
    double now = farm_now(f);
    for (peer *p = f->peers, *next; p; p = next) {
        next = p->next; /* p may be closed (but is freed only later) */
        if (!conn_is_closing(p->c)) peer_check(p, now);
    }
    farm_schedule_all(f);
    for (job *j = f->jobs; j; j = j->next)
        if (!j->finished && j->cb && j->reported != j->rep.tiles_done) {
            farm_report r;
            farm_report_fill(f, j, &r);
            j->reported = j->rep.tiles_done;
            j->cb(j->ctx, &r, 0);
        }
}

/* ---- public ------------------------------------------------------------------ */

farm *farm_new(uv_loop_t *loop, const farm_options *o, char *err, size_t err_len) {
    farm *f = calloc(1, sizeof *f);
    if (!f) {
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    f->loop = loop;
    f->opt = *o;
    struct sockaddr_storage addr;
    int rc = uv_ip4_addr(o->host, o->port, (struct sockaddr_in *)&addr);
    if (rc) rc = uv_ip6_addr(o->host, o->port, (struct sockaddr_in6 *)&addr);
    if (rc) {
        snprintf(err, err_len, "cannot listen on %s:%d: not a numeric IPv4 or IPv6 address", o->host, o->port);
        free(f);
        return NULL;
    }
    uv_tcp_init(loop, &f->listener);
    f->listener.data = f;
    rc = uv_tcp_bind(&f->listener, (struct sockaddr *)&addr, 0);
    if (rc == 0) rc = uv_listen((uv_stream_t *)&f->listener, 1024, on_connection);
    if (rc) {
        snprintf(err, err_len, "cannot listen on %s:%d: %s", o->host, o->port, uv_strerror(rc));
        uv_close((uv_handle_t *)&f->listener, NULL);
        uv_run(loop, UV_RUN_NOWAIT); /* let the close finish before freeing */
        free(f);
        return NULL;
    }
    int n = sizeof addr;
    uv_tcp_getsockname(&f->listener, (struct sockaddr *)&addr, &n);
    f->port = ntohs(addr.ss_family == AF_INET ? ((struct sockaddr_in *)&addr)->sin_port
                                               : ((struct sockaddr_in6 *)&addr)->sin6_port);
    uv_timer_init(loop, &f->tick);
    f->tick.data = f;
    uv_timer_start(&f->tick, on_tick, FARM_TICK_MS, FARM_TICK_MS);
    return f;
}

int farm_port(const farm *f) { return f->port; }

int farm_submit(farm *f, const proto_job *desc, const uint8_t *bundle, size_t bundle_len,
                const farm_job_options *o, float *rgb, farm_job_cb cb, void *ctx) {
    job *j = calloc(1, sizeof *j);
    if (!j) return -1;
    j->desc = *desc;
    j->tile_size = o->tile_size;
    j->priority = o->priority;
    j->on_tile = o->on_tile;
    j->rgb = rgb;
    j->channels = desc->adaptive ? ADAPTIVE_CHANNELS : 3;
    j->mask = desc->adaptive ? o->mask : NULL;
    j->first = desc->adaptive ? o->first : 0;
    j->count = desc->adaptive ? o->count : (uint32_t)desc->spp;
    j->cb = cb;
    j->ctx = ctx;
    j->tile_count = render_split_tiles(desc->width, desc->height, o->tile_size, NULL, 0);
    size_t n = (size_t)j->tile_count;
    j->rects = calloc(n, sizeof *j->rects);
    j->done = calloc(n, 1);
    j->holders = calloc(n, 1);
    j->queued = calloc(n, 1);
    j->failures = calloc(n, 1);
    j->first_start = calloc(n, sizeof *j->first_start);
    j->queue = calloc(n, sizeof *j->queue);
    j->scene = bundle_len < UINT32_MAX ? conn_blob_new(WIRE_HEADER_BYTES + bundle_len) : NULL;
    if (!j->rects || !j->done || !j->holders || !j->queued || !j->failures || !j->first_start || !j->queue ||
        !j->scene) {
        job_free(j);
        return -1;
    }
    wire_put_u32(j->scene->data, (uint32_t)(bundle_len + 1));
    j->scene->data[4] = WIRE_KIND_SCENE;
    memcpy(j->scene->data + WIRE_HEADER_BYTES, bundle, bundle_len);
    render_split_tiles(desc->width, desc->height, o->tile_size, j->rects, j->tile_count);
    for (int t = 0; t < j->tile_count; t++) {
        if (o->done && o->done[t]) {
            j->done[t] = 1;
            j->rep.tiles_done++;
        }
        job_enqueue(j, (uint32_t)t);
    }
    j->reported = j->rep.tiles_done;
    job **pp = &f->jobs; /* by priority, then submission order */
    while (*pp && (*pp)->priority >= j->priority) pp = &(*pp)->next;
    j->next = *pp;
    *pp = j;
    if (j->rep.tiles_done == j->tile_count)
        job_finish(f, j);
    else
        farm_schedule_all(f);
    return 0;
}

int farm_cancel(farm *f, uint32_t id) {
    job *j = farm_find_job(f, id);
    if (!j || j->finished) return -1;
    j->rep.cancelled = 1;
    snprintf(j->rep.error, sizeof j->rep.error, "cancelled");
    job_finish(f, j);
    farm_schedule_all(f); /* the freed workers take other jobs */
    return 0;
}

int farm_forget(farm *f, uint32_t id) {
    for (job **pp = &f->jobs; *pp; pp = &(*pp)->next)
        if ((*pp)->desc.id == id) {
            job *j = *pp;
            if (!j->finished) return -1;
            for (peer *p = f->peers; p; p = p->next) /* leases of it die with it */
                for (lease **lp = &p->leases; *lp;) {
                    lease *l = *lp;
                    if (l->job == j) {
                        *lp = l->next;
                        free(l);
                    } else {
                        lp = &l->next;
                    }
                }
            *pp = j->next;
            job_free(j);
            return 0;
        }
    return -1;
}

int farm_list_workers(const farm *f, farm_worker_info *out, int max) {
    int n = 0;
    double now = farm_now(f);
    for (const peer *p = f->peers; p; p = p->next) {
        if (p->state == PEER_HELLO) continue;
        if (n < max) {
            farm_worker_info *w = &out[n];
            memset(w, 0, sizeof *w);
            snprintf(w->name, sizeof w->name, "%s", p->rec.name);
            snprintf(w->addr, sizeof w->addr, "%s", p->rec.addr);
            w->threads = p->rec.threads;
            w->stalled = p->state == PEER_STALLED;
            w->tiles = p->rec.tiles;
            w->samples = p->rec.samples;
            w->connected_s = now - p->joined;
            w->silent_s = now - p->last_heard;
        }
        n++;
    }
    return n;
}

int farm_job_report(const farm *f, uint32_t id, farm_report *r) {
    const job *j = farm_find_job(f, id);
    if (!j) return -1;
    farm_report_fill(f, j, r);
    return 0;
}

static void print_record(FILE *out, const peer_record *r, const char *state, uint64_t in, uint64_t out_b) {
    fprintf(out, "  %-20s %-22s %3d threads %6llu tiles %8.2f Msamples  in %8.1f KiB  out %8.1f KiB  %s\n",
            r->name, r->addr, r->threads, (unsigned long long)r->tiles, (double)r->samples / 1e6,
            (double)in / 1024.0, (double)out_b / 1024.0, state);
}

void farm_print_workers(const farm *f, FILE *out) {
    for (const peer *p = f->peers; p; p = p->next)
        if (p->state != PEER_HELLO)
            print_record(out, &p->rec, p->state == PEER_STALLED ? "stalled" : "connected", conn_bytes_in(p->c),
                         conn_bytes_out(p->c));
    for (int i = 0; i < f->departed_count; i++) {
        char state[160];
        snprintf(state, sizeof state, "left: %s", f->departed[i].why);
        print_record(out, &f->departed[i], state, f->departed[i].bytes_in, f->departed[i].bytes_out);
    }
}

static void on_handle_closed(uv_handle_t *h) {
    farm *f = h->data;
    if (--f->open_handles == 0 && f->closed_cb) f->closed_cb(f->closed_ctx);
}

void farm_close(farm *f, void (*cb)(void *ctx), void *ctx) {
    f->closing = 1;
    f->closed_cb = cb;
    f->closed_ctx = ctx;
    for (peer *p = f->peers, *next; p; p = next) {
        next = p->next;
        conn_close(p->c, "the coordinator is done", 1);
    }
    f->open_handles = 2;
    uv_close((uv_handle_t *)&f->listener, on_handle_closed);
    uv_close((uv_handle_t *)&f->tick, on_handle_closed);
}

void farm_free(farm *f) {
    if (!f) return;
    while (f->jobs) {
        job *j = f->jobs;
        f->jobs = j->next;
        job_free(j);
    }
    free(f->departed);
    free(f);
}
