/* http.c - the dashboard's HTTP server (see http.h): a request parser over
 * libhttp-parser with limits, connections on the caller's libuv loop,
 * one-shot answers and bounded event streams. */
#include "http.h"
#include "net/address.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <ctype.h>
#include <strings.h>

#include "connlimit.h"
#include "list.h"
#include "net/blob.h"

/* ---- the request parser ------------------------------------------------- */

static http_reqparser *rp_of(http_parser *p) { return p->data; }

static int rp_on_url(http_parser *p, const char *at, size_t len) {
    http_reqparser *r = rp_of(p);
    if (r->url_len + len >= sizeof r->url) {
        r->error = 414;
        return 1;
    }
    memcpy(r->url + r->url_len, at, len);
    r->url_len += len;
    r->url[r->url_len] = '\0';
    return 0;
}

/* The destination of a header the dashboard keeps, or NULL. */
static char *rp_header_dest(http_reqparser *r) {
    static const char *const names[] = {"authorization", "cookie", "origin", "host", "x-csrf-token"};
    char *dests[] = {r->rq.authorization, r->rq.cookie, r->rq.origin, r->rq.host, r->rq.csrf};
    for (int i = 0; i < 5; i++)
        if (r->field_len == strlen(names[i]) && strncasecmp(r->field, names[i], r->field_len) == 0) return dests[i];
    return NULL;
}

static int rp_on_field(http_parser *p, const char *at, size_t len) {
    http_reqparser *r = rp_of(p);
    if (r->last_was_value || r->headers == 0) {
        if (++r->headers > r->max_headers) {
            r->error = 431;
            return 1;
        }
        r->field_len = 0;
        r->last_was_value = 0;
    }
    size_t room = sizeof r->field - 1 - r->field_len;
    size_t n = len < room ? len : room;
    memcpy(r->field + r->field_len, at, n);
    r->field_len += n;
    if (len > room) r->field_len = sizeof r->field - 1; /* too long to be one we keep; the name is junk */
    return 0;
}

static int rp_on_value(http_parser *p, const char *at, size_t len) {
    http_reqparser *r = rp_of(p);
    if (!r->last_was_value) {
        r->last_was_value = 1;
        r->value_dest = rp_header_dest(r);
        r->value_len = 0;
    }
    if (!r->value_dest) return 0;
    if (r->value_len + len >= HTTP_VALUE_MAX) {
        r->error = 431;
        return 1;
    }
    memcpy(r->value_dest + r->value_len, at, len);
    r->value_len += len;
    r->value_dest[r->value_len] = '\0';
    return 0;
}

static int rp_on_headers_complete(http_parser *p) {
    http_reqparser *r = rp_of(p);
    snprintf(r->rq.method, sizeof r->rq.method, "%s", http_method_str((enum http_method)p->method));
    const char *q = strchr(r->url, '?');
    size_t plen = q ? (size_t)(q - r->url) : r->url_len;
    if (plen >= sizeof r->rq.path || (q && strlen(q + 1) >= sizeof r->rq.query)) {
        r->error = 414;
        return -1; /* not 1: that means "no body" to http_parser */
    }
    memcpy(r->rq.path, r->url, plen);
    r->rq.path[plen] = '\0';
    snprintf(r->rq.query, sizeof r->rq.query, "%s", q ? q + 1 : "");
    if (p->content_length != ULLONG_MAX && p->content_length > r->max_request) {
        r->error = 413;
        return -1; /* not 1: that means "no body" to http_parser */
    }
    return 0;
}

static int rp_on_body(http_parser *p, const char *at, size_t len) {
    http_reqparser *r = rp_of(p);
    if (r->rq.body_len + len + 1 > r->body_cap) {
        size_t cap = r->body_cap ? 2 * r->body_cap : 1024;
        while (cap < r->rq.body_len + len + 1) cap *= 2;
        if (cap > r->max_request + 1) cap = r->max_request + 1;
        if (r->rq.body_len + len + 1 > cap) {
            r->error = 413;
            return 1;
        }
        char *b = realloc(r->body, cap);
        if (!b) {
            r->error = 503;
            return 1;
        }
        r->body = b;
        r->body_cap = cap;
    }
    memcpy(r->body + r->rq.body_len, at, len);
    r->rq.body_len += len;
    r->body[r->rq.body_len] = '\0';
    return 0;
}

static int rp_on_complete(http_parser *p) {
    http_reqparser *r = rp_of(p);
    r->complete = 1;
    r->rq.body = r->body ? r->body : (char *)"";
    http_parser_pause(p, 1); /* one request per connection: ignore what follows */
    return 0;
}

