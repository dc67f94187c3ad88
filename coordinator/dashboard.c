/* dashboard.c - routes, JSON, events, preview and metrics of the web
 * dashboard (see dashboard.h; the HTTP side is http.c, the pages
 * web_assets.c). */
#include "dashboard.h"

#include <ctype.h>
#include <sodium.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/queue.h>

#include "http.h"
#include "image/image.h"
#include "image/image_codecs.h"
#include "limit.h"
#include "net/address.h"

#define DASH_SESSIONS 64
#define DASH_MAX_REQUEST (64 << 10)
#define DASH_MAX_HEADERS 64
#define DASH_FLUSH_MS 250 /* events are batched: one write per stream per tick, not per tile */
#define DASH_ENCODES 2       /* images read and encoded at once, on libuv's pool */
#define DASH_ENCODE_QUEUE 16 /* image requests waiting for one; beyond, 503 */
#define DASH_FOLLOWERS 64    /* the same image asked again while it is made: answered with it */
#define DASH_COPY_FLOATS (2u << 20) /* a live frame is copied 8 MB a loop turn (4096x4096: 25 turns) */

/* Tile latency histogram bounds, seconds (Prometheus le=). */
static const double latency_bounds[] = {0.01, 0.025, 0.05, 0.1, 0.25, 0.5, 1, 2.5, 5, 10, 30, 60};
#define LATENCY_BUCKETS (sizeof latency_bounds / sizeof latency_bounds[0])

extern const char web_index_html[];
extern const char web_login_html[];

/* Append printf-formatted text to a growing buffer. */
typedef struct {
    char *s;
    size_t len, cap;
} strbuf;

static void __attribute__((format(printf, 2, 3))) sb_printf(strbuf *b, const char *fmt, ...) {
    for (;;) {
        va_list ap;
        va_start(ap, fmt);
        int n = b->s ? vsnprintf(b->s + b->len, b->cap - b->len, fmt, ap) : -2;
        va_end(ap);
        if (n >= 0 && (size_t)n < b->cap - b->len) {
            b->len += (size_t)n;
            return;
        }
        size_t cap = b->cap ? 2 * b->cap : 4096;
        if (n >= 0 && cap < b->len + (size_t)n + 1) cap = b->len + (size_t)n + 1;
        char *s = realloc(b->s, cap);
        if (!s) return;
        b->s = s;
        b->cap = cap;
    }
}

typedef struct dash_encode dash_encode;

struct dashboard {
    uv_loop_t *loop;
    farm *f;
    http_server *http;
    dashboard_options o;
    int https;                /* served over TLS (o.tls_cert, o.tls_key) */
    char cert[400];           /* the certificate served, for logs (tls_config_describe) */
    const auth_keyring *auth; /* NULL: no tokens; the owner's ring, which SIGHUP may change */
    dashboard_source src;
    char csrf[AUTH_HEX];
    char sessions[DASH_SESSIONS][AUTH_HEX];
    /* The key of the token each session logged in with: its class is looked
     * up in the ring on every request, so a token taken away by SIGHUP ends
     * its sessions. */
    unsigned char session_key[DASH_SESSIONS][AUTH_KEY_BYTES];
    int next_session;
    uint64_t tiles_done, tiles_assigned, tiles_requeued, samples, joins, leaves;
    uint64_t latency_counts[LATENCY_BUCKETS + 1];
    double latency_sum;
    uint64_t requests;
    strbuf pending;    /* event lines not yet sent to the streams */
    uv_timer_t flush;  /* sends them every DASH_FLUSH_MS */
    int open_parts;    /* the http server, the timer and each encode in flight, until closed */
    int closing;
    TAILQ_HEAD(, dash_encode) waiting; /* image requests not yet started */
    TAILQ_HEAD(, dash_encode) running; /* ... and on the pool */
    int waiting_n, encoding;           /* queued, and on the pool now */
    uint64_t images_busy;              /* image requests refused with 503 (queue full) */
    uint64_t images_encoded, images_shared; /* encodings made, and requests answered with another's */
    void (*closed_cb)(void *);
    void *closed_ctx;
};

int dashboard_parse_request(const char *data, size_t len) {
    http_reqparser r;
    http_reqparser_init(&r, DASH_MAX_REQUEST, DASH_MAX_HEADERS);
    int rc = http_reqparser_feed(&r, data, len);
    http_reqparser_free(&r);
    return rc;
}

int dashboard_parse_address(const char *s, dashboard_options *o, char *host_buf, size_t host_len, char *err,
                            size_t err_len) {
    if (address_parse(s, host_buf, host_len, &o->port, err, err_len)) return -1;
    o->host = host_buf;
    return 0;
}

/* ---- events ------------------------------------------------------------------ */

