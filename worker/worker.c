/* worker.c - the worker's event loop: connection, handshake, messages from
 * the coordinator, results back to it (see worker.h, docs/protocol.md).
 *
 * Everything here runs on the loop thread. Render threads (pool.c) hand
 * finished tiles back through an async handle; each finished task frees a
 * slot, announced to the coordinator with a "ready" message (pull-based
 * scheduling: the coordinator never sends more tiles than asked for). Each
 * connection has a generation number: results of tiles given on an earlier
 * connection are dropped, never sent to a coordinator that did not ask. */
#include "worker.h"

#include <stdarg.h>
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include <uv.h>

#include "log.h"
#include "net/address.h"
#include "net/conn.h"
#include "job/job.h"
#include "net/protocol.h"
#include "net/wire.h"
#include "pool.h"

#define TICK_MS 100

typedef struct {
    char hash[SCENE_BUNDLE_HASH_HEX];
    uint8_t *bytes;
    size_t len;
} cached_bundle;

typedef struct {
    worker_config cfg;
    char where[300]; /* the coordinator's HOST:PORT as logs print it ([V6]:PORT) */
    uv_loop_t loop;
    pool *pool;
    uv_async_t wake;
    uv_timer_t tick;
    uv_signal_t sigterm, sigint;
    uv_getaddrinfo_t resolve;
    uv_connect_t connect;
    conn *c;
    int resolving, connected, welcomed;
    uint64_t generation;
    int held;             /* tasks pushed and not yet back from the pool */
    double backoff;       /* seconds before the next attempt */
    double next_attempt;  /* loop time (s) of the next connection attempt */
    double last_heard, last_sent, last_tick;
    double last_work;     /* loop time (s) a tile was last in hand (--idle-exit) */
    double last_welcomed; /* loop time (s) a coordinator was last connected */
    double heartbeat_s, timeout_s;
    char nonce[AUTH_HEX]; /* ours, for the coordinator to prove itself */
    char challenge[200];  /* the coordinator's nonce: with ours, the link's keys */
    /* The bundles this connection sent, until it says forget_scene: the
     * coordinator decides which are kept (FARM_PEER_SCENES, farm_sched.c),
     * so both sides agree on them. */
    cached_bundle *bundles;
    int bundle_count;
    int stopping, exit_code;
    unsigned long tiles_sent;
    char label[160]; /* "worker NAME" for logs */
} worker;

static void close_handles(worker *w);
static void check_idle(worker *w, double now);

static double now_s(worker *w) { return (double)uv_now(&w->loop) / 1e3; }

