/* blob.c - reference-counted byte buffers (blob.h). */
#include "blob.h"

#include <stdlib.h>
#include <string.h>

#include "wire.h"

conn_blob *conn_blob_new(size_t len) {
    conn_blob *b = malloc(sizeof *b + len);
    if (!b) return NULL;
    b->refs = 1;
    b->len = len;
    return b;
}

conn_blob *conn_blob_frame(int kind, const uint8_t *body, size_t len) {
    if (len >= UINT32_MAX) return NULL;
    conn_blob *b = conn_blob_new(WIRE_HEADER_BYTES + len);
    if (!b) return NULL;
    conn_blob_set_frame_header(b, kind);
    if (len) memcpy(b->data + WIRE_HEADER_BYTES, body, len);
    return b;
}

void conn_blob_set_frame_header(conn_blob *b, int kind) {
    wire_put_u32(b->data, (uint32_t)(b->len - WIRE_HEADER_BYTES + 1));
    b->data[4] = (uint8_t)kind;
}

void conn_blob_unref(conn_blob *b) {
    if (b && --b->refs == 0) free(b);
}
