/* fuzz_seal.c - libFuzzer target: the encrypted frame layer (net/seal.h)
 * and the handshake's check (auth_check_hello), fed what a stranger on the
 * path can send.
 *
 * The first byte picks the part:
 *   even: the rest is a byte stream cut into reads (sizes from the second
 *         byte) for a frame decoder whose frames are opened as sealed
 *         frames of a link with known keys; a frame that opens goes on to
 *         the JSON parser. Must never crash or open a frame the fuzzer
 *         could not have sealed (it has no key: nothing may open).
 *         A round trip of the same bytes sealed with the right key must
 *         open to exactly them, and fail once one byte is flipped.
 *   odd:  the rest is a hello (JSON) checked against a keyring of worker,
 *         client and admin keys and two users' for a fixed nonce: no input may prove a
 *         class, since the fuzzer knows no token. */
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <errno.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "net/auth.h"
#include "net/protocol.h"
#include "net/seal.h"
#include "net/wire.h"

static auth_keyring ring;
static unsigned char down[AUTH_KEY_BYTES], up[AUTH_KEY_BYTES];
static const char *const challenge = "00112233445566778899aabbccddeeff00112233445566778899aabbccddeeff";

/* Keys from three token files written once. */
static void setup(void) {
    static int done;
    if (done) return;
    done = 1;
    const char *texts[] = {"fuzz worker token", "fuzz client token", "fuzz admin token"};
    const char *paths[3];
    static char names[3][64];
    for (int i = 0; i < 3; i++) {
        snprintf(names[i], sizeof names[i], "/tmp/fuzz-seal-token-%d-%d", i, (int)getpid());
        FILE *f = fopen(names[i], "w");
        if (!f) abort();
        fputs(texts[i], f);
        fclose(f);
        paths[i] = names[i];
    }
    char err[300];
    if (auth_keyring_load(&ring, NULL, paths[0], paths[1], paths[2], err, sizeof err)) abort();
    /* Two users' own tokens (--client-tokens): none may be proved either. */
    static char dir[64], user[2][128];
    snprintf(dir, sizeof dir, "/tmp/fuzz-seal-users-%d", (int)getpid());
    if (mkdir(dir, 0700) && errno != EEXIST) abort();
    for (int i = 0; i < 2; i++) {
        snprintf(user[i], sizeof user[i], "%s/%s.token", dir, i ? "bob" : "alice");
        FILE *f = fopen(user[i], "w");
        if (!f) abort();
        fputs(i ? "fuzz bob token" : "fuzz alice token", f);
        fclose(f);
    }
    if (auth_keyring_set_users(&ring, dir, err, sizeof err) || ring.user_count != 2) abort();
    for (int i = 0; i < 2; i++) remove(user[i]);
    rmdir(dir);
    for (int i = 0; i < 3; i++) remove(names[i]);
    auth_link_keys(&ring.keys[AUTH_WORKER], challenge, "peer nonce of the fuzz link", down, up);
}

static int on_frame(void *ctx, int kind, const uint8_t *body, size_t len) {
    seal_dir *rx = ctx;
    uint8_t *plain;
    size_t plen;
    char err[256];
    if (seal_open(rx, kind, body, len, &plain, &plen, err, sizeof err) == 0) abort(); /* forged without the key */
    return 0;
}

/* Seal data with the right key and open it again, intact and flipped. */
static void round_trip(const uint8_t *data, size_t size) {
    size_t flen, slen, plen;
    uint8_t *frame = wire_frame_new(WIRE_KIND_JSON, size, &flen), *plain;
    if (!frame) return;
    if (size) memcpy(frame + WIRE_HEADER_BYTES, data, size);
    seal_dir tx, rx, rx2;
    seal_init(&tx, up);
    seal_init(&rx, up);
    seal_init(&rx2, up);
    uint8_t *s = seal_wrap(&tx, frame, flen, &slen);
    char err[256];
    if (!s || seal_open(&rx, s[4], s + WIRE_HEADER_BYTES, slen - WIRE_HEADER_BYTES, &plain, &plen, err, sizeof err))
        abort();
    if (plen != flen || memcmp(plain, frame, flen) != 0) abort();
    free(plain);
    s[WIRE_HEADER_BYTES + (size % (slen - WIRE_HEADER_BYTES))] ^= 0x01;
    if (seal_open(&rx2, s[4], s + WIRE_HEADER_BYTES, slen - WIRE_HEADER_BYTES, &plain, &plen, err, sizeof err) == 0)
        abort(); /* an altered frame opened */
    free(s);
    free(frame);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    setup();
    if (size < 2) return 0;
    if (data[0] & 1) {
        cJSON *hello = cJSON_ParseWithLength((const char *)data + 1, size - 1);
        auth_class offered;
        const auth_key *key;
        if (auth_check_hello(&ring, challenge, hello, &offered, &key) != AUTH_NONE || offered != AUTH_NONE || key)
            abort(); /* a proof made without any token */
        cJSON_Delete(hello);
        return 0;
    }
    size_t step = 1 + data[1] % 64;
    seal_dir rx;
    seal_init(&rx, down);
    wire_decoder d;
    wire_decoder_init(&d, (1u << 16) + SEAL_OVERHEAD);
    char err[256];
    for (size_t off = 2; off < size; off += step) {
        size_t n = size - off < step ? size - off : step;
        if (wire_decoder_feed(&d, data + off, n, on_frame, &rx, err, sizeof err) != 0) break;
    }
    wire_decoder_free(&d);
    if (rx.count != 0) abort();
    round_trip(data + 2, size - 2 < 4096 ? size - 2 : 4096);
    return 0;
}
