/* auth.c - token-based challenge-response over libsodium (see auth.h). */
#include "auth.h"

#include <ctype.h>
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"

int auth_key_load(const char *path, auth_key *k, char *err, size_t err_len) {
    size_t len;
    char *text = file_read_all(path, 1 << 16, &len, err, err_len);
    if (!text) return -1;
    size_t b = 0, e = len;
    while (b < e && isspace((unsigned char)text[b])) b++;
    while (e > b && isspace((unsigned char)text[e - 1])) e--;
    if (e == b) {
        snprintf(err, err_len, "%s: the token file is empty", path);
        free(text);
        return -1;
    }
    if (sodium_init() < 0) {
        snprintf(err, err_len, "libsodium could not start");
        free(text);
        return -1;
    }
    crypto_generichash(k->key, sizeof k->key, (const unsigned char *)text + b, e - b, NULL, 0);
    sodium_memzero(text, len);
    free(text);
    k->enabled = 1;
    return 0;
}

void auth_nonce(char hex[AUTH_HEX]) {
    unsigned char n[32];
    if (sodium_init() < 0) abort(); /* no randomness: nothing safe to do */
    randombytes_buf(n, sizeof n);
    sodium_bin2hex(hex, AUTH_HEX, n, sizeof n);
}

static void proof_bytes(const auth_key *k, const char *nonce, const char *who, unsigned char out[32]) {
    crypto_auth_hmacsha256_state st;
    crypto_auth_hmacsha256_init(&st, k->key, sizeof k->key);
    crypto_auth_hmacsha256_update(&st, (const unsigned char *)nonce, strlen(nonce));
    crypto_auth_hmacsha256_update(&st, (const unsigned char *)"\n", 1);
    crypto_auth_hmacsha256_update(&st, (const unsigned char *)who, strlen(who));
    crypto_auth_hmacsha256_final(&st, out);
}

void auth_proof(const auth_key *k, const char *nonce, const char *who, char hex[AUTH_HEX]) {
    unsigned char p[32];
    proof_bytes(k, nonce, who, p);
    sodium_bin2hex(hex, AUTH_HEX, p, sizeof p);
}

int auth_check(const auth_key *k, const char *nonce, const char *who, const char *proof) {
    unsigned char want[32], got[32];
    size_t n = 0;
    if (!proof || strlen(proof) != 64 ||
        sodium_hex2bin(got, sizeof got, proof, 64, NULL, &n, NULL) != 0 || n != sizeof got)
        return 0;
    proof_bytes(k, nonce, who, want);
    return sodium_memcmp(want, got, sizeof want) == 0;
}

void auth_link_keys(const auth_key *k, const char *coordinator_nonce, const char *peer_nonce,
                    unsigned char down[AUTH_KEY_BYTES], unsigned char up[AUTH_KEY_BYTES]) {
    unsigned char master[crypto_kdf_KEYBYTES];
    crypto_generichash_state st;
    crypto_generichash_init(&st, k->key, sizeof k->key, sizeof master);
    crypto_generichash_update(&st, (const unsigned char *)"tessera link v1\n", 16);
    crypto_generichash_update(&st, (const unsigned char *)coordinator_nonce, strlen(coordinator_nonce) + 1);
    crypto_generichash_update(&st, (const unsigned char *)peer_nonce, strlen(peer_nonce) + 1);
    crypto_generichash_final(&st, master, sizeof master);
    crypto_kdf_derive_from_key(down, AUTH_KEY_BYTES, 1, "tsr-link", master);
    crypto_kdf_derive_from_key(up, AUTH_KEY_BYTES, 2, "tsr-link", master);
    sodium_memzero(master, sizeof master);
}
