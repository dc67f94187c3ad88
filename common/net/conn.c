/* conn.c - framed TCP connections over libuv (see conn.h). */
#include "conn.h"
#include "address.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "seal.h"
#include "wire.h"

#define CONN_READ_BYTES (64u << 10)

struct conn {
    uv_tcp_t tcp; /* first: libuv hands back this pointer */
    conn_callbacks cb;
    void *data;
    wire_decoder dec;
    char readbuf[CONN_READ_BYTES];
    int closing;
    int started;   /* conn_start succeeded: the connection is established */
    int malformed; /* closed because the peer's byte stream was not frames */
    uint64_t bytes_in, bytes_out;
    uv_shutdown_t shutdown;
    int sealed;                            /* conn_seal was called */
    seal_dir tx, rx;                       /* keys and frame counters, each way */
    size_t max_frame;                      /* the owner's limit, before sealing's overhead */
    void (*drain_cb)(conn *c, void *arg);  /* conn_on_drain: once, when the queue falls to drain_below */
    void *drain_arg;
    size_t drain_below;
};

typedef struct {
    uv_write_t req;
    uint8_t *owned;
    conn_blob *blob;
} write_req;

conn *conn_new(uv_loop_t *loop, const conn_callbacks *cb, void *data, size_t max_frame) {
    conn *c = calloc(1, sizeof *c);
    if (!c) return NULL;
    c->cb = *cb;
    c->data = data;
    wire_decoder_init(&c->dec, max_frame);
    c->max_frame = max_frame;
    uv_tcp_init(loop, &c->tcp);
    c->tcp.data = c;
    return c;
}

uv_tcp_t *conn_tcp(conn *c) { return &c->tcp; }

void conn_set_callbacks(conn *c, const conn_callbacks *cb, void *data) {
    c->cb = *cb;
    c->data = data;
}
void *conn_data(const conn *c) { return c->data; }
void conn_set_max_frame(conn *c, size_t max_frame) {
    c->max_frame = max_frame;
    c->dec.max_frame = max_frame + (c->sealed ? SEAL_OVERHEAD : 0);
}

int conn_sealed(const conn *c) { return c->sealed; }

void conn_seal(conn *c, const unsigned char tx_key[32], const unsigned char rx_key[32]) {
    seal_init(&c->tx, tx_key);
    seal_init(&c->rx, rx_key);
    c->sealed = 1;
    conn_set_max_frame(c, c->max_frame);
}

/* Open a sealed frame and hand the frame inside to the owner. Returns
 * on_frame's answer, or 1 after closing c with the reason. */
static int open_frame(conn *c, int kind, const uint8_t *body, size_t len) {
    char reason[200];
    uint8_t *plain;
    size_t plen;
    if (seal_open(&c->rx, kind, body, len, &plain, &plen, reason, sizeof reason)) {
        c->malformed = 1;
        conn_close(c, reason, 0);
        return 1;
    }
    int rc = c->cb.on_frame(c, plain[4], plain + WIRE_HEADER_BYTES, plen - WIRE_HEADER_BYTES);
    free(plain);
    return rc;
}
int conn_is_closing(const conn *c) { return c->closing; }
int conn_malformed(const conn *c) { return c->malformed; }
uint64_t conn_bytes_in(const conn *c) { return c->bytes_in; }
uint64_t conn_bytes_out(const conn *c) { return c->bytes_out; }
size_t conn_write_queue(const conn *c) { return c->tcp.write_queue_size; }
size_t conn_pending(const conn *c) { return wire_decoder_pending(&c->dec); }
uint8_t *conn_take_frame(conn *c) { return wire_decoder_take(&c->dec); }

static void on_alloc(uv_handle_t *h, size_t suggested, uv_buf_t *buf) {
    (void)suggested;
    conn *c = h->data;
    *buf = uv_buf_init(c->readbuf, sizeof c->readbuf);
}

static int on_decoded(void *ctx, int kind, const uint8_t *body, size_t len) {
    conn *c = ctx;
    if (c->closing) return 1; /* closed by an earlier frame's handler */
    if (c->sealed) return open_frame(c, kind, body, len);
    return c->cb.on_frame(c, kind, body, len);
}

static void on_read(uv_stream_t *s, ssize_t n, const uv_buf_t *buf) {
    (void)buf;
    conn *c = s->data;
    if (c->closing) return;
    char reason[256];
    if (n < 0) {
        size_t pending = wire_decoder_pending(&c->dec);
        c->malformed = pending > 0; /* EOF or reset: either way the frame is cut short */
        if (c->malformed)
            snprintf(reason, sizeof reason, "connection %s in the middle of a frame (%zu bytes received)",
                     n == UV_EOF ? "closed" : uv_strerror((int)n), pending);
        else
            snprintf(reason, sizeof reason, "%s", n == UV_EOF ? "connection closed by peer" : uv_strerror((int)n));
        conn_close(c, reason, 0);
        return;
    }
    c->bytes_in += (uint64_t)n;
    int rc = wire_decoder_feed(&c->dec, (const uint8_t *)c->readbuf, (size_t)n, on_decoded, c, reason,
                               sizeof reason);
    if (rc == -1) {
        c->malformed = 1;
        conn_close(c, reason, 0);
    }
}

