/* wire.c - frame encoding and the incremental frame decoder. */
#include "wire.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

void wire_put_u32(uint8_t *p, uint32_t v) {
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

void wire_put_u64(uint8_t *p, uint64_t v) {
    for (int i = 0; i < 8; i++) p[i] = (uint8_t)(v >> (8 * i));
}

void wire_put_f32(uint8_t *p, float v) {
    uint32_t u;
    memcpy(&u, &v, 4);
    wire_put_u32(p, u);
}

uint32_t wire_get_u32(const uint8_t *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint64_t wire_get_u64(const uint8_t *p) { return (uint64_t)wire_get_u32(p) | (uint64_t)wire_get_u32(p + 4) << 32; }

float wire_get_f32(const uint8_t *p) {
    uint32_t u = wire_get_u32(p);
    float v;
    memcpy(&v, &u, 4);
    return v;
}

uint8_t *wire_frame_new(int kind, size_t body_len, size_t *frame_len) {
    if (body_len >= UINT32_MAX) return NULL;
    uint8_t *f = malloc(WIRE_HEADER_BYTES + body_len);
    if (!f) return NULL;
    wire_put_u32(f, (uint32_t)(body_len + 1));
    f[4] = (uint8_t)kind;
    *frame_len = WIRE_HEADER_BYTES + body_len;
    return f;
}

uint8_t *wire_frame_json(const cJSON *msg, size_t *frame_len) {
    char *text = cJSON_PrintUnformatted(msg);
    if (!text) return NULL;
    size_t n = strlen(text);
    uint8_t *f = n <= WIRE_JSON_MAX ? wire_frame_new(WIRE_KIND_JSON, n, frame_len) : NULL;
    if (f) memcpy(f + WIRE_HEADER_BYTES, text, n);
    free(text);
    return f;
}

void wire_decoder_init(wire_decoder *d, size_t max_frame) {
    memset(d, 0, sizeof *d);
    d->max_frame = max_frame;
}

/* Make room for need bytes in d->buf. Returns 0 or -1 (out of memory). */
static int decoder_reserve(wire_decoder *d, size_t need) {
    if (need <= d->cap) return 0;
    size_t cap = d->cap ? d->cap : 4096;
    while (cap < need) cap *= 2;
    uint8_t *b = realloc(d->buf, cap);
    if (!b) return -1;
    d->buf = b;
    d->cap = cap;
    return 0;
}

int wire_decoder_feed(wire_decoder *d, const uint8_t *data, size_t len, wire_frame_cb cb, void *ctx, char *err,
                      size_t err_len) {
    while (len > 0) {
        /* Bytes still missing: up to the header, then up to the frame's end. */
        size_t want = 4;
        if (d->have >= 4) {
            uint32_t l = wire_get_u32(d->buf);
            want = 4 + (size_t)l;
        }
        size_t take = want - d->have < len ? want - d->have : len;
        if (decoder_reserve(d, d->have + take)) {
            snprintf(err, err_len, "out of memory for a frame of %zu bytes", want);
            return -1;
        }
        memcpy(d->buf + d->have, data, take);
        d->have += take;
        data += take;
        len -= take;
        if (d->have == 4) {
            uint32_t l = wire_get_u32(d->buf);
            if (l == 0 || l > d->max_frame) {
                snprintf(err, err_len, "frame of %u bytes %s", l,
                         l == 0 ? "is empty (no kind byte)" : "exceeds the limit");
                if (l) snprintf(err + strlen(err), err_len - strlen(err), " of %zu", d->max_frame);
                return -1;
            }
            continue;
        }
        if (d->have < 4 || d->have < 4 + (size_t)wire_get_u32(d->buf)) continue;
        size_t l = wire_get_u32(d->buf);
        d->have = 0; /* before the callback, which may free the decoder's owner's state */
        int rc = cb(ctx, d->buf[4], d->buf + 5, l - 1);
        if (rc) return rc;
        if (d->cap > (1u << 20)) { /* don't keep a large buffer between large frames */
            free(d->buf);
            d->buf = NULL;
            d->cap = 0;
        }
    }
    return 0;
}

uint8_t *wire_decoder_take(wire_decoder *d) {
    uint8_t *b = d->buf;
    d->buf = NULL;
    d->cap = 0;
    return b;
}

void wire_decoder_free(wire_decoder *d) {
    free(d->buf);
    memset(d, 0, sizeof *d);
}
