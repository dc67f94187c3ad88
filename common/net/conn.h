/* conn.h - one framed TCP connection on a libuv loop: reads frames into a
 * callback, queues whole frames for writing, closes once.
 *
 * Both the coordinator and the worker speak through this. Ownership: the
 * conn owns its uv_tcp_t and its buffers; frames given to conn_send belong
 * to the conn from then on; a conn_blob is shared by reference count, so a
 * large scene bundle is held once however many peers it goes to. A conn is
 * freed by libuv's close callback after conn_close; its on_close callback
 * runs exactly once, first, so owners unlink it there. */
#ifndef TESSERA_CONN_H
#define TESSERA_CONN_H

#include <stddef.h>
#include <stdint.h>
#include <uv.h>

#include "blob.h"

typedef struct conn conn;

typedef struct {
    /* A complete frame arrived (body without the kind byte; valid during the
     * call). Return 0, or non-zero after calling conn_close on c. */
    int (*on_frame)(conn *c, int kind, const uint8_t *body, size_t len);
    /* The connection is going away: EOF, an error, a malformed frame or
     * conn_close; reason says which. Called once. */
    void (*on_close)(conn *c, const char *reason);
} conn_callbacks;

/* A connection on loop whose uv_tcp_t (conn_tcp) is initialised but neither
 * connected nor reading. max_frame bounds incoming frames (wire.h). Returns
 * NULL when out of memory. */
conn *conn_new(uv_loop_t *loop, const conn_callbacks *cb, void *data, size_t max_frame);
uv_tcp_t *conn_tcp(conn *c);
void *conn_data(const conn *c);

/* Hand the connection to a new owner: frames still buffered or arriving
 * later go to cb with data. Can't fail. */
void conn_set_callbacks(conn *c, const conn_callbacks *cb, void *data);

/* Start reading. Returns 0 or a libuv error code. */
int conn_start(conn *c);

/* Change the largest frame accepted from now on. Can't fail. */
void conn_set_max_frame(conn *c, size_t max_frame);

/* Queue a frame (malloc'd; the conn frees it). Returns 0, or -1 when the
 * connection is closing or the write failed (the frame is freed anyway). */
int conn_send(conn *c, uint8_t *frame, size_t len);

/* Queue a shared blob (the conn holds a reference until written). */
int conn_send_blob(conn *c, conn_blob *b);

/* Close: calls on_close(reason) now. With flush, queued frames are written
 * first (a last message before the close); without, or before conn_start
 * (a connection still being made), they are dropped.
 * Safe to call more than once; only the first call counts. */
void conn_close(conn *c, const char *reason, int flush);

int conn_is_closing(const conn *c);

/* In on_close: whether the close is because the peer sent something that is
 * not a well-formed frame (too long, empty, truncated). */
int conn_malformed(const conn *c);

/* Bytes received and queued for sending so far, and bytes still queued. */
uint64_t conn_bytes_in(const conn *c);
uint64_t conn_bytes_out(const conn *c);
size_t conn_write_queue(const conn *c);

/* Back-pressure for a sender that streams: call cb(c, arg) once, when a
 * write completes and at most `below` bytes are still queued. Replaces an
 * earlier request; cb NULL cancels. Not called once the connection is
 * closing (the owner's on_close runs instead). Can't fail. */
void conn_on_drain(conn *c, size_t below, void (*cb)(conn *c, void *arg), void *arg);

/* In on_frame: take the memory of the frame being delivered (the body
 * passed to on_frame is at + WIRE_HEADER_BYTES in it); the caller frees it.
 * NULL outside a frame callback. */
uint8_t *conn_take_frame(conn *c);

/* Bytes of a frame received so far but not complete (0 between frames). */
size_t conn_pending(const conn *c);

/* Seal every frame from now on (common/net/conn.c): each frame sent is
 * wrapped whole in a WIRE_KIND_SEALED frame, encrypted and authenticated
 * with XChaCha20-Poly1305 under tx_key, the nonce a counter of frames sent
 * (so order is part of the seal); each frame received must be such a frame
 * under rx_key with the next counter. An unsealed, altered, replayed,
 * reordered or missing frame closes the connection with the reason (and
 * conn_malformed). Keys: auth_link_keys. Can't fail. */
void conn_seal(conn *c, const unsigned char tx_key[32], const unsigned char rx_key[32]);

/* Whether conn_seal was called. */
int conn_sealed(const conn *c);

/* "ADDRESS:PORT" of the peer, or "?" when unknown. Can't fail. */
void conn_peer_address(const conn *c, char *out, size_t len);

#endif
