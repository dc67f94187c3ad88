/* seal.h - one direction of a sealed link: whole frames wrapped in
 * WIRE_KIND_SEALED frames, encrypted and authenticated with
 * XChaCha20-Poly1305 (libsodium; docs/protocol.md, "Encrypted links").
 *
 * The nonce is a counter of frames sealed (or opened) in that direction, so
 * the order of the frames is part of the seal: an altered, replayed,
 * reordered or missing frame fails to open. The outer header (length and
 * kind) is the AEAD's additional data. Used by conn.c (libuv peers) and by
 * the blocking command-line client (cli/client.c); keys come from
 * auth_link_keys. */
#ifndef TESSERA_SEAL_H
#define TESSERA_SEAL_H

#include <stddef.h>
#include <stdint.h>

#define SEAL_KEY_BYTES 32
#define SEAL_TAG_BYTES 16 /* crypto_aead_xchacha20poly1305_ietf_ABYTES */
#define SEAL_OVERHEAD (5 + SEAL_TAG_BYTES) /* outer header + tag, per frame */

typedef struct {
    unsigned char key[SEAL_KEY_BYTES];
    uint64_t count; /* frames sealed or opened so far: the next nonce */
} seal_dir;

/* Start a direction with key (counter 0). Can't fail. */
void seal_init(seal_dir *s, const unsigned char key[SEAL_KEY_BYTES]);

/* Forget the key. Can't fail. */
void seal_wipe(seal_dir *s);

/* The sealed frame for a whole plain frame (header included): malloc'd,
 * *out_len set; the caller frees. NULL when out of memory or too long. */
uint8_t *seal_wrap(seal_dir *s, const uint8_t *frame, size_t len, size_t *out_len);

/* Open a received frame of kind with body (header excluded). Returns 0 and
 * the whole inner frame (malloc'd, *plain_len bytes, header included, its
 * length field checked); or -1 with the reason in err ("unsealed frame
 * ...", "sealed frame N failed authentication ...", "... does not hold one
 * whole frame", out of memory); the counter then stays where it was. */
int seal_open(seal_dir *s, int kind, const uint8_t *body, size_t len, uint8_t **plain, size_t *plain_len, char *err,
              size_t err_len);

#endif