void http_reqparser_init(http_reqparser *r, size_t max_request, int max_headers) {
    memset(r, 0, sizeof *r);
    http_parser_init(&r->p, HTTP_REQUEST);
    r->p.data = r;
    http_parser_settings_init(&r->s);
    r->s.on_url = rp_on_url;
    r->s.on_header_field = rp_on_field;
    r->s.on_header_value = rp_on_value;
    r->s.on_headers_complete = rp_on_headers_complete;
    r->s.on_body = rp_on_body;
    r->s.on_message_complete = rp_on_complete;
    r->max_request = max_request;
    r->max_headers = max_headers;
}

int http_reqparser_feed(http_reqparser *r, const char *data, size_t len) {
    if (r->complete) return 1;
    if (r->error) return r->error;
    r->seen += len;
    if (r->seen > r->max_request) return r->error = 413;
    size_t n = http_parser_execute(&r->p, &r->s, data, len);
    if (r->complete) return 1;
    if (r->error) return r->error;
    enum http_errno e = HTTP_PARSER_ERRNO(&r->p);
    if (e == HPE_HEADER_OVERFLOW) return r->error = 431;
    if (e != HPE_OK || n != len) return r->error = 400;
    return 0;
}

void http_reqparser_free(http_reqparser *r) {
    free(r->body);
    r->body = NULL;
}

/* ---- request fields ---------------------------------------------------------- */

/* The value of cookie name in a Cookie header into out; 0 or -1. */
int http_cookie_get(const char *header, const char *name, char *out, size_t n) {
    size_t nl = strlen(name);
    for (const char *p = header; *p;) {
        while (*p == ' ' || *p == ';') p++;
        if (strncmp(p, name, nl) == 0 && p[nl] == '=') {
            p += nl + 1;
            size_t len = strcspn(p, ";");
            if (len >= n) return -1;
            memcpy(out, p, len);
            out[len] = '\0';
            return 0;
        }
        p += strcspn(p, ";");
    }
    return -1;
}

/* The value of form field name in an application/x-www-form-urlencoded
 * body, decoded; 0 or -1. */
int http_form_get(const char *body, const char *name, char *out, size_t n) {
    size_t nl = strlen(name);
    for (const char *p = body; *p;) {
        size_t len = strcspn(p, "&");
        if (strncmp(p, name, nl) == 0 && p[nl] == '=') {
            size_t o = 0;
            for (size_t i = nl + 1; i < len && o + 1 < n; i++) {
                char c = p[i];
                if (c == '+') c = ' ';
                else if (c == '%' && i + 2 < len && isxdigit((unsigned char)p[i + 1]) &&
                         isxdigit((unsigned char)p[i + 2])) {
                    char hex[3] = {p[i + 1], p[i + 2], 0};
                    c = (char)strtol(hex, NULL, 16);
                    i += 2;
                }
                out[o++] = c;
            }
            out[o] = '\0';
            return 0;
        }
        p += len;
        if (*p) p++;
    }
    return -1;
}

/* ---- connections ---------------------------------------------------------- */

struct http_conn {
    http_server *s;
    uv_tcp_t tcp;
    uv_timer_t idle;
    http_reqparser *rp;
    int streaming, closing, answered;
    int counted;   /* in s->limits under ip */
    tls_conn *tls; /* HTTPS: the session (freed with c) */
    int sniffed;   /* HTTPS: the first byte has been looked at */
    int holds;     /* http_conn_hold: the memory outlives the handles */
    int gone;      /* the handles are closed (freed at the last release) */
    char ip[64];
    LIST_ENTRY(http_conn) link;
};

struct http_server {
    uv_loop_t *loop;
    http_options o;
    uv_tcp_t listener;
    http_handler handler;
    void *ctx;
    int port, conns, closing, open_handles;
    uint64_t dropped, refused, tls_failed;
    tls_config *tls; /* new connections' certificate, or NULL */
    connlimit *limits; /* connections per address and in all */
    LIST_HEAD(, http_conn) all;
    void (*closed_cb)(void *);
    void *closed_ctx;
};

typedef struct {
    uv_write_t req;
    conn_blob *blob; /* bytes shared by every write that holds them (net/blob.h) */
} http_write;

/* A blob holding a copy of len bytes, or NULL when out of memory. */
static conn_blob *blob_copy(const char *data, size_t len) {
    conn_blob *b = conn_blob_new(len);
    if (b && len) memcpy(b->data, data, len);
    return b;
}