static void on_farm_event(void *ctx, const farm_event *e) {
    dashboard *d = ctx;
    static const char *const kinds[] = {"assign", "done", "requeue", "join", "leave"};
    switch (e->kind) {
    case FARM_EV_ASSIGN: d->tiles_assigned++; break;
    case FARM_EV_DONE: {
        d->tiles_done++;
        d->samples += e->samples;
        d->latency_sum += e->seconds;
        size_t b = 0;
        while (b < LATENCY_BUCKETS && e->seconds > latency_bounds[b]) b++;
        d->latency_counts[b]++;
        break;
    }
    case FARM_EV_REQUEUE: d->tiles_requeued++; break;
    case FARM_EV_JOIN: d->joins++; break;
    case FARM_EV_LEAVE: d->leaves++; break;
    }
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "kind", kinds[e->kind]);
    if (e->kind <= FARM_EV_REQUEUE) {
        cJSON_AddNumberToObject(m, "job", e->job);
        cJSON_AddNumberToObject(m, "tile", e->tile);
        cJSON_AddNumberToObject(m, "x0", e->rect.x0);
        cJSON_AddNumberToObject(m, "y0", e->rect.y0);
        cJSON_AddNumberToObject(m, "x1", e->rect.x1);
        cJSON_AddNumberToObject(m, "y1", e->rect.y1);
    }
    if (e->worker) cJSON_AddStringToObject(m, "worker", e->worker);
    if (e->kind == FARM_EV_DONE) cJSON_AddNumberToObject(m, "seconds", e->seconds);
    if (e->backup) cJSON_AddTrueToObject(m, "backup");
    char *json = cJSON_PrintUnformatted(m);
    cJSON_Delete(m);
    if (!json) return;
    if (d->pending.len < (4u << 20)) sb_printf(&d->pending, "data: %s\n\n", json); /* else: nobody is flushing */
    free(json);
}

void dashboard_farm_event(dashboard *d, const farm_event *e) { on_farm_event(d, e); }

static void on_flush(uv_timer_t *t) {
    dashboard *d = t->data;
    if (!d->pending.len) return;
    http_server_broadcast(d->http, d->pending.s, d->pending.len);
    d->pending.len = 0;
}

/* ---- authentication ---------------------------------------------------------- */

static int dash_secured(const dashboard *d) { return d->auth && auth_keyring_enabled(d->auth); }

/* Who a request is: its class, and for a user's own token (--client-tokens)
 * the user's name ("" for the admin or the shared client token). */
typedef struct {
    auth_class cls;
    char user[AUTH_USER_NAME];
} dash_who;

/* Which key of the ring key is (every key compared every time, in constant
 * time): AUTH_ADMIN, or AUTH_CLIENT (the client token's, or a user's own,
 * then with the user's name), or AUTH_NONE (a worker token opens nothing
 * here; nor does a token SIGHUP took away). */
static dash_who key_who(const dashboard *d, const unsigned char key[AUTH_KEY_BYTES]) {
    const auth_key *a = &d->auth->keys[AUTH_ADMIN], *c = &d->auth->keys[AUTH_CLIENT];
    int admin = (sodium_memcmp(key, a->key, AUTH_KEY_BYTES) == 0) & a->enabled;
    int client = (sodium_memcmp(key, c->key, AUTH_KEY_BYTES) == 0) & c->enabled;
    int user = -1;
    for (int u = 0; u < d->auth->user_count; u++) {
        const auth_key *k = &d->auth->users[u].key;
        int match = (sodium_memcmp(key, k->key, AUTH_KEY_BYTES) == 0) & k->enabled;
        if (match) user = u;
        client |= match;
    }
    dash_who w = {admin ? AUTH_ADMIN : client ? AUTH_CLIENT : AUTH_NONE, ""};
    if (w.cls == AUTH_CLIENT && user >= 0) snprintf(w.user, sizeof w.user, "%s", d->auth->users[user].name);
    return w;
}

/* The token as typed or sent (surrounding whitespace ignored) made into
 * its key; then key_who. An empty token is no token. */
static dash_who token_who(const dashboard *d, const char *token, size_t len, unsigned char key[AUTH_KEY_BYTES]) {
    while (len && isspace((unsigned char)*token)) token++, len--;
    while (len && isspace((unsigned char)token[len - 1])) len--;
    crypto_generichash(key, AUTH_KEY_BYTES, (const unsigned char *)token, len, NULL, 0);
    dash_who w = key_who(d, key);
    if (len == 0) w = (dash_who){AUTH_NONE, ""};
    return w;
}

/* Who a request is: the admin without tokens, else the bearer token's or
 * the session's holder, or AUTH_NONE. */
static dash_who request_who(const dashboard *d, const http_request *rq) {
    if (!dash_secured(d)) return (dash_who){AUTH_ADMIN, ""};
    if (strncasecmp(rq->authorization, "Bearer ", 7) == 0) {
        unsigned char key[AUTH_KEY_BYTES];
        dash_who w = token_who(d, rq->authorization + 7, strlen(rq->authorization + 7), key);
        sodium_memzero(key, sizeof key);
        return w;
    }
    char sid[AUTH_HEX];
    if (http_cookie_get(rq->cookie, "tessera_session", sid, sizeof sid) || strlen(sid) != AUTH_HEX - 1)
        return (dash_who){AUTH_NONE, ""};
    for (int i = 0; i < DASH_SESSIONS; i++)
        if (d->sessions[i][0] && sodium_memcmp(d->sessions[i], sid, AUTH_HEX - 1) == 0)
            return key_who(d, d->session_key[i]);
    return (dash_who){AUTH_NONE, ""};
}

/* The owner of job id into owner ("" when it has none, or when the source
 * does not say). Returns 0, or -1 when there is no such job. */
static int job_owner(const dashboard *d, uint32_t id, char *owner, size_t len) {
    owner[0] = '\0';
    return d->src.owner ? d->src.owner(d->src.ctx, id, owner, len) : 0;
}

/* Whether w may see the pixels of a job owned by owner (its preview and
 * image), as `tessera fetch` may: the admin any job; a user their own and
 * those without an owner; the shared client token (which names no one)
 * any job but a user's. */
static int may_view(const dashboard *d, const dash_who *w, const char *owner) {
    if (w->cls == AUTH_ADMIN || !owner[0]) return 1;
    if (w->user[0]) return strcmp(owner, w->user) == 0;
    return !auth_is_user(d->auth, owner);
}

