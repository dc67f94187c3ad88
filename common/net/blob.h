/* blob.h - reference-counted byte buffers: a frame (or any bytes) written
 * to many connections is held once, and freed when the last write that
 * holds it ends. conn.h sends them; the dashboard's HTTP server (which has
 * connections of its own) shares them among its streams.
 *
 * Layer net/. Ownership: a new blob has one reference, its creator's;
 * every holder takes one (refs++) and drops it with conn_blob_unref. One
 * loop thread: the count is not atomic. */
#ifndef TESSERA_BLOB_H
#define TESSERA_BLOB_H

#include <stddef.h>
#include <stdint.h>

/* A reference-counted byte buffer: a complete frame for conn_send_blob,
 * or any bytes a writer shares among its writes (the dashboard's HTTP). */
typedef struct {
    int refs;
    size_t len;
    uint8_t data[];
} conn_blob;

/* A blob of len bytes with one reference, or NULL when out of memory. */
conn_blob *conn_blob_new(size_t len);

/* A blob holding one frame of the given kind (wire.h) with a copy of the
 * len-byte body, one reference; NULL when out of memory or when the body
 * does not fit a frame's 32-bit length. */
conn_blob *conn_blob_frame(int kind, const uint8_t *body, size_t len);

/* Write the header of a frame of the given kind at the start of b, whose
 * body (b->len - WIRE_HEADER_BYTES bytes, less than UINT32_MAX) is already
 * in place behind it: conn_blob_frame without the copy. Can't fail. */
void conn_blob_set_frame_header(conn_blob *b, int kind);

/* Drop one reference; the last frees b. NULL is fine. */
void conn_blob_unref(conn_blob *b);

#endif