static void server_maybe_done(http_server *s) {
    if (s->closing && s->open_handles == 0 && s->conns == 0) {
        void (*cb)(void *) = s->closed_cb;
        void *ctx = s->closed_ctx;
        connlimit_free(s->limits);
        tls_config_unref(s->tls);
        free(s);
        if (cb) cb(ctx);
    }
}

static void conn_on_handle_closed(uv_handle_t *h) {
    http_conn *c = h->data;
    if (h == (uv_handle_t *)&c->tcp) c->answered |= 2;
    else c->answered |= 4;
    if ((c->answered & 6) != 6) return;
    http_server *s = c->s;
    s->conns--;
    if (c->counted) connlimit_release(s->limits, c->ip, CONNLIMIT_OPEN);
    tls_conn_free(c->tls);
    c->tls = NULL;
    c->gone = 1;
    if (!c->holds) free(c);
    server_maybe_done(s);
}

void http_conn_hold(http_conn *c) { c->holds++; }

void http_conn_release(http_conn *c) {
    if (--c->holds == 0 && c->gone) free(c);
}

int http_conn_open(const http_conn *c) { return !c->closing; }

static void conn_close(http_conn *c) {
    if (c->closing) return;
    c->closing = 1;
    LIST_REMOVE(c, link);
    if (c->rp) {
        http_reqparser_free(c->rp);
        free(c->rp);
        c->rp = NULL;
    }
    uv_close((uv_handle_t *)&c->idle, conn_on_handle_closed);
    uv_close((uv_handle_t *)&c->tcp, conn_on_handle_closed);
}

static void on_written(uv_write_t *req, int status) {
    http_write *w = (http_write *)req;
    http_conn *c = req->data;
    conn_blob_unref(w->blob);
    free(w);
    /* answered and everything sent (a TLS handshake's writes come before
     * the answer): done */
    if (status < 0 ||
        ((c->answered & 1) && !c->streaming && uv_stream_get_write_queue_size((uv_stream_t *)&c->tcp) == 0))
        conn_close(c);
}

/* Queue the blob's bytes on the socket as they are (a reference is taken).
 * Returns 0, or -1 (the connection is closed). */
static int conn_send(http_conn *c, conn_blob *b) {
    http_write *w = malloc(sizeof *w);
    if (!w) {
        conn_close(c);
        return -1;
    }
    b->refs++;
    w->blob = b;
    w->req.data = c;
    uv_buf_t buf = uv_buf_init((char *)b->data, (unsigned)b->len);
    if (uv_write(&w->req, (uv_stream_t *)&c->tcp, &buf, 1, on_written)) {
        conn_blob_unref(b);
        free(w);
        conn_close(c);
        return -1;
    }
    return 0;
}

/* Send what the TLS session has for the peer. Returns 0, or -1 (the
 * connection is closed). */
static int conn_flush_tls(http_conn *c) {
    size_t n = c->tls ? tls_conn_pending(c->tls) : 0;
    if (!n || c->closing) return 0;
    conn_blob *b = conn_blob_new(n);
    if (!b) {
        conn_close(c);
        return -1;
    }
    b->len = tls_conn_take(c->tls, b->data, n);
    int rc = conn_send(c, b);
    conn_blob_unref(b);
    return rc;
}

/* Queue the blob's bytes for the peer, encrypted on an HTTPS connection (a
 * reference is taken). An event stream with more than max_queue bytes
 * waiting is closed instead. Returns 0, or -1 (the connection is closed). */
static int conn_write_blob(http_conn *c, conn_blob *b) {
    if (c->closing) return -1;
    if (c->streaming && uv_stream_get_write_queue_size((uv_stream_t *)&c->tcp) > c->s->o.max_queue) {
        c->s->dropped++;
        conn_close(c);
        return -1;
    }
    if (!c->tls) return conn_send(c, b);
    if (tls_conn_write(c->tls, b->data, b->len)) {
        conn_close(c);
        return -1;
    }
    return conn_flush_tls(c);
}

/* Queue len bytes (copied). Returns 0, or -1 (the connection is closed). */
static int conn_write(http_conn *c, const char *data, size_t len) {
    conn_blob *b = c->closing ? NULL : blob_copy(data, len);
    if (!b) {
        conn_close(c);
        return -1;
    }
    int rc = conn_write_blob(c, b);
    conn_blob_unref(b);
    return rc;
}