/* Whether w may cancel or reprioritise a job owned by owner: the admin any
 * job; a user their own and those without an owner; the shared client token
 * only when there is neither an admin token nor users (then it is the
 * only credential there is). */
static int may_change(const dashboard *d, const dash_who *w, const char *owner) {
    if (w->cls == AUTH_ADMIN) return 1;
    if (w->user[0]) return !owner[0] || strcmp(owner, w->user) == 0;
    return !d->auth->keys[AUTH_ADMIN].enabled && d->auth->user_count == 0;
}

/* Browsers send Origin on POSTs; one that is not this server is refused. */
static int origin_ok(const http_request *rq) {
    if (!rq->origin[0]) return 1;
    const char *o = strstr(rq->origin, "://");
    return o && strcmp(o + 3, rq->host) == 0;
}

/* A Host that is not a loopback name while we listen on loopback is a DNS
 * rebinding attempt: refused. */
static int host_ok(const dashboard *d, const http_request *rq) {
    if (!address_is_loopback(d->o.host)) return 1;
    char h[HTTP_VALUE_MAX];
    snprintf(h, sizeof h, "%s", rq->host);
    if (h[0] == '[') {
        char *e = strchr(h, ']');
        if (e) *e = '\0';
        memmove(h, h + 1, strlen(h));
    } else {
        char *c = strrchr(h, ':');
        if (c) *c = '\0';
    }
    return h[0] == '\0' || address_is_loopback(h);
}

/* ---- answers ----------------------------------------------------------------- */

static void send_text(http_conn *c, int status, const char *text) {
    http_respond(c, status, "text/plain; charset=utf-8", text, strlen(text), NULL);
}

static void send_json(http_conn *c, cJSON *v) {
    char *s = cJSON_PrintUnformatted(v);
    cJSON_Delete(v);
    if (!s) {
        send_text(c, 503, "out of memory\n");
        return;
    }
    http_respond(c, 200, "application/json", s, strlen(s), NULL);
    free(s);
}

static void route_workers(dashboard *d, http_conn *c) {
    farm_worker_info w[256];
    int n = farm_list_workers(d->f, w, 256);
    cJSON *arr = cJSON_CreateArray();
    for (int i = 0; i < n && i < 256; i++) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", w[i].name);
        cJSON_AddStringToObject(o, "addr", w[i].addr);
        cJSON_AddNumberToObject(o, "threads", w[i].threads);
        cJSON_AddBoolToObject(o, "stalled", w[i].stalled);
        cJSON_AddNumberToObject(o, "tiles", (double)w[i].tiles);
        cJSON_AddNumberToObject(o, "samples", (double)w[i].samples);
        cJSON_AddNumberToObject(o, "connected_s", w[i].connected_s);
        cJSON_AddNumberToObject(o, "silent_s", w[i].silent_s);
        cJSON_AddNumberToObject(o, "failures", w[i].failures);
        cJSON_AddNumberToObject(o, "quarantined", w[i].quarantined); /* jobs whose audit it failed */
        cJSON_AddNumberToObject(o, "blocklisted", w[i].blocklisted); /* running jobs it may not take now */
        cJSON_AddNumberToObject(o, "retry_s", w[i].retry_s);
        cJSON_AddNumberToObject(o, "msamples_per_s",
                                w[i].connected_s > 0 ? (double)w[i].samples / w[i].connected_s / 1e6 : 0);
        cJSON_AddItemToArray(arr, o);
    }
    send_json(c, arr);
}

static cJSON *jobs_array(dashboard *d) {
    cJSON *arr = cJSON_CreateArray();
    if (d->src.jobs) d->src.jobs(d->src.ctx, arr);
    return arr;
}

