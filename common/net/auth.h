/* auth.h - a shared-secret challenge-response for farm connections
 * (libsodium; docs/protocol.md, "Authentication").
 *
 * The coordinator opens every connection with a random nonce; a peer proves
 * it knows the token with HMAC-SHA-256(key, nonce "\n" who), where key is the
 * BLAKE2b-256 of the token file's contents. The token itself never crosses
 * the wire, and a proof is useless for any other connection. Peers may ask
 * the coordinator to prove itself the same way. */
#ifndef TESSERA_AUTH_H
#define TESSERA_AUTH_H

#include <stddef.h>

#define AUTH_KEY_BYTES 32
#define AUTH_HEX 65 /* 32 bytes as hex, plus NUL */

typedef struct {
    int enabled;
    unsigned char key[AUTH_KEY_BYTES];
} auth_key;

/* Read a token file (surrounding whitespace ignored) and derive the key.
 * Returns 0, or -1 with "PATH: reason" in err (unreadable, empty). */
int auth_key_load(const char *path, auth_key *k, char *err, size_t err_len);

/* A fresh random nonce as hex. Can't fail. */
void auth_nonce(char hex[AUTH_HEX]);

/* The proof that the holder of k saw nonce, speaking as who. Can't fail. */
void auth_proof(const auth_key *k, const char *nonce, const char *who, char hex[AUTH_HEX]);

/* Whether proof is right, compared in constant time. */
int auth_check(const auth_key *k, const char *nonce, const char *who, const char *proof);

/* The two keys that seal a connection's frames after the handshake
 * (conn_seal): master = BLAKE2b-256 keyed with k over "tessera link v1",
 * the coordinator's nonce and the peer's; down (coordinator to peer) and up
 * (peer to coordinator) are crypto_kdf subkeys 1 and 2 of it. Fresh nonces
 * on both sides make every connection's keys new, so frames recorded from
 * one connection are worthless in another. Can't fail. */
void auth_link_keys(const auth_key *k, const char *coordinator_nonce, const char *peer_nonce,
                    unsigned char down[AUTH_KEY_BYTES], unsigned char up[AUTH_KEY_BYTES]);

#endif