const char *http_status_text(int status) {
    switch (status) {
    case 200: return "OK";
    case 204: return "No Content";
    case 303: return "See Other";
    case 400: return "Bad Request";
    case 401: return "Unauthorized";
    case 403: return "Forbidden";
    case 404: return "Not Found";
    case 405: return "Method Not Allowed";
    case 409: return "Conflict";
    case 413: return "Content Too Large";
    case 414: return "URI Too Long";
    case 431: return "Request Header Fields Too Large";
    case 503: return "Service Unavailable";
    default: return "Error";
    }
}

conn_blob *http_response_build(int status, const char *content_type, const void *body, size_t len,
                               const char *extra_headers) {
    char head[2048];
    /* Referrer-Policy same-origin, not no-referrer: under no-referrer a
     * browser sends "Origin: null" on the page's own POSTs, which the
     * dashboard's origin check must refuse. */
    int n = snprintf(head, sizeof head,
                     "HTTP/1.1 %d %s\r\nContent-Type: %s\r\nContent-Length: %zu\r\nConnection: close\r\n"
                     "Cache-Control: no-store\r\nX-Content-Type-Options: nosniff\r\nX-Frame-Options: DENY\r\n"
                     "Referrer-Policy: same-origin\r\n%s\r\n",
                     status, http_status_text(status), content_type, len, extra_headers ? extra_headers : "");
    if (n < 0 || (size_t)n >= sizeof head) n = 0;
    conn_blob *b = conn_blob_new((size_t)n + len); /* head and body, copied once */
    if (!b) return NULL;
    memcpy(b->data, head, (size_t)n);
    if (len) memcpy(b->data + n, body, len);
    return b;
}

void http_respond_blob(http_conn *c, conn_blob *b) {
    if (c->closing || c->answered & 1) return;
    c->answered |= 1;
    uv_read_stop((uv_stream_t *)&c->tcp);
    if (!b) {
        conn_close(c);
        return;
    }
    if (conn_write_blob(c, b) == 0 && c->tls) {
        tls_conn_shutdown(c->tls);
        conn_flush_tls(c);
    }
}

void http_respond(http_conn *c, int status, const char *content_type, const void *body, size_t len,
                  const char *extra_headers) {
    if (c->closing || c->answered & 1) return;
    conn_blob *b = http_response_build(status, content_type, body, len, extra_headers);
    http_respond_blob(c, b);
    conn_blob_unref(b);
}

int http_stream_start(http_conn *c) {
    if (c->closing || c->answered & 1) return -1;
    c->answered |= 1;
    c->streaming = 1;
    uv_timer_stop(&c->idle);
    int sndbuf = 64 << 10; /* the kernel's share of a lagging stream stays small too */
    uv_send_buffer_size((uv_handle_t *)&c->tcp, &sndbuf);
    static const char head[] = "HTTP/1.1 200 OK\r\nContent-Type: text/event-stream\r\nCache-Control: no-store\r\n"
                               "X-Content-Type-Options: nosniff\r\nConnection: keep-alive\r\n\r\n: tessera\n\n";
    return conn_write(c, head, sizeof head - 1);
}

int http_server_broadcast(http_server *s, const char *data, size_t len) {
    int n = 0;
    conn_blob *b = NULL; /* one copy for every stream */
    http_conn *c, *next;
    LIST_FOREACH_SAFE(c, &s->all, link, next) {
        if (!c->streaming || c->closing) continue;
        if (!b && !(b = blob_copy(data, len))) return n;
        if (conn_write_blob(c, b) == 0) n++;
    }
    conn_blob_unref(b);
    return n;
}

static void conn_alloc(uv_handle_t *h, size_t suggested, uv_buf_t *buf) {
    (void)h;
    (void)suggested;
    static char slab[16384]; /* one loop thread; consumed before the next read */
    *buf = uv_buf_init(slab, sizeof slab);
}

static void conn_refuse(http_conn *c, int status) {
    char msg[128];
    int n = snprintf(msg, sizeof msg, "%d %s\n", status, http_status_text(status));
    http_respond(c, status, "text/plain; charset=utf-8", msg, (size_t)n, NULL);
}

/* Request bytes in plain text, from the socket or the TLS session. */
static void conn_on_plain(http_conn *c, const char *data, size_t len) {
    if (c->closing || c->streaming || (c->answered & 1)) return; /* a stream's client has nothing to say */
    int rc = http_reqparser_feed(c->rp, data, len);
    if (rc == 0) return;
    uv_timer_stop(&c->idle);
    if (rc == 1) c->s->handler(c->s->ctx, c, &c->rp->rq);
    else conn_refuse(c, rc);
    if (!c->closing && c->rp) {
        http_reqparser_free(c->rp);
        free(c->rp);
        c->rp = NULL;
    }
}