static void route_metrics(dashboard *d, http_conn *c) {
    strbuf b = {0};
    farm_totals t;
    farm_get_totals(d->f, &t);
    farm_worker_info w[256];
    int workers = farm_list_workers(d->f, w, 256);
    const struct {
        const char *name, *help;
        uint64_t v;
    } counters[] = {
        {"tessera_tiles_rendered_total", "Tiles rendered and stitched.", d->tiles_done},
        {"tessera_tiles_assigned_total", "Tiles handed out to workers (backups included).", d->tiles_assigned},
        {"tessera_tiles_requeued_total", "Tiles put back in the queue after a loss, stall or lease.",
         d->tiles_requeued},
        {"tessera_samples_total", "Samples traced in stitched tiles.", d->samples},
        {"tessera_bytes_received_total", "Bytes received from workers and clients.", t.bytes_in},
        {"tessera_bytes_sent_total", "Bytes sent to workers and clients.", t.bytes_out},
        {"tessera_worker_joins_total", "Workers that joined.", d->joins},
        {"tessera_http_requests_total", "HTTP requests answered by the dashboard.", d->requests},
        {"tessera_http_streams_dropped_total", "Event streams dropped for falling behind.",
         http_server_dropped(d->http)},
        {"tessera_http_refused_total", "HTTP connections refused (503) over the per-address or total cap.",
         http_server_refused(d->http)},
        {"tessera_http_images_busy_total", "Preview and download requests refused (503) with the encoding queue full.",
         d->images_busy},
        {"tessera_http_images_encoded_total", "Previews and downloads encoded.", d->images_encoded},
        {"tessera_http_images_shared_total", "Preview and download requests answered with the bytes another was "
         "already making.", d->images_shared},
        {"tessera_http_tls_failures_total", "HTTPS connections that ended before a request (handshake failed, "
         "plain HTTP, peer gone).", http_server_tls_failed(d->http)},
    };
    for (size_t i = 0; i < sizeof counters / sizeof counters[0]; i++)
        sb_printf(&b, "# HELP %s %s\n# TYPE %s counter\n%s %llu\n", counters[i].name, counters[i].help,
                  counters[i].name, counters[i].name, (unsigned long long)counters[i].v);
    sb_printf(&b, "# HELP tessera_queue_tiles Tiles waiting to be handed out.\n# TYPE tessera_queue_tiles gauge\n"
                  "tessera_queue_tiles %d\n", t.queued);
    sb_printf(&b, "# HELP tessera_workers Connected workers.\n# TYPE tessera_workers gauge\ntessera_workers %d\n",
              workers);
    static const char *const states[] = {"queued", "running", "done", "failed", "cancelled"};
    int by_state[5] = {0};
    cJSON *jobs = jobs_array(d), *j;
    cJSON_ArrayForEach(j, jobs) {
        const cJSON *st = cJSON_GetObjectItemCaseSensitive(j, "state");
        for (int i = 0; i < 5; i++)
            if (cJSON_IsString(st) && strcmp(st->valuestring, states[i]) == 0) by_state[i]++;
    }
    cJSON_Delete(jobs);
    sb_printf(&b, "# HELP tessera_jobs Jobs by state.\n# TYPE tessera_jobs gauge\n");
    for (int i = 0; i < 5; i++) sb_printf(&b, "tessera_jobs{state=\"%s\"} %d\n", states[i], by_state[i]);
    sb_printf(&b, "# HELP tessera_tile_seconds Time from handing a tile out to stitching it.\n"
                  "# TYPE tessera_tile_seconds histogram\n");
    uint64_t cum = 0;
    for (size_t i = 0; i < LATENCY_BUCKETS; i++) {
        cum += d->latency_counts[i];
        sb_printf(&b, "tessera_tile_seconds_bucket{le=\"%g\"} %llu\n", latency_bounds[i], (unsigned long long)cum);
    }
    cum += d->latency_counts[LATENCY_BUCKETS];
    sb_printf(&b, "tessera_tile_seconds_bucket{le=\"+Inf\"} %llu\n", (unsigned long long)cum);
    sb_printf(&b, "tessera_tile_seconds_sum %.6f\ntessera_tile_seconds_count %llu\n", d->latency_sum,
              (unsigned long long)cum);
    if (!b.s) {
        send_text(c, 503, "out of memory\n");
        return;
    }
    http_respond(c, 200, "text/plain; version=0.0.4; charset=utf-8", b.s, b.len, NULL);
    free(b.s);
}

/* The exposure=S of a query (-20 to 20 stops), or 0. */
static float query_exposure(const char *query) {
    const char *e = strstr(query, "exposure=");
    double x = e ? strtod(e + 9, NULL) : 0;
    return x >= -20 && x <= 20 ? (float)x : 0;
}

/* ---- images: previews and downloads, read and encoded on libuv's pool ---- */

typedef enum { ENC_PREVIEW, ENC_PNG, ENC_EXR } enc_kind;

/* One image request. The pixels are a copy of the job's live frame (made on
 * the loop a band per turn, copy_step) or read from the job's saved file on
 * the pool; the encoding runs there too, so a 4096x4096 EXR does not hold
 * up the farm's loop. Answered on the loop, with everyone who asked for the
 * same bytes meanwhile, if they are still there. */
struct dash_encode {
    uv_work_t req;
    dashboard *d;
    http_conn *c; /* held until answered */
    http_conn *followers[DASH_FOLLOWERS]; /* asked for the same image meanwhile; held too */
    int nfollow;
    uint32_t id;
    enc_kind kind;
    float exposure;
    float *rgb; /* the copy, or what the pool read */
    int w, h;
    size_t copied; /* floats of the live frame copied so far */
    char path[4096]; /* "" when rgb holds a copy */
    conn_blob *answer; /* the whole 200 answer, built on the pool */
    int status;        /* 200, or the error's, with err */
    char err[400];
    TAILQ_ENTRY(dash_encode) link;
};

static void encode_free(dash_encode *e) {
    http_conn_release(e->c);
    for (int i = 0; i < e->nfollow; i++) http_conn_release(e->followers[i]);
    free(e->rgb);
    conn_blob_unref(e->answer);
    free(e);
}

/* The encoded image of e (read first when a path), or NULL with the reason
 * in e->err. On the pool. */
static uint8_t *encode_bytes(dash_encode *e, size_t *len) {
    if (e->path[0]) {
        image img;
        if (image_read(e->path, &img, e->err, sizeof e->err)) return NULL;
        e->rgb = img.rgb;
        e->w = img.width;
        e->h = img.height;
    }
    if (e->kind == ENC_EXR) {
        codec_exr_options eo = {.compression = CODEC_EXR_ZIP};
        return codec_exr_encode(e->rgb, e->w, e->h, &eo, len, e->err, sizeof e->err);
    }
    tonemap_options t = {TONEMAP_REINHARD, e->exposure, 0}; /* the job's way, with the query's exposure */
    size_t n = (size_t)e->w * (size_t)e->h;
    uint8_t *px = malloc(n * 3);
    if (!px) return snprintf(e->err, sizeof e->err, "out of memory"), NULL;
    tonemap_to_8bit(e->rgb, n, &t, px);
    uint8_t *out = codec_png_encode(px, e->w, e->h, len, e->err, sizeof e->err);
    free(px);
    return out;
}

/* On the pool: the whole answer (so the loop only queues it: a 40 MB EXR
 * is not copied there), or status 503 with the reason; touches only e. */
