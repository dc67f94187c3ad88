/* dashboard.h - the farm watched in a browser (issue 16): pages, JSON,
 * Server-Sent Events, a live preview and Prometheus metrics, served by
 * http.h on the coordinator's own loop.
 *
 *   GET  /healthz                 "ok"
 *   GET  /metrics                 Prometheus text format 0.0.4
 *   GET  /  (and /job/N, /workers) the single-page app (web_assets.c)
 *   GET  /api/jobs, /api/workers  JSON
 *   GET  /api/events              text/event-stream: tile handed out, done,
 *                                 requeued, workers joining and leaving
 *   GET  /api/jobs/N/preview.png  the job's frame tone mapped (?exposure=S)
 *   GET  /api/csrf                the token POSTs must carry (X-CSRF-Token)
 *   GET  /api/jobs/N/image.exr, image.png  a finished job's image (download)
 *   GET  /api/jobs/N/log?last=N   the job's event log (joblog.h) as JSON
 *   POST /api/jobs/N/cancel       (not with read_only)
 *   POST /api/jobs/N/priority     priority=P (not with read_only)
 *   POST /login                   token=... -> HttpOnly SameSite=Strict cookie
 *
 * With a token every route but /healthz and /login needs the session
 * cookie or "Authorization: Bearer TOKEN". Nothing is served by path.
 * With tls_cert and tls_key everything is served over HTTPS (tls.h) and the
 * cookie is Secure. Previews and downloads are read and encoded on libuv's
 * thread pool (a live frame copied a band per loop turn), two at a time. */
#ifndef TESSERA_DASHBOARD_H
#define TESSERA_DASHBOARD_H

#include <cjson/cJSON.h>
#include <stdint.h>
#include <uv.h>

#include "farm.h"
#include "image/tonemap.h"

/* What the dashboard asks of the program that owns the jobs (the job
 * service, or `tessera render`'s local farm). All called on the loop. */
typedef struct {
    /* Append one object per job to arr: id, name, state, tiles_done,
     * tiles_total, samples, priority, width, height, spp, submitted,
     * started, finished (epoch seconds, 0 when not yet), submitter, and
     * owner when it has one. */
    void (*jobs)(void *ctx, cJSON *arr);
    /* The job's frame while it is held in memory, width * height * 3
     * floats (valid until the next callback; the dashboard copies what it
     * keeps), or -1 when there is none. */
    int (*frame)(void *ctx, uint32_t id, float **rgb, int *w, int *h);
    /* Cancel a job. 0, or -1 with the reason in err. NULL: not offered. */
    int (*cancel)(void *ctx, uint32_t id, char *err, size_t err_len);
    void *ctx;
    /* The file of the job's saved image (a PFM, read with image_read off
     * the loop) into path: with done_only, only once the job is done; else
     * the last saved (an adaptive job's previous round). 0, or -1 when there
     * is none. NULL: downloads are not offered. */
    int (*image_file)(void *ctx, uint32_t id, int done_only, char *path, size_t len);
    /* Change a job's priority. 0, or -1 with the reason in err. NULL: not
     * offered. */
    int (*priority)(void *ctx, uint32_t id, int priority, char *err, size_t err_len);
    /* Add the job's event log to out (joblog_to_json; the newest last
     * lines, 0: all), or -1 when there is no such job. NULL: the page
     * shows only the events it sees live. */
    int (*log)(void *ctx, uint32_t id, int last, cJSON *out);
    /* The job's owner, the name of the client that submitted it, into
     * owner ("" when it has none). 0, or -1 when there is no such job.
     * NULL: jobs have no owners (anyone signed in may see and change any). */
    int (*owner)(void *ctx, uint32_t id, char *owner, size_t len);
    /* 0: the dashboard takes the farm's event callback; 1: the source
     * keeps it and hands each event on with dashboard_farm_event. */
    int forwards_events;
} dashboard_source;

typedef struct {
    const char *host; /* default 127.0.0.1 */
    int port;
    const auth_keyring *auth; /* any key: HTTP needs the client or admin token too (read on
                               * every login, so a rotation by SIGHUP applies at once) */
    int read_only;        /* no POSTs but /login */
    int insecure;         /* allow a non-loopback address without a token */
    const char *tls_cert, *tls_key; /* HTTPS with this PEM certificate chain and key (both or
                                     * neither; the paths must outlive the dashboard) */
} dashboard_options;

typedef struct dashboard dashboard;

/* Parse "ADDR:PORT" for --http into o (host copied into host_buf). Returns 0
 * or -1 with the reason in err. */
int dashboard_parse_address(const char *s, dashboard_options *o, char *host_buf, size_t host_len, char *err,
                            size_t err_len);

/* Start serving on loop, watching farm f (its event callback is taken).
 * Returns the dashboard or NULL with the reason in err (cannot listen,
 * non-loopback without a token or --insecure). */
dashboard *dashboard_new(uv_loop_t *loop, farm *f, const dashboard_options *o, const dashboard_source *src,
                         char *err, size_t err_len);

int dashboard_port(const dashboard *d);

/* "https" or "http", for the address the owner prints. */
const char *dashboard_scheme(const dashboard *d);

/* The certificate served ("/CN=..., expires ...") into out. Returns 1, or 0
 * (nothing written) without HTTPS. */
int dashboard_tls_describe(const dashboard *d, char *out, size_t len);

/* Read the certificate and key files again (a renewed certificate; SIGHUP):
 * new connections get them, open ones go on. Returns 1 (re-read, what into
 * what: "CN=..., expires ..."), 0 (no HTTPS here), or -1 with the reason in
 * what (the previous certificate stays). */
int dashboard_reload_tls(dashboard *d, char *what, size_t what_len);

/* A farm event, for a source with forwards_events (d: the dashboard). */
void dashboard_farm_event(dashboard *d, const farm_event *e);

/* Stop serving; cb(ctx) once every connection is closed and d freed. */
void dashboard_close(dashboard *d, void (*cb)(void *ctx), void *ctx);

/* The request entry point, for the fuzz target: parse raw bytes as one
 * request within the dashboard's limits. Returns what http_reqparser_feed
 * returns. */
int dashboard_parse_request(const char *data, size_t len);

#endif
