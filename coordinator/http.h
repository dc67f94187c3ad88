/* http.h - a small HTTP/1.1 server on a libuv loop for the dashboard
 * (dashboard.h): requests parsed by Node's http_parser (libhttp-parser),
 * one request per connection (answered with "Connection: close"), and
 * Server-Sent Event streams that stay open.
 *
 * Limits keep a browser, slow or hostile, from costing the farm anything:
 * a request (line, headers and body) of at most max_request bytes (413
 * beyond), at most max_headers headers (431), at most max_conns
 * connections (the next are closed at once), idle_s to send a whole
 * request (then closed), and at most max_queue bytes waiting to be written
 * to one connection: an event stream that falls behind is dropped rather
 * than buffered, so tile traffic on the same loop never waits for it. */
#ifndef TESSERA_HTTP_H
#define TESSERA_HTTP_H

#include <stddef.h>
#include <stdint.h>
#include <uv.h>

#include <http_parser.h>

#include "net/blob.h"
#include "tls.h"

#define HTTP_PATH_MAX 512
#define HTTP_VALUE_MAX 1024

/* A parsed request. Only the headers the dashboard reads are kept. */
typedef struct {
    char method[8];              /* "GET", "POST", ... */
    char path[HTTP_PATH_MAX];    /* without the query */
    char query[HTTP_PATH_MAX];   /* after '?', or "" */
    char authorization[HTTP_VALUE_MAX], cookie[HTTP_VALUE_MAX], origin[HTTP_VALUE_MAX], host[HTTP_VALUE_MAX],
        csrf[HTTP_VALUE_MAX];    /* X-CSRF-Token */
    char *body;                  /* NUL-terminated, body_len bytes (the parser's) */
    size_t body_len;
} http_request;

/* Incremental request parser, independent of any socket (the fuzz target
 * drives it directly). */
typedef struct {
    http_parser p;
    http_parser_settings s;
    http_request rq;
    size_t max_request, seen;
    int max_headers, headers;
    int last_was_value;     /* the header callbacks' state */
    char field[64];         /* the current header's name (truncated) */
    size_t field_len;
    char *value_dest;       /* where the current header's value goes, or NULL */
    size_t value_len;
    size_t url_len;
    char url[HTTP_PATH_MAX * 2];
    char *body;
    size_t body_cap;
    int complete, error;    /* error: the status to answer with */
} http_reqparser;

/* Start parsing a request within these limits. Can't fail. */
void http_reqparser_init(http_reqparser *r, size_t max_request, int max_headers);

/* Feed bytes. Returns 0 while more is needed, 1 once a whole request is
 * in r->rq, or an HTTP status to refuse it with (400 malformed, 413 too
 * large, 414 URL too long, 431 too many or too long headers). */
int http_reqparser_feed(http_reqparser *r, const char *data, size_t len);

/* Free the body buffer. Can't fail. */
void http_reqparser_free(http_reqparser *r);

/* The value of cookie name in a Cookie header into out (NUL-terminated).
 * Returns 0, or -1 when absent or longer than n - 1. */
int http_cookie_get(const char *header, const char *name, char *out, size_t n);

/* The value of field name in an application/x-www-form-urlencoded body,
 * %-decoded and truncated to n - 1 bytes. Returns 0, or -1 when absent. */
int http_form_get(const char *body, const char *name, char *out, size_t n);

typedef struct http_server http_server;
typedef struct http_conn http_conn;

/* Called once per complete request; the handler must answer with
 * http_respond, or http_stream_start (then the connection stays open). */
typedef void (*http_handler)(void *ctx, http_conn *c, const http_request *rq);

typedef struct {
    const char *host;
    int port;           /* 0: any free port */
    size_t max_request; /* default 64 KiB */
    int max_headers;    /* default 64 */
    int max_conns;      /* default 512 */
    int max_per_address; /* connections from one address, default 64 (beyond: 503) */
    double idle_s;      /* default 10 s */
    size_t max_queue;   /* default 256 KiB (an event stream's socket buffer: 64 KiB) */
    tls_config *tls;    /* HTTPS with this certificate (the server takes a reference), or NULL */
} http_options;

/* Listen on o->host:o->port. With o->tls every connection is HTTPS: a
 * plain HTTP request is answered in plain text with 400 naming https, and
 * a connection over the caps is closed without an answer (there is no
 * session to answer in yet). Answers end with TLS close_notify. Returns
 * the server, or NULL with the reason in err ("cannot listen on
 * 127.0.0.1:8080: address already in use"). */
http_server *http_server_new(uv_loop_t *loop, const http_options *o, http_handler h, void *ctx, char *err,
                             size_t err_len);

int http_server_port(const http_server *s);

/* Keep c's memory after it closes, for an answer given later (work on
 * libuv's pool): every hold needs one release, the last of which frees a
 * closed connection. http_conn_open says whether it may still be answered.
 * Can't fail. */
void http_conn_hold(http_conn *c);
void http_conn_release(http_conn *c);
int http_conn_open(const http_conn *c);

/* The bytes of a whole answer: status line, headers (those of every
 * answer, then extra_headers) and body, with one reference; NULL when out
 * of memory. Touches no server state: callable on any thread, so a big
 * body is copied off the loop. */
conn_blob *http_response_build(int status, const char *content_type, const void *body, size_t len,
                               const char *extra_headers);

/* Send an answer from http_response_build (a reference is taken) and
 * close. */
void http_respond_blob(http_conn *c, conn_blob *b);

/* Answer and close. extra_headers: more "Name: value\r\n" lines, or NULL. */
void http_respond(http_conn *c, int status, const char *content_type, const void *body, size_t len,
                  const char *extra_headers);

/* Answer with the headers of an event stream; the connection then receives
 * every http_server_broadcast. Returns 0. */
int http_stream_start(http_conn *c);

/* Send data to every event stream; one that has more than max_queue bytes
 * waiting is closed. Returns how many streams there are. */
int http_server_broadcast(http_server *s, const char *data, size_t len);

/* Connections open now, and streams dropped for falling behind so far. */
int http_server_conns(const http_server *s);
uint64_t http_server_dropped(const http_server *s);

/* Connections answered 503 and closed at once for being over max_conns or
 * max_per_address. */
uint64_t http_server_refused(const http_server *s);

/* Serve new connections with t (a reference is taken; the previous
 * config's is dropped, and its open connections go on with it). t NULL on
 * a server without TLS: nothing happens. Can't fail. */
void http_server_set_tls(http_server *s, tls_config *t);

/* TLS connections that ended before a request: failed handshakes, plain
 * HTTP on the TLS port, peers that went away mid-handshake. */
uint64_t http_server_tls_failed(const http_server *s);

/* Close the listener and every connection; cb(ctx) runs when all are
 * closed and the server freed. */
void http_server_close(http_server *s, void (*cb)(void *ctx), void *ctx);

const char *http_status_text(int status);

#endif