static void encode_work(uv_work_t *req) {
    dash_encode *e = req->data;
    size_t len = 0;
    uint8_t *out = encode_bytes(e, &len);
    if (out) {
        char hdr[200] = "";
        if (e->kind != ENC_PREVIEW)
            snprintf(hdr, sizeof hdr, "Content-Disposition: attachment; filename=\"job-%u.%s\"\r\n", e->id,
                     e->kind == ENC_EXR ? "exr" : "png");
        e->answer = http_response_build(200, e->kind == ENC_EXR ? "image/x-exr" : "image/png", out, len,
                                        hdr[0] ? hdr : NULL);
        if (!e->answer) snprintf(e->err, sizeof e->err, "out of memory");
        free(out);
    }
    e->status = e->answer ? 200 : 503;
    if (!e->answer) {
        char why[400];
        snprintf(why, sizeof why, "%s", e->err);
        snprintf(e->err, sizeof e->err, "cannot encode the image: %.350s\n", why);
    }
}

static void encode_pump(dashboard *d);
static void on_part_closed(dashboard *d);

/* Whether anyone e holds (the asker, its followers) still waits. */
static int encode_wanted(const dash_encode *e) {
    if (http_conn_open(e->c)) return 1;
    for (int i = 0; i < e->nfollow; i++)
        if (http_conn_open(e->followers[i])) return 1;
    return 0;
}

/* e is over: answer everyone it holds (with the answer built on the pool,
 * or e->status and the text in e->err), free it, start the next. */
static void encode_end(dash_encode *e) {
    dashboard *d = e->d;
    d->encoding--;
    TAILQ_REMOVE(&d->running, e, link);
    d->images_encoded += e->status == 200;
    for (int i = -1; i < e->nfollow && !d->closing; i++) {
        http_conn *c = i < 0 ? e->c : e->followers[i];
        if (!http_conn_open(c)) continue;
        if (e->status == 200) http_respond_blob(c, e->answer); /* one copy of the bytes for all who asked */
        else send_text(c, e->status, e->err);
    }
    encode_free(e);
    if (!d->closing) encode_pump(d);
    on_part_closed(d);
}

static void encode_fail(dash_encode *e, int status, const char *text) {
    e->status = status;
    snprintf(e->err, sizeof e->err, "%s", text);
    encode_end(e);
}

/* Back on the loop: answer, then start the next. */
static void encode_done(uv_work_t *req, int status) {
    (void)status;
    encode_end(req->data);
}

/* Read (a path) and encode e on the pool. */
static void encode_queue(dash_encode *e) {
    if (uv_queue_work(e->d->loop, &e->req, encode_work, encode_done))
        encode_fail(e, 503, "cannot start the image's encoding\n");
}

static void copy_step(dash_encode *e);

/* Nothing on the pool: a way back to the loop for the next band. */
static void copy_bounce(uv_work_t *req) { (void)req; }

static void copy_next(uv_work_t *req, int status) {
    (void)status;
    copy_step(req->data);
}

/* Copy the next DASH_COPY_FLOATS of the job's live frame (copying 200 MB
 * at once held the loop 171 ms: mostly the copy's page faults), then, on a
 * later turn, the next, then the encoding. A band is copied between tiles,
 * so a preview may mix tiles of two moments: they all landed. A frame that
 * left memory meanwhile (the job ended) is read from its saved file. */
static void copy_step(dash_encode *e) {
    dashboard *d = e->d;
    float *live;
    int w, h;
    if (d->closing || !encode_wanted(e)) return encode_fail(e, 503, "nobody is waiting\n");
    if (!d->src.frame || d->src.frame(d->src.ctx, e->id, &live, &w, &h) || w != e->w || h != e->h) {
        free(e->rgb);
        e->rgb = NULL;
        if (d->src.image_file && d->src.image_file(d->src.ctx, e->id, 0, e->path, sizeof e->path) == 0)
            return encode_queue(e);
        return encode_fail(e, 404, "no image for this job\n");
    }
    size_t total = (size_t)w * (size_t)h * 3, n = total - e->copied;
    if (n > DASH_COPY_FLOATS) n = DASH_COPY_FLOATS;
    memcpy(e->rgb + e->copied, live + e->copied, n * sizeof *live);
    e->copied += n;
    if (e->copied == total) return encode_queue(e);
    if (uv_queue_work(d->loop, &e->req, copy_bounce, copy_next)) encode_fail(e, 503, "cannot copy the frame\n");
}

/* Start e (counted, in the running list): a preview of a job in memory is
 * copied a band a turn first; otherwise the pool reads the saved file. */
static void encode_start(dashboard *d, dash_encode *e) {
    float *live;
    e->req.data = e;
    if (e->kind == ENC_PREVIEW && d->src.frame && d->src.frame(d->src.ctx, e->id, &live, &e->w, &e->h) == 0) {
        if (!(e->rgb = malloc((size_t)e->w * (size_t)e->h * 3 * sizeof *live)))
            return encode_fail(e, 503, "out of memory\n");
        return copy_step(e);
    }
    if (d->src.image_file &&
        d->src.image_file(d->src.ctx, e->id, e->kind != ENC_PREVIEW, e->path, sizeof e->path) == 0)
        return encode_queue(e);
    encode_fail(e, 404, e->kind == ENC_PREVIEW ? "no image for this job\n" : "no finished image for this job\n");
}

/* Start waiting requests while fewer than DASH_ENCODES run. */
static void encode_pump(dashboard *d) {
    dash_encode *e;
    while (d->encoding < DASH_ENCODES && (e = TAILQ_FIRST(&d->waiting))) {
        TAILQ_REMOVE(&d->waiting, e, link);
        d->waiting_n--;
        if (!encode_wanted(e)) {
            encode_free(e);
            continue;
        }
        d->encoding++;
        d->open_parts++;
        TAILQ_INSERT_TAIL(&d->running, e, link);
        encode_start(d, e); /* may end it at once (and pump again) */
    }
}

