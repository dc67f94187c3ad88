/* seal.c - sealing and opening frames of one link direction (see seal.h). */
#include "seal.h"

#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "wire.h"

_Static_assert(SEAL_TAG_BYTES == crypto_aead_xchacha20poly1305_ietf_ABYTES, "tag size");
_Static_assert(SEAL_KEY_BYTES == crypto_aead_xchacha20poly1305_ietf_KEYBYTES, "key size");
_Static_assert(SEAL_OVERHEAD == WIRE_HEADER_BYTES + SEAL_TAG_BYTES, "overhead");

void seal_init(seal_dir *s, const unsigned char key[SEAL_KEY_BYTES]) {
    memcpy(s->key, key, sizeof s->key);
    s->count = 0;
}

void seal_wipe(seal_dir *s) { sodium_memzero(s, sizeof *s); }

/* The nonce of frame number count: the counter, little-endian, then zeros. */
static void seal_nonce(uint64_t count, unsigned char n[crypto_aead_xchacha20poly1305_ietf_NPUBBYTES]) {
    memset(n, 0, crypto_aead_xchacha20poly1305_ietf_NPUBBYTES);
    for (int i = 0; i < 8; i++) n[i] = (unsigned char)(count >> (8 * i));
}

uint8_t *seal_wrap(seal_dir *s, const uint8_t *frame, size_t len, size_t *out_len) {
    size_t body = len + SEAL_TAG_BYTES;
    if (body + 1 > UINT32_MAX) return NULL;
    uint8_t *out = malloc(WIRE_HEADER_BYTES + body);
    if (!out) return NULL;
    wire_put_u32(out, (uint32_t)(body + 1));
    out[4] = WIRE_KIND_SEALED;
    unsigned char nonce[crypto_aead_xchacha20poly1305_ietf_NPUBBYTES];
    seal_nonce(s->count++, nonce);
    crypto_aead_xchacha20poly1305_ietf_encrypt(out + WIRE_HEADER_BYTES, NULL, frame, len, out, WIRE_HEADER_BYTES,
                                               NULL, nonce, s->key);
    *out_len = WIRE_HEADER_BYTES + body;
    return out;
}

int seal_open(seal_dir *s, int kind, const uint8_t *body, size_t len, uint8_t **plain, size_t *plain_len, char *err,
              size_t err_len) {
    *plain = NULL;
    if (kind != WIRE_KIND_SEALED || len < SEAL_TAG_BYTES || len + 1 > UINT32_MAX) {
        snprintf(err, err_len, "unsealed frame (kind 0x%02x) on an encrypted link", kind);
        return -1;
    }
    size_t plen = len - SEAL_TAG_BYTES;
    uint8_t *p = malloc(plen ? plen : 1), ad[WIRE_HEADER_BYTES];
    if (!p) {
        snprintf(err, err_len, "out of memory opening a sealed frame of %zu bytes", len);
        return -1;
    }
    wire_put_u32(ad, (uint32_t)(len + 1));
    ad[4] = WIRE_KIND_SEALED;
    unsigned char nonce[crypto_aead_xchacha20poly1305_ietf_NPUBBYTES];
    seal_nonce(s->count, nonce);
    if (crypto_aead_xchacha20poly1305_ietf_decrypt(p, NULL, NULL, body, len, ad, sizeof ad, nonce, s->key)) {
        free(p);
        snprintf(err, err_len,
                 "sealed frame %llu failed authentication (altered, replayed, reordered, or one went missing)",
                 (unsigned long long)s->count);
        return -1;
    }
    uint32_t inner = plen >= WIRE_HEADER_BYTES ? wire_get_u32(p) : 0;
    if (plen < WIRE_HEADER_BYTES || inner == 0 || (size_t)inner + 4 != plen) {
        free(p);
        snprintf(err, err_len, "sealed frame %llu does not hold one whole frame", (unsigned long long)s->count);
        return -1;
    }
    s->count++;
    *plain = p;
    *plain_len = plen;
    return 0;
}