static void worker_log(worker *w, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void worker_log(worker *w, const char *fmt, ...) {
    char who[128];
    snprintf(who, sizeof who, "tessera-worker %s", w->cfg.name);
    va_list ap;
    va_start(ap, fmt);
    log_vline(NULL, LOG_INFO, who, fmt, ap);
    va_end(ap);
}

/* The pool's lines (scenes loaded, or why not), from a render thread:
 * log_vline writes each whole. */
static void pool_log_line(void *ctx, const char *line) { worker_log(ctx, "%s", line); }

static int capacity(const worker *w) { return w->cfg.threads + w->cfg.prefetch; }

/* Send a frame if connected; frees it otherwise. */
static void worker_send(worker *w, uint8_t *frame, size_t len) {
    if (!frame) return;
    if (!w->c || !w->welcomed) {
        free(frame);
        return;
    }
    conn_send(w->c, frame, len);
    w->last_sent = now_s(w);
}

static void send_json(worker *w, cJSON *m) {
    size_t len;
    uint8_t *f = m ? wire_frame_json(m, &len) : NULL;
    cJSON_Delete(m);
    if (f) worker_send(w, f, len);
}

static void send_ready(worker *w, int slots) {
    if (slots <= 0) return;
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", "ready");
    cJSON_AddNumberToObject(m, "slots", slots);
    send_json(w, m);
}

/* {"type": TYPE, "job": J, "tile": T[, "reason": R]} */
static void send_tile_note(worker *w, const char *type, const proto_assign *a, const char *reason) {
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", type);
    cJSON_AddNumberToObject(m, "job", a->job);
    cJSON_AddNumberToObject(m, "tile", a->tile);
    if (reason) cJSON_AddStringToObject(m, "reason", reason);
    send_json(w, m);
}

static void forget_bundles(worker *w) {
    for (int i = 0; i < w->bundle_count; i++) free(w->bundles[i].bytes);
    free(w->bundles);
    w->bundles = NULL;
    w->bundle_count = 0;
}

/* The cached bundle of this hash, or NULL. */
static cached_bundle *find_bundle(worker *w, const char *hash) {
    for (int i = 0; i < w->bundle_count; i++)
        if (strcmp(w->bundles[i].hash, hash) == 0) return &w->bundles[i];
    return NULL;
}

/* ---- finished tiles ------------------------------------------------------ */

static void on_wake(uv_async_t *a) {
    worker *w = a->data;
    int freed = 0;
    if (!w->pool) return;
    for (pool_task *t = pool_take_done(w->pool), *next; t; t = next) {
        next = STAILQ_NEXT(t, link);
        w->held--;
        freed++;
        if (t->generation == w->generation && w->welcomed) {
            if (t->status == TASK_DONE) {
                worker_send(w, t->frame, t->frame_len);
                t->frame = NULL;
                w->tiles_sent++;
            } else if (t->status == TASK_FAILED) {
                worker_log(w, "tile %u of job %u failed: %s", t->assign.tile, t->assign.job, t->error);
                send_tile_note(w, "failed", &t->assign, t->error);
            } else {
                send_tile_note(w, "cancelled", &t->assign, NULL);
            }
        }
        pool_task_free(w->pool, t);
    }
    if (w->welcomed && !w->stopping) send_ready(w, freed);
}

static void send_hello(worker *w, const char *challenge);

/* ---- messages from the coordinator ----------------------------------------- */

/* Close the connection over a protocol error; returns 1 for on_frame. */
static int protocol_error(worker *w, conn *c, const char *reason) {
    worker_log(w, "coordinator broke the protocol: %s; disconnecting", reason);
    conn_close(c, reason, 0);
    return 1;
}

static int on_welcome(worker *w, conn *c, const cJSON *m) {
    const cJSON *proof = cJSON_GetObjectItemCaseSensitive(m, "proof");
    if (w->cfg.auth.enabled &&
        !auth_check(&w->cfg.auth, w->nonce, "coordinator", cJSON_IsString(proof) ? proof->valuestring : NULL))
        return protocol_error(w, c, "the coordinator could not prove it knows the token");
    if (w->cfg.auth.enabled) { /* every frame from here on is sealed (conn_seal) */
        unsigned char down[AUTH_KEY_BYTES], up[AUTH_KEY_BYTES];
        auth_link_keys(&w->cfg.auth, w->challenge, w->nonce, down, up);
        conn_seal(c, up, down);
        sodium_memzero(down, sizeof down);
        sodium_memzero(up, sizeof up);
    }
    const cJSON *hb = cJSON_GetObjectItemCaseSensitive(m, "heartbeat_ms");
    const cJSON *to = cJSON_GetObjectItemCaseSensitive(m, "timeout_ms");
    if (!cJSON_IsNumber(hb) || !cJSON_IsNumber(to) || !(hb->valuedouble >= 10) || !(to->valuedouble > hb->valuedouble))
        return protocol_error(w, c, "welcome: heartbeat_ms and timeout_ms must be numbers, 10 <= heartbeat < timeout");
    w->heartbeat_s = hb->valuedouble / 1e3;
    w->timeout_s = to->valuedouble / 1e3;
    w->welcomed = 1;
    w->backoff = 0.1;
    conn_set_max_frame(c, SCENE_BUNDLE_MAX_BYTES + 1); /* scene bundles may follow */
    if (!w->cfg.quiet)
        worker_log(w, "joined the farm at %s (%d threads, %d prefetch)", w->where, w->cfg.threads, w->cfg.prefetch);
    send_ready(w, capacity(w) - w->held);
    return 0;
}

static int on_job(worker *w, conn *c, const cJSON *m) {
    char err[512];
    proto_job d;
    if (proto_job_parse(m, "coordinator", &d, err, sizeof err)) return protocol_error(w, c, err);
    if (pool_job_find(w->pool, d.id)) return protocol_error(w, c, "job: id already in use");
    cached_bundle *cb = find_bundle(w, d.scene_hash);
    int pinned = !cb && pool_pinned(w->pool, d.scene_hash); /* claimed in the hello: loaded here already */
    if (!cb && !pinned) {
        snprintf(err, sizeof err, "job %u: scene %s was never sent", d.id, d.scene_hash);
        return protocol_error(w, c, err);
    }
    int shared;
    if (!pool_job_new(w->pool, &d, cb ? cb->bytes : NULL, cb ? cb->len : 0, &shared, err, sizeof err))
        return protocol_error(w, c, err);
    if (w->cfg.verbose)
        worker_log(w, "job %u: scene %.12s, %dx%d, %d spp%s", d.id, d.scene_hash, d.width, d.height, d.spp,
                   pinned   ? " (its scene was loaded before this worker started: shared with the coordinator's "
                              "pages, not loaded again)"
                   : shared ? " (its scene is already loaded or loading here: shared, not loaded again)"
                            : "");
    return 0;
}

static int on_assign(worker *w, conn *c, const cJSON *m) {
    char err[512];
    proto_assign a;
    if (proto_assign_parse(m, "coordinator", &a, err, sizeof err)) return protocol_error(w, c, err);
    pool_job *j = pool_job_find(w->pool, a.job);
    if (!j) {
        free(a.mask);
        snprintf(err, sizeof err, "assign: tile %u of unknown job %u", a.tile, a.job);
        return protocol_error(w, c, err);
    }
    if (pool_push(w->pool, j, &a, w->generation)) { /* the task owns a.mask once pushed */
        free(a.mask);
        return protocol_error(w, c, "out of memory for a tile");
    }
    w->held++;
    w->last_work = now_s(w);
    return 0;
}

/* Read the "job" (and "tile") numbers of a cancel/job_end message. */
static int read_ids(const cJSON *m, int want_tile, uint32_t *job, uint32_t *tile) {
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(m, "job"), *t = cJSON_GetObjectItemCaseSensitive(m, "tile");
    if (!cJSON_IsNumber(j) || j->valuedouble < 0 || j->valuedouble > UINT32_MAX) return -1;
    if (want_tile && (!cJSON_IsNumber(t) || t->valuedouble < 0 || t->valuedouble > UINT32_MAX)) return -1;
    *job = (uint32_t)j->valuedouble;
    *tile = want_tile ? (uint32_t)t->valuedouble : 0;
    return 0;
}

static int on_json(worker *w, conn *c, const uint8_t *body, size_t len) {
    char err[256];
    const char *type;
    cJSON *m = proto_parse_json(body, len, &type, err, sizeof err);
    if (!m) return protocol_error(w, c, err);
    int rc = 0;
    uint32_t job, tile;
    if (strcmp(type, "challenge") == 0 && !w->welcomed) {
        const cJSON *n = cJSON_GetObjectItemCaseSensitive(m, "nonce");
        if (cJSON_IsString(n) && strlen(n->valuestring) < 200) send_hello(w, n->valuestring);
        else rc = protocol_error(w, c, "challenge without a nonce");
    } else if (strcmp(type, "welcome") == 0) {
        rc = on_welcome(w, c, m);
    } else if (strcmp(type, "refused") == 0) {
        const cJSON *r = cJSON_GetObjectItemCaseSensitive(m, "reason");
        worker_log(w, "the coordinator refused this worker: %s", cJSON_IsString(r) ? r->valuestring : "(no reason)");
        w->exit_code = 1;
        w->stopping = 1;
        conn_close(c, "refused", 0);
        rc = 1;
    } else if (!w->welcomed) {
        rc = protocol_error(w, c, "message before the welcome");
    } else if (strcmp(type, "job") == 0) {
        rc = on_job(w, c, m);
    } else if (strcmp(type, "assign") == 0) {
        rc = on_assign(w, c, m);
    } else if (strcmp(type, "cancel") == 0) {
        if (read_ids(m, 1, &job, &tile)) rc = protocol_error(w, c, "cancel: expected job and tile numbers");
        else pool_cancel(w->pool, job, tile);
    } else if (strcmp(type, "job_end") == 0) {
        pool_job *j;
        if (read_ids(m, 0, &job, &tile)) rc = protocol_error(w, c, "job_end: expected a job number");
        else if ((j = pool_job_find(w->pool, job)) != NULL) pool_job_end(w->pool, j);
    } else if (strcmp(type, "forget_scene") == 0) {
        const cJSON *h = cJSON_GetObjectItemCaseSensitive(m, "scene");
        cached_bundle *cb = cJSON_IsString(h) ? find_bundle(w, h->valuestring) : NULL;
        if (!cb && cJSON_IsString(h) && pool_unpin(w->pool, h->valuestring)) {
            if (w->cfg.verbose) worker_log(w, "scene %.12s forgotten, as the coordinator says", h->valuestring);
        } else if (!cb) {
            rc = protocol_error(w, c, "forget_scene: not a scene this connection sent");
        } else {
            if (w->cfg.verbose) worker_log(w, "scene %.12s forgotten, as the coordinator says", cb->hash);
            free(cb->bytes);
            *cb = w->bundles[--w->bundle_count];
        }
    } else if (strcmp(type, "error") == 0) {
        const cJSON *r = cJSON_GetObjectItemCaseSensitive(m, "reason");
        worker_log(w, "coordinator says: %s", cJSON_IsString(r) ? r->valuestring : "(no reason)");
    } else if (strcmp(type, "heartbeat") != 0) {
        snprintf(err, sizeof err, "unknown message type \"%.40s\"", type);
        rc = protocol_error(w, c, err);
    }
    cJSON_Delete(m);
    return rc;
}

static int on_scene(worker *w, conn *c, const uint8_t *body, size_t len) {
    char hash[SCENE_BUNDLE_HASH_HEX];
    scene_bundle_hash(body, len, hash);
    if (find_bundle(w, hash)) return 0; /* sent again: the same bytes, held already */
    cached_bundle *b = realloc(w->bundles, (size_t)(w->bundle_count + 1) * sizeof *b);
    uint8_t *bytes = malloc(len ? len : 1);
    if (b) w->bundles = b;
    if (!b || !bytes) {
        free(bytes);
        return protocol_error(w, c, "out of memory for a scene");
    }
    memcpy(bytes, body, len);
    cached_bundle *cb = &w->bundles[w->bundle_count++];
    memcpy(cb->hash, hash, sizeof hash);
    cb->bytes = bytes;
    cb->len = len;
    return 0;
}

static int on_frame(conn *c, int kind, const uint8_t *body, size_t len) {
    worker *w = conn_data(c);
    w->last_heard = now_s(w);
    if (kind == WIRE_KIND_JSON) return on_json(w, c, body, len);
    if (kind == WIRE_KIND_SCENE && w->welcomed) return on_scene(w, c, body, len);
    char err[64];
    snprintf(err, sizeof err, "unexpected frame kind 0x%02x", kind);
    return protocol_error(w, c, err);
}

/* ---- connection ---------------------------------------------------------- */

static void schedule_retry(worker *w) {
    w->next_attempt = now_s(w) + w->backoff;
    w->backoff = w->backoff * 2 < w->cfg.retry_max_s ? w->backoff * 2 : w->cfg.retry_max_s;
}

static void on_conn_close(conn *c, const char *reason) {
    worker *w = conn_data(c);
    if (w->c != c) return;
    int was_welcomed = w->welcomed;
    w->c = NULL;
    w->connected = w->welcomed = 0;
    w->generation++;
    pool_job_end_all(w->pool); /* the next coordinator may reuse job ids */
    forget_bundles(w);
    if (w->cfg.once && !w->stopping) {
        if (!was_welcomed)
            worker_log(w, "cannot reach the coordinator at %s: %s", w->where, reason);
        else if (!w->cfg.quiet)
            worker_log(w, "connection ended (%s); exiting (--once)", reason);
        w->exit_code = was_welcomed ? 0 : 1;
        w->stopping = 1;
    }
    if (w->stopping) {
        if (!w->resolving) close_handles(w); /* exit now, not at the next tick */
        return;
    }
    worker_log(w, "%s %s: %s; retrying in %.1f s", was_welcomed ? "lost the coordinator at" : "cannot reach",
               w->where, reason, w->backoff);
    schedule_retry(w);
}

static const conn_callbacks worker_conn_cb = {on_frame, on_conn_close};

/* Answer the coordinator's challenge: hello, with a proof of the token
 * and a nonce of ours when a token is configured. */
static void send_hello(worker *w, const char *challenge) {
    snprintf(w->challenge, sizeof w->challenge, "%s", challenge);
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", "hello");
    cJSON_AddNumberToObject(m, "protocol", PROTOCOL_VERSION);
    cJSON_AddStringToObject(m, "build", protocol_build_id());
    cJSON_AddStringToObject(m, "name", w->cfg.name);
    cJSON_AddNumberToObject(m, "threads", w->cfg.threads);
    char held[PROTOCOL_HELLO_SCENES][SCENE_BUNDLE_HASH_HEX];
    int nheld = pool_pinned_hashes(w->pool, held, PROTOCOL_HELLO_SCENES);
    if (nheld > 0) { /* loaded before the first connection: the coordinator need not send them */
        cJSON *arr = cJSON_AddArrayToObject(m, "scenes");
        for (int i = 0; i < nheld; i++) cJSON_AddItemToArray(arr, cJSON_CreateString(held[i]));
    }
    if (w->cfg.auth.enabled) {
        char who[128], proof[AUTH_HEX];
        snprintf(who, sizeof who, "worker:%s", w->cfg.name);
        auth_proof(&w->cfg.auth, challenge, who, proof);
        auth_nonce(w->nonce);
        cJSON_AddStringToObject(m, "proof", proof);
        cJSON_AddStringToObject(m, "nonce", w->nonce);
    }
    size_t len;
    uint8_t *f = wire_frame_json(m, &len);
    cJSON_Delete(m);
    if (f) conn_send(w->c, f, len);
}

static void on_connected(uv_connect_t *req, int status) {
    worker *w = req->data;
    if (!w->c || conn_tcp(w->c) != (uv_tcp_t *)req->handle) return;
    if (status == 0) status = conn_start(w->c);
    if (status != 0) {
        conn_close(w->c, uv_strerror(status), 0);
        return;
    }
    uv_tcp_nodelay(conn_tcp(w->c), 1); /* small control messages must not wait for Nagle */
    w->connected = 1;
    w->last_heard = now_s(w); /* the coordinator speaks first: a challenge */
}

static void on_resolved(uv_getaddrinfo_t *req, int status, struct addrinfo *res) {
    worker *w = req->data;
    w->resolving = 0;
    if (w->stopping) {
        uv_freeaddrinfo(res);
        return;
    }
    if (status != 0) {
        if (w->cfg.once) {
            worker_log(w, "cannot resolve %s: %s", w->cfg.host, uv_strerror(status));
            w->exit_code = 1;
            w->stopping = 1;
        } else {
            worker_log(w, "cannot resolve %s: %s; retrying in %.1f s", w->cfg.host, uv_strerror(status), w->backoff);
            schedule_retry(w);
        }
        return;
    }
    w->c = conn_new(&w->loop, &worker_conn_cb, w, WIRE_JSON_MAX + 1);
    int rc = w->c ? 0 : UV_ENOMEM;
    if (rc == 0) {
        w->connect.data = w;
        rc = uv_tcp_connect(&w->connect, conn_tcp(w->c), res->ai_addr, on_connected);
    }
    uv_freeaddrinfo(res);
    if (rc != 0 && w->c) conn_close(w->c, uv_strerror(rc), 0);
}

static void try_connect(worker *w) {
    char port[16];
    snprintf(port, sizeof port, "%d", w->cfg.port);
    struct addrinfo hints = {.ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM};
    w->resolve.data = w;
    w->next_attempt = 1e300;
    if (uv_getaddrinfo(&w->loop, &w->resolve, on_resolved, w->cfg.host, port, &hints) == 0)
        w->resolving = 1;
    else
        schedule_retry(w);
}

/* ---- timers and signals -------------------------------------------------- */


static void on_tick(uv_timer_t *t) {
    worker *w = t->data;
    double now = now_s(w);
    /* A long gap between ticks means this process was not running (SIGSTOP,
     * a suspended VM): the silence is ours, so give the coordinator a fresh
     * chance to speak before calling it gone. */
    if (now - w->last_tick > 5 * TICK_MS / 1e3) w->last_heard = now;
    w->last_tick = now;
    if (w->stopping) {
        if (!w->c && !w->resolving) close_handles(w);
        return;
    }
    check_idle(w, now);
    if (w->stopping) return;
    pool_trim(w->pool);
    if (w->welcomed && now - w->last_sent >= w->heartbeat_s) {
        size_t len;
        uint8_t *frame = proto_frame_simple("heartbeat", &len);
        worker_send(w, frame, len);
    }
    if (w->c && w->connected && now - w->last_heard > (w->welcomed ? w->timeout_s : 10.0)) {
        char reason[96];
        snprintf(reason, sizeof reason, "no message from the coordinator for %.1f s", now - w->last_heard);
        conn_close(w->c, reason, 0);
    }
    if (!w->c && !w->resolving && now >= w->next_attempt) try_connect(w);
}

/* Leave cleanly: say bye, abandon the tiles in hand (the coordinator hands
 * them to others) and let the loop wind down; exit status stays 0. */
static void worker_leave(worker *w) {
    w->stopping = 1;
    if (w->c && w->welcomed) {
        size_t len;
        uint8_t *frame = proto_frame_simple("bye", &len);
        worker_send(w, frame, len);
    }
    pool_leave(w->pool); /* a scene being loaded too */
    if (w->c) conn_close(w->c, "leaving", 1);
}

static void on_signal(uv_signal_t *s, int signum) {
    worker *w = s->data;
    if (w->stopping) return;
    const char *sig = signum == SIGTERM ? "SIGTERM" : "SIGINT";
    if (!w->cfg.quiet && w->held > 0)
        worker_log(w, "%s: abandoning %d tile%s and leaving", sig, w->held, w->held == 1 ? "" : "s");
    else if (!w->cfg.quiet)
        worker_log(w, "%s: leaving", sig);
    worker_leave(w);
}

/* --idle-exit: leave once no tile has been in hand for idle_exit_s seconds,
 * saying why (no coordinator reachable, or one that gave no work). */
static void check_idle(worker *w, double now) {
    if (w->welcomed) w->last_welcomed = now;
    if (w->held > 0) w->last_work = now;
    double idle = now - w->last_work;
    if (w->cfg.idle_exit_s <= 0 || w->held > 0 || idle < w->cfg.idle_exit_s) return;
    if (w->welcomed)
        worker_log(w, "no work from the coordinator at %s for %.1f s (--idle-exit %g); leaving", w->where, idle,
                   w->cfg.idle_exit_s);
    else if (now - w->last_welcomed >= w->cfg.idle_exit_s)
        worker_log(w, "no coordinator reachable at %s for %.1f s (--idle-exit %g); leaving", w->where,
                   now - w->last_welcomed, w->cfg.idle_exit_s);
    else
        worker_log(w, "no work for %.1f s and the coordinator at %s went away (--idle-exit %g); leaving", idle,
                   w->where, w->cfg.idle_exit_s);
    worker_leave(w);
}

/* Stop: join the render threads (they may still wake the loop), then close
 * every handle so that uv_run returns. */
static void close_handles(worker *w) {
    if (uv_is_closing((uv_handle_t *)&w->tick)) return;
    pool_free(w->pool);
    w->pool = NULL;
    uv_close((uv_handle_t *)&w->tick, NULL);
    uv_close((uv_handle_t *)&w->wake, NULL);
    uv_close((uv_handle_t *)&w->sigterm, NULL);
    uv_close((uv_handle_t *)&w->sigint, NULL);
}

static void wake_loop(void *ctx) { uv_async_send(ctx); }

worker_config worker_config_default(void) {
    return (worker_config){.threads = (int)sysconf(_SC_NPROCESSORS_ONLN), .prefetch = 1, .retry_max_s = 5,
                           .keep_scene_s = 30};
}

int worker_run(const worker_config *cfg) {
    worker *w = calloc(1, sizeof *w);
    if (!w) {
        fprintf(stderr, "tessera-worker: out of memory\n");
        return 1;
    }
    w->cfg = *cfg;
    address_format(cfg->host, cfg->port, w->where, sizeof w->where);
    w->backoff = 0.1;
    uv_loop_init(&w->loop);
    w->last_work = w->last_welcomed = now_s(w);
    uv_async_init(&w->loop, &w->wake, on_wake);
    w->wake.data = w;
    pool_config pc = {.threads = cfg->threads, .throttle_ms = cfg->throttle_ms, .keep_s = cfg->keep_scene_s,
                      .wake = wake_loop, .wake_ctx = &w->wake, .log = cfg->verbose ? pool_log_line : NULL, .log_ctx = w};
    w->pool = pool_new(&pc);
    if (w->pool && cfg->preload_scene && pool_preload(w->pool, cfg->preload_hash, cfg->preload_scene)) {
        scene_free(cfg->preload_scene); /* out of memory for its entry: the bundle will be asked for instead */
        worker_log(w, "out of memory for the scene handed over; it will be loaded from its bundle");
    }
    if (!w->pool) {
        scene_free(cfg->preload_scene);
        worker_log(w, "cannot start %d render threads", cfg->threads);
        uv_close((uv_handle_t *)&w->wake, NULL);
        uv_run(&w->loop, UV_RUN_DEFAULT);
        uv_loop_close(&w->loop);
        free(w);
        return 1;
    }
    uv_timer_init(&w->loop, &w->tick);
    w->tick.data = w;
    uv_timer_start(&w->tick, on_tick, 0, TICK_MS);
    uv_signal_init(&w->loop, &w->sigterm);
    uv_signal_init(&w->loop, &w->sigint);
    w->sigterm.data = w->sigint.data = w;
    uv_signal_start(&w->sigterm, on_signal, SIGTERM);
    uv_signal_start(&w->sigint, on_signal, SIGINT);
    try_connect(w);
    uv_run(&w->loop, UV_RUN_DEFAULT);
    forget_bundles(w);
    int rc = uv_loop_close(&w->loop);
    if (rc) worker_log(w, "event loop closed with handles open: %s", uv_strerror(rc));
    int code = w->exit_code;
    if (cfg->verbose) worker_log(w, "sent %lu tiles", w->tiles_sent);
    free(w);
    return code;
}