/* A request waiting or being made for the same bytes (the same job, kind
 * and exposure) with room for one more asker, or NULL. */
static dash_encode *encode_same(dashboard *d, uint32_t id, enc_kind kind, float exposure) {
    for (int running = 0; running < 2; running++) {
        dash_encode *e = running ? TAILQ_FIRST(&d->running) : TAILQ_FIRST(&d->waiting);
        for (; e; e = TAILQ_NEXT(e, link))
            if (e->id == id && e->kind == kind && e->exposure == exposure && e->nfollow < DASH_FOLLOWERS) return e;
    }
    return NULL;
}

/* Queue an image request on c (answered later), or refuse it with 503 when
 * DASH_ENCODE_QUEUE already wait. */
static void encode_request(dashboard *d, http_conn *c, uint32_t id, enc_kind kind, const char *query) {
    float exposure = kind == ENC_EXR ? 0 : query_exposure(query); /* an EXR is linear: the same for any */
    dash_encode *same = encode_same(d, id, kind, exposure);
    if (same) { /* answered with its bytes: no second encoding (a preview may be one encoding older) */
        http_conn_hold(c);
        same->followers[same->nfollow++] = c;
        d->images_shared++;
        return;
    }
    if (d->waiting_n >= DASH_ENCODE_QUEUE) {
        d->images_busy++;
        char text[200];
        snprintf(text, sizeof text, "busy: %d images are being encoded and %d wait; retry\n", d->encoding,
                 d->waiting_n);
        http_respond(c, 503, "text/plain; charset=utf-8", text, strlen(text), "Retry-After: 1\r\n");
        return;
    }
    dash_encode *e = calloc(1, sizeof *e);
    if (!e) return send_text(c, 503, "out of memory\n");
    e->d = d;
    e->c = c;
    http_conn_hold(c);
    e->id = id;
    e->kind = kind;
    e->exposure = exposure;
    TAILQ_INSERT_TAIL(&d->waiting, e, link);
    d->waiting_n++;
    encode_pump(d);
}

/* GET /api/jobs/N/log[?last=N]: the source's log of the job (the newest N
 * lines). */
static void route_log(dashboard *d, http_conn *c, uint32_t id, const char *query) {
    const char *q = strstr(query, "last=");
    long last = q ? strtol(q + 5, NULL, 10) : 0;
    cJSON *o = cJSON_CreateObject();
    if (!d->src.log || d->src.log(d->src.ctx, id, (int)(last > 0 && last < INT32_MAX ? last : 0), o)) {
        cJSON_Delete(o);
        return send_text(c, 404, "no log for this job\n");
    }
    send_json(c, o);
}

/* POST /api/jobs/N/priority with priority=P in the form body. */
static void route_priority(dashboard *d, http_conn *c, uint32_t id, const http_request *rq) {
    char v[32], *end, err[300] = "changing the priority is not offered here";
    long p = http_form_get(rq->body, "priority", v, sizeof v) ? 0 : strtol(v, &end, 10);
    if (!v[0] || *end || p < -LIMIT_PRIORITY || p > LIMIT_PRIORITY) {
        snprintf(err, sizeof err, "priority must be an integer from %d to %d\n", -LIMIT_PRIORITY, LIMIT_PRIORITY);
        return send_text(c, 400, err);
    }
    if (!d->src.priority || d->src.priority(d->src.ctx, id, (int)p, err, sizeof err)) return send_text(c, 409, err);
    send_text(c, 200, "priority changed\n");
}

static void route_login(dashboard *d, http_conn *c, const http_request *rq) {
    if (strcmp(rq->method, "POST") != 0) {
        http_respond(c, 200, "text/html; charset=utf-8", web_login_html, strlen(web_login_html), NULL);
        return;
    }
    char token[1024];
    unsigned char key[AUTH_KEY_BYTES];
    if (!origin_ok(rq) || http_form_get(rq->body, "token", token, sizeof token) || !dash_secured(d) ||
        token_who(d, token, strlen(token), key).cls == AUTH_NONE) {
        sodium_memzero(token, sizeof token);
        http_respond(c, 303, "text/plain", "", 0, "Location: /login?failed=1\r\n");
        return;
    }
    sodium_memzero(token, sizeof token);
    memcpy(d->session_key[d->next_session], key, sizeof key);
    sodium_memzero(key, sizeof key);
    char *sid = d->sessions[d->next_session];
    d->next_session = (d->next_session + 1) % DASH_SESSIONS;
    auth_nonce(sid);
    char hdr[300];
    snprintf(hdr, sizeof hdr,
             "Set-Cookie: tessera_session=%s; HttpOnly; SameSite=Strict; Path=/%s\r\nLocation: /\r\n", sid,
             d->https ? "; Secure" : "");
    http_respond(c, 303, "text/plain", "", 0, hdr);
}

/* "/api/jobs/N/REST" -> N and REST; 0 or -1. */
static int parse_job_path(const char *path, uint32_t *id, const char **rest) {
    const char *p = path + strlen("/api/jobs/");
    char *end;
    unsigned long v = strtoul(p, &end, 10);
    if (end == p || v == 0 || v > UINT32_MAX || *end != '/') return -1;
    *id = (uint32_t)v;
    *rest = end + 1;
    return 0;
}

/* POST /api/jobs/N/priority or /cancel, from w (signed in): refused unless
 * may_change; the source then decides. */