/* An HTTPS connection ends before a request: counted, closed. */
static void conn_tls_fail(http_conn *c) {
    if (!(c->answered & 1)) c->s->tls_failed++;
    conn_close(c);
}

/* Bytes from the socket of an HTTPS connection: a first byte that does not
 * open a TLS handshake record (22) is plain HTTP, answered in plain text;
 * otherwise decrypted into conn_on_plain, and the session's replies sent. */
static void conn_on_cipher(http_conn *c, const char *data, size_t len) {
    static char plain[16384]; /* one loop thread; consumed before the next read */
    if (!c->sniffed) {
        c->sniffed = 1;
        if ((unsigned char)data[0] != 22) {
            static const char msg[] = "400 this dashboard is served over HTTPS: use https:// in the address\n";
            tls_conn_free(c->tls);
            c->tls = NULL;
            c->s->tls_failed++;
            http_respond(c, 400, "text/plain; charset=utf-8", msg, sizeof msg - 1, NULL);
            return;
        }
    }
    if (tls_conn_feed(c->tls, data, len)) return conn_tls_fail(c);
    for (;;) {
        if (c->closing) return;
        ssize_t n = tls_conn_read(c->tls, plain, sizeof plain);
        if (n < 0) return conn_tls_fail(c);
        if (n == 0) break;
        conn_on_plain(c, plain, (size_t)n);
    }
    conn_flush_tls(c);
}

static void conn_on_read(uv_stream_t *st, ssize_t nread, const uv_buf_t *buf) {
    http_conn *c = st->data;
    if (nread < 0) {
        if (c->tls) return conn_tls_fail(c);
        conn_close(c);
        return;
    }
    if (nread == 0) return;
    if (c->tls) conn_on_cipher(c, buf->base, (size_t)nread);
    else conn_on_plain(c, buf->base, (size_t)nread);
}

static void conn_on_idle(uv_timer_t *t) {
    http_conn *c = t->data;
    if (!(c->answered & 1)) conn_close(c);
}

/* The peer's address of c into c->ip ("" when unknown). */
static void conn_peer_ip(http_conn *c) {
    struct sockaddr_storage a;
    int n = sizeof a;
    c->ip[0] = '\0';
    if (uv_tcp_getpeername(&c->tcp, (struct sockaddr *)&a, &n)) return;
    if (a.ss_family == AF_INET6) uv_ip6_name((struct sockaddr_in6 *)&a, c->ip, sizeof c->ip);
    else uv_ip4_name((struct sockaddr_in *)&a, c->ip, sizeof c->ip);
}

/* Count the new connection c under its address; over a cap (one address
 * holding max_per_address, or max_conns in all: nginx's limit_conn), answer
 * 503 naming the cap and close. Returns 0 (admitted), or -1 (refused). */
static int conn_admit(http_conn *c) {
    http_server *s = c->s;
    char why[200], text[300];
    conn_peer_ip(c);
    if (connlimit_admit(s->limits, c->ip, why, sizeof why) == 0) {
        c->counted = 1;
        return 0;
    }
    s->refused++;
    if (s->tls) { /* no session to answer in */
        conn_close(c);
        return -1;
    }
    if (connlimit_last_kind(s->limits) == 1)
        snprintf(text, sizeof text, "503 too many connections: %s has %d open to this dashboard (at most %d)\n", c->ip,
                 s->o.max_per_address, s->o.max_per_address);
    else
        snprintf(text, sizeof text, "503 too many connections: this dashboard has %d open (at most %d)\n", s->o.max_conns,
                 s->o.max_conns);
    http_respond(c, 503, "text/plain; charset=utf-8", text, strlen(text), "Retry-After: 1\r\n");
    return -1;
}

