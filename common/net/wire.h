/* wire.h - frames on a byte stream: the transport layer of the farm's
 * protocol (docs/protocol.md).
 *
 * A frame is a 4-byte little-endian length L followed by L bytes: one kind
 * byte and L - 1 bytes of body. Kinds: 'J' a JSON object (control
 * messages), 'T' a rendered tile (binary), 'S' a scene bundle (binary),
 * 'D' a chunk of a streamed file.
 * A decoder never buffers more than one frame, and refuses a length above
 * its limit before allocating anything, so a peer can't make it hold more
 * than the limit however it lies. */
#ifndef TESSERA_WIRE_H
#define TESSERA_WIRE_H

#include <cjson/cJSON.h>
#include <stddef.h>
#include <stdint.h>

#define WIRE_KIND_JSON 'J'
#define WIRE_KIND_TILE 'T'
#define WIRE_KIND_SCENE 'S'
#define WIRE_KIND_SEALED 'E' /* an encrypted frame (conn_seal) */
#define WIRE_KIND_DATA 'D'   /* a chunk of a file sent in pieces (a fetched image) */
#define WIRE_HEADER_BYTES 5 /* length + kind */
#define WIRE_JSON_MAX (64u << 10) /* largest JSON control message */

/* Little-endian scalars at unaligned addresses. These can't fail. */
void wire_put_u32(uint8_t *p, uint32_t v);
void wire_put_u64(uint8_t *p, uint64_t v);
void wire_put_f32(uint8_t *p, float v);
uint32_t wire_get_u32(const uint8_t *p);
uint64_t wire_get_u64(const uint8_t *p);
float wire_get_f32(const uint8_t *p);

/* A malloc'd frame of the given kind with room for body_len body bytes at
 * frame + WIRE_HEADER_BYTES (the caller fills them and frees the frame).
 * Returns NULL when out of memory or when body_len is too large for a frame. */
uint8_t *wire_frame_new(int kind, size_t body_len, size_t *frame_len);

/* A 'J' frame holding msg printed without spaces. Returns NULL when out of
 * memory or when the text exceeds WIRE_JSON_MAX. The caller frees. */
uint8_t *wire_frame_json(const cJSON *msg, size_t *frame_len);

/* Called for every complete frame; body excludes the kind byte and is valid
 * only during the call. Return 0 to go on, non-zero to stop decoding (the
 * feed then returns that value). */
typedef int (*wire_frame_cb)(void *ctx, int kind, const uint8_t *body, size_t len);

typedef struct {
    uint8_t *buf; /* the frame being assembled (header included) */
    size_t have;  /* bytes of it received */
    size_t cap;
    size_t max_frame; /* largest accepted L */
} wire_decoder;

/* Start a decoder that accepts frames with L <= max_frame. Can't fail. */
void wire_decoder_init(wire_decoder *d, size_t max_frame);

/* Feed received bytes; calls cb for each frame completed. Returns 0; the
 * callback's non-zero value if it stopped; or -1 with the reason in err
 * (e.g. "frame of 4294967295 bytes exceeds the limit of 65536") when the
 * stream is malformed or memory ran out. After a non-zero return the
 * decoder must not be fed again. */
int wire_decoder_feed(wire_decoder *d, const uint8_t *data, size_t len, wire_frame_cb cb, void *ctx, char *err,
                      size_t err_len);

/* Bytes of an unfinished frame held (0 between frames): a peer that closes
 * with this non-zero sent a truncated frame. */
static inline size_t wire_decoder_pending(const wire_decoder *d) { return d->have; }

/* During a frame callback: take the buffer holding the frame (its body at
 * + WIRE_HEADER_BYTES; the caller frees it), so that a large body is kept
 * without copying it into new memory. The decoder allocates afresh for the
 * next frame. */
uint8_t *wire_decoder_take(wire_decoder *d);

/* Free the decoder's buffer. */
void wire_decoder_free(wire_decoder *d);

#endif