static void route_change(dashboard *d, http_conn *c, const http_request *rq, const dash_who *w) {
    if (d->o.read_only) return send_text(c, 403, "read-only dashboard\n");
    if (!origin_ok(rq) || strlen(rq->csrf) != AUTH_HEX - 1 || sodium_memcmp(rq->csrf, d->csrf, AUTH_HEX - 1))
        return send_text(c, 403, "missing or wrong CSRF token\n");
    uint32_t id;
    const char *rest;
    char owner[128], err[300] = "cancel is not offered here";
    if (strncmp(rq->path, "/api/jobs/", 10) != 0 || parse_job_path(rq->path, &id, &rest) ||
        (strcmp(rest, "priority") != 0 && strcmp(rest, "cancel") != 0))
        return send_text(c, 404, "not found\n");
    int missing = job_owner(d, id, owner, sizeof owner); /* owner "": refusals without one come first */
    if (!may_change(d, w, owner)) {
        if (w->user[0])
            snprintf(err, sizeof err, "job %u belongs to %s: only they, or the admin token, may change it\n", id,
                     owner);
        else
            snprintf(err, sizeof err, "changing a job from the dashboard needs the admin token%s\n",
                     d->auth->user_count ? " or its owner's own token" : "");
        return send_text(c, 403, err);
    }
    if (missing) {
        snprintf(err, sizeof err, "no job %u\n", id);
        return send_text(c, 409, err);
    }
    if (strcmp(rest, "priority") == 0) return route_priority(d, c, id, rq);
    if (!d->src.cancel || d->src.cancel(d->src.ctx, id, err, sizeof err)) return send_text(c, 409, err);
    send_text(c, 200, "cancelled\n");
}

/* GET /api/jobs: the source's jobs, each with what w may do with it
 * ("view": its preview and image; "change": cancel, priority). */
static void route_jobs(dashboard *d, http_conn *c, const dash_who *w) {
    cJSON *jobs = jobs_array(d), *j;
    cJSON_ArrayForEach(j, jobs) {
        const cJSON *o = cJSON_GetObjectItemCaseSensitive(j, "owner");
        const char *owner = cJSON_IsString(o) ? o->valuestring : "";
        cJSON_AddBoolToObject(j, "view", may_view(d, w, owner));
        cJSON_AddBoolToObject(j, "change", may_change(d, w, owner) && !d->o.read_only);
    }
    send_json(c, jobs);
}

/* GET /api/csrf: the page's token for POSTs, what is offered, and who
 * signed in ("user": a user's name, or null; "admin"). */
static void route_csrf(dashboard *d, http_conn *c, const dash_who *w) {
    cJSON *o = cJSON_CreateObject();
    cJSON_AddStringToObject(o, "csrf", d->csrf);
    cJSON_AddBoolToObject(o, "read_only", d->o.read_only);
    cJSON_AddBoolToObject(o, "priority", d->src.priority != NULL);
    cJSON_AddBoolToObject(o, "cancel", d->src.cancel != NULL);
    if (w->user[0]) cJSON_AddStringToObject(o, "user", w->user);
    else cJSON_AddNullToObject(o, "user");
    cJSON_AddBoolToObject(o, "admin", w->cls == AUTH_ADMIN);
    send_json(c, o);
}

/* GET /api/jobs/N/REST: the preview, the image and the log; 0, or -1 when
 * REST is none of those. Pixels only for who may_view them (the log, as
 * `tessera logs`, for anyone signed in). */
static int route_job_get(dashboard *d, http_conn *c, const http_request *rq, const dash_who *w) {
    uint32_t id;
    const char *rest;
    if (strncmp(rq->path, "/api/jobs/", 10) != 0 || parse_job_path(rq->path, &id, &rest)) return -1;
    if (strcmp(rest, "log") == 0) return route_log(d, c, id, rq->query), 0;
    int preview = strcmp(rest, "preview.png") == 0, exr = strcmp(rest, "image.exr") == 0;
    if (!preview && !exr && strcmp(rest, "image.png") != 0) return -1;
    char owner[128], err[300];
    if (!job_owner(d, id, owner, sizeof owner) && !may_view(d, w, owner)) {
        snprintf(err, sizeof err, "job %u belongs to %s: only they, or the admin token, may see its pixels\n", id,
                 owner);
        return send_text(c, 403, err), 0;
    }
    encode_request(d, c, id, preview ? ENC_PREVIEW : exr ? ENC_EXR : ENC_PNG, rq->query);
    return 0;
}

static void on_request(void *ctx, http_conn *c, const http_request *rq) {
    dashboard *d = ctx;
    d->requests++;
    int get = strcmp(rq->method, "GET") == 0 || strcmp(rq->method, "HEAD") == 0;
    int post = strcmp(rq->method, "POST") == 0;
    if (!host_ok(d, rq)) return send_text(c, 403, "this dashboard answers to loopback names only\n");
    if (strcmp(rq->path, "/healthz") == 0) return send_text(c, 200, "ok\n");
    if (strcmp(rq->path, "/login") == 0 && (get || post)) return route_login(d, c, rq);
    dash_who w = request_who(d, rq);
    if (w.cls == AUTH_NONE) {
        if (get && strncmp(rq->path, "/api/", 5) != 0 && strcmp(rq->path, "/metrics") != 0)
            return http_respond(c, 303, "text/plain", "", 0, "Location: /login\r\n");
        return http_respond(c, 401, "text/plain; charset=utf-8", "401 token required\n", 19,
                            "WWW-Authenticate: Bearer realm=\"tessera\"\r\n");
    }
    if (post) return route_change(d, c, rq, &w);
    if (!get) return http_respond(c, 405, "text/plain", "405\n", 4, "Allow: GET, POST\r\n");
    if (strcmp(rq->path, "/metrics") == 0) return route_metrics(d, c);
    if (strcmp(rq->path, "/api/jobs") == 0) return route_jobs(d, c, &w);
    if (strcmp(rq->path, "/api/workers") == 0) return route_workers(d, c);
    if (strcmp(rq->path, "/api/events") == 0) {
        http_stream_start(c);
        return;
    }
    if (strcmp(rq->path, "/api/csrf") == 0) return route_csrf(d, c, &w);
    if (route_job_get(d, c, rq, &w) == 0) return;
    if (strcmp(rq->path, "/") == 0 || strcmp(rq->path, "/workers") == 0 || strncmp(rq->path, "/job/", 5) == 0)
        return http_respond(c, 200, "text/html; charset=utf-8", web_index_html, strlen(web_index_html),
                            "Content-Security-Policy: default-src 'self'; script-src 'unsafe-inline'; "
                            "style-src 'unsafe-inline'; img-src 'self' blob:\r\n");
    send_text(c, 404, "not found\n");
}