static void server_on_connection(uv_stream_t *listener, int status) {
    http_server *s = listener->data;
    if (status < 0 || s->closing) return;
    http_conn *c = calloc(1, sizeof *c);
    if (!c) return;
    c->s = s;
    uv_tcp_init(s->loop, &c->tcp);
    uv_timer_init(s->loop, &c->idle);
    c->tcp.data = c->idle.data = c;
    s->conns++;
    LIST_INSERT_HEAD(&s->all, c, link);
    if (uv_accept(listener, (uv_stream_t *)&c->tcp)) {
        conn_close(c);
        return;
    }
    if (conn_admit(c)) return;
    if (s->tls && !(c->tls = tls_conn_new(s->tls))) {
        conn_close(c);
        return;
    }
    if (!(c->rp = malloc(sizeof *c->rp))) {
        conn_close(c);
        return;
    }
    http_reqparser_init(c->rp, s->o.max_request, s->o.max_headers);
    uv_tcp_nodelay(&c->tcp, 1);
    uv_timer_start(&c->idle, conn_on_idle, (uint64_t)(s->o.idle_s * 1e3), 0);
    uv_read_start((uv_stream_t *)&c->tcp, conn_alloc, conn_on_read);
}

http_server *http_server_new(uv_loop_t *loop, const http_options *o, http_handler h, void *ctx, char *err,
                             size_t err_len) {
    http_server *s = calloc(1, sizeof *s);
    if (!s) {
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    s->loop = loop;
    s->o = *o;
    if (!s->o.max_request) s->o.max_request = 64 << 10;
    if (!s->o.max_headers) s->o.max_headers = 64;
    if (!s->o.max_conns) s->o.max_conns = 512;
    if (!s->o.max_per_address) s->o.max_per_address = 64;
    connlimit_caps caps = {.max_total = s->o.max_conns, .max_open = s->o.max_per_address};
    if (!(s->limits = connlimit_new(&caps))) {
        snprintf(err, err_len, "out of memory");
        free(s);
        return NULL;
    }
    if (!(s->o.idle_s > 0)) s->o.idle_s = 10;
    if (!s->o.max_queue) s->o.max_queue = 256 << 10;
    s->handler = h;
    s->ctx = ctx;
    s->o.tls = NULL; /* the reference is taken once the server exists */
    LIST_INIT(&s->all);
    struct sockaddr_storage addr;
    char where[300];
    address_format(o->host, o->port, where, sizeof where);
    int rc = uv_ip4_addr(o->host, o->port, (struct sockaddr_in *)&addr);
    if (rc) rc = uv_ip6_addr(o->host, o->port, (struct sockaddr_in6 *)&addr);
    if (rc) {
        snprintf(err, err_len, "cannot listen on %s: not a numeric IPv4 or IPv6 address", where);
        connlimit_free(s->limits);
        free(s);
        return NULL;
    }
    uv_tcp_init(loop, &s->listener);
    s->listener.data = s;
    rc = uv_tcp_bind(&s->listener, (struct sockaddr *)&addr, 0);
    if (rc == 0) rc = uv_listen((uv_stream_t *)&s->listener, 128, server_on_connection);
    if (rc) {
        snprintf(err, err_len, "cannot listen on %s: %s", where, uv_strerror(rc));
        uv_close((uv_handle_t *)&s->listener, NULL);
        uv_run(loop, UV_RUN_NOWAIT);
        connlimit_free(s->limits);
        free(s);
        return NULL;
    }
    int n = sizeof addr;
    uv_tcp_getsockname(&s->listener, (struct sockaddr *)&addr, &n);
    s->port = ntohs(addr.ss_family == AF_INET ? ((struct sockaddr_in *)&addr)->sin_port
                                               : ((struct sockaddr_in6 *)&addr)->sin6_port);
    s->open_handles = 1;
    if (o->tls) s->tls = tls_config_ref(o->tls);
    return s;
}

int http_server_port(const http_server *s) { return s->port; }

int http_server_conns(const http_server *s) { return s->conns; }

uint64_t http_server_dropped(const http_server *s) { return s->dropped; }

uint64_t http_server_refused(const http_server *s) { return s->refused; }

uint64_t http_server_tls_failed(const http_server *s) { return s->tls_failed; }

void http_server_set_tls(http_server *s, tls_config *t) {
    if (!s->tls || !t) return;
    tls_config_unref(s->tls);
    s->tls = tls_config_ref(t);
}

static void server_on_listener_closed(uv_handle_t *h) {
    http_server *s = h->data;
    s->open_handles--;
    server_maybe_done(s);
}

void http_server_close(http_server *s, void (*cb)(void *ctx), void *ctx) {
    s->closing = 1;
    s->closed_cb = cb;
    s->closed_ctx = ctx;
    http_conn *c, *next;
    LIST_FOREACH_SAFE(c, &s->all, link, next) conn_close(c);
    uv_close((uv_handle_t *)&s->listener, server_on_listener_closed);
}