int conn_start(conn *c) {
    int rc = uv_read_start((uv_stream_t *)&c->tcp, on_alloc, on_read);
    c->started = rc == 0;
    return rc;
}

static void on_written(uv_write_t *req, int status) {
    (void)status; /* a failed write shows up as a read error or EOF too */
    write_req *w = (write_req *)req;
    conn *c = (conn *)req->handle; /* the uv_tcp_t is the conn's first member; NULL when never queued */
    free(w->owned);
    conn_blob_unref(w->blob);
    free(w);
    if (c && c->drain_cb && !c->closing && c->tcp.write_queue_size <= c->drain_below) {
        void (*cb)(conn *, void *) = c->drain_cb;
        c->drain_cb = NULL;
        cb(c, c->drain_arg);
    }
}

void conn_on_drain(conn *c, size_t below, void (*cb)(conn *c, void *arg), void *arg) {
    c->drain_cb = cb;
    c->drain_arg = arg;
    c->drain_below = below;
}

/* Queue buf for writing with w holding what to release afterwards. */
static int conn_write(conn *c, write_req *w, uint8_t *data, size_t len) {
    uv_buf_t b = uv_buf_init((char *)data, (unsigned)len);
    if (c->closing || uv_write(&w->req, (uv_stream_t *)&c->tcp, &b, 1, on_written) != 0) {
        on_written(&w->req, -1);
        return -1;
    }
    c->bytes_out += len;
    return 0;
}

int conn_send(conn *c, uint8_t *frame, size_t len) {
    if (c->sealed && frame) {
        size_t slen = 0;
        uint8_t *s = seal_wrap(&c->tx, frame, len, &slen);
        free(frame);
        if (!s) return -1;
        frame = s;
        len = slen;
    }
    write_req *w = calloc(1, sizeof *w);
    if (!w) {
        free(frame);
        return -1;
    }
    w->owned = frame;
    return conn_write(c, w, frame, len);
}

int conn_send_blob(conn *c, conn_blob *b) {
    if (c->sealed) { /* sealed per connection: no sharing */
        uint8_t *copy = malloc(b->len);
        if (!copy) return -1;
        memcpy(copy, b->data, b->len);
        return conn_send(c, copy, b->len);
    }
    write_req *w = calloc(1, sizeof *w);
    if (!w) return -1;
    b->refs++;
    w->blob = b;
    return conn_write(c, w, b->data, b->len);
}

static void on_closed(uv_handle_t *h) {
    conn *c = h->data;
    seal_wipe(&c->tx);
    seal_wipe(&c->rx);
    wire_decoder_free(&c->dec);
    memset(c, 0xdb, sizeof *c); /* poison: a use after free fails loudly */
    free(c);
}

static void on_shutdown(uv_shutdown_t *req, int status) {
    (void)status;
    conn *c = req->data;
    uv_close((uv_handle_t *)&c->tcp, on_closed);
}

void conn_close(conn *c, const char *reason, int flush) {
    if (c->closing) return;
    c->closing = 1;
    if (c->cb.on_close) c->cb.on_close(c, reason);
    uv_read_stop((uv_stream_t *)&c->tcp);
    c->shutdown.data = c;
    /* Only an established connection is shut down: libuv takes a shutdown
     * of a socket still connecting, then never completes it (the handle
     * stays open and the loop with it: a worker told to leave while it
     * connected hung until killed). */
    if (flush && c->started && uv_is_writable((uv_stream_t *)&c->tcp) &&
        uv_shutdown(&c->shutdown, (uv_stream_t *)&c->tcp, on_shutdown) == 0)
        return;
    uv_close((uv_handle_t *)&c->tcp, on_closed);
}

void conn_peer_address(const conn *c, char *out, size_t len) {
    struct sockaddr_storage ss;
    int n = sizeof ss;
    char host[64] = "?";
    int port = 0;
    if (uv_tcp_getpeername(&c->tcp, (struct sockaddr *)&ss, &n) == 0) {
        if (ss.ss_family == AF_INET) {
            uv_ip4_name((struct sockaddr_in *)&ss, host, sizeof host);
            port = ntohs(((struct sockaddr_in *)&ss)->sin_port);
        } else if (ss.ss_family == AF_INET6) {
            uv_ip6_name((struct sockaddr_in6 *)&ss, host, sizeof host);
            port = ntohs(((struct sockaddr_in6 *)&ss)->sin6_port);
        }
    }
    address_format(host, port, out, len);
}