/* ---- life ---------------------------------------------------------------------- */

dashboard *dashboard_new(uv_loop_t *loop, farm *f, const dashboard_options *o, const dashboard_source *src,
                         char *err, size_t err_len) {
    const char *host = o->host ? o->host : "127.0.0.1";
    int secured = o->auth && auth_keyring_enabled(o->auth);
    if (!address_is_loopback(host) && !secured && !o->insecure) {
        char where[300];
        address_format(host, o->port, where, sizeof where);
        snprintf(err, err_len,
                 "--http %s is not a loopback address and there is no --token-file: anyone who can reach it "
                 "could watch and cancel jobs; give a token, or --insecure to serve it anyway",
                 where);
        return NULL;
    }
    if (sodium_init() < 0) {
        snprintf(err, err_len, "libsodium could not start");
        return NULL;
    }
    if (!o->tls_cert != !o->tls_key) {
        snprintf(err, err_len, "HTTPS needs both a certificate (--http-cert) and its key (--http-key)");
        return NULL;
    }
    tls_config *tls = NULL;
    if (o->tls_cert && !(tls = tls_config_load(o->tls_cert, o->tls_key, err, err_len))) return NULL;
    dashboard *d = calloc(1, sizeof *d);
    if (!d) {
        tls_config_unref(tls);
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    d->loop = loop;
    d->f = f;
    d->o = *o;
    d->o.host = host;
    d->auth = secured ? o->auth : NULL;
    d->src = *src;
    auth_nonce(d->csrf);
    http_options ho = {.host = host, .port = o->port, .max_request = DASH_MAX_REQUEST,
                       .max_headers = DASH_MAX_HEADERS, .tls = tls};
    d->http = http_server_new(loop, &ho, on_request, d, err, err_len);
    d->https = tls != NULL;
    if (tls) tls_config_describe(tls, d->cert, sizeof d->cert);
    tls_config_unref(tls); /* the server holds its own reference */
    if (!d->http) {
        free(d);
        return NULL;
    }
    /* the caller's string may go; only loopback-ness is kept */
    d->o.host = address_is_loopback(host) ? "127.0.0.1" : "0.0.0.0";
    uv_timer_init(loop, &d->flush);
    d->flush.data = d;
    uv_timer_start(&d->flush, on_flush, DASH_FLUSH_MS, DASH_FLUSH_MS);
    d->open_parts = 2;
    TAILQ_INIT(&d->waiting);
    TAILQ_INIT(&d->running);
    if (!src->forwards_events) farm_set_event_cb(f, on_farm_event, d);
    return d;
}

int dashboard_port(const dashboard *d) { return http_server_port(d->http); }

const char *dashboard_scheme(const dashboard *d) { return d->https ? "https" : "http"; }

int dashboard_tls_describe(const dashboard *d, char *out, size_t len) {
    if (!d->https) return 0;
    snprintf(out, len, "%s", d->cert);
    return 1;
}

int dashboard_reload_tls(dashboard *d, char *what, size_t what_len) {
    if (!d->https) return 0;
    tls_config *t = tls_config_load(d->o.tls_cert, d->o.tls_key, what, what_len);
    if (!t) return -1;
    http_server_set_tls(d->http, t);
    tls_config_describe(t, d->cert, sizeof d->cert);
    snprintf(what, what_len, "%s", d->cert);
    tls_config_unref(t);
    return 1;
}

static void on_part_closed(dashboard *d) {
    if (--d->open_parts > 0) return;
    void (*cb)(void *) = d->closed_cb;
    void *cctx = d->closed_ctx;
    free(d->pending.s);
    sodium_memzero(d, sizeof *d);
    free(d);
    if (cb) cb(cctx);
}

static void on_http_closed(void *ctx) { on_part_closed(ctx); }

static void on_timer_closed(uv_handle_t *h) { on_part_closed(h->data); }

void dashboard_close(dashboard *d, void (*cb)(void *ctx), void *ctx) {
    if (!d->src.forwards_events) farm_set_event_cb(d->f, NULL, NULL);
    d->closed_cb = cb;
    d->closed_ctx = ctx;
    d->closing = 1; /* image requests waiting are dropped; those on the pool end unanswered */
    dash_encode *e;
    while ((e = TAILQ_FIRST(&d->waiting))) {
        TAILQ_REMOVE(&d->waiting, e, link);
        encode_free(e);
    }
    d->waiting_n = 0;
    uv_close((uv_handle_t *)&d->flush, on_timer_closed);
    http_server_close(d->http, on_http_closed, d);
}
