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

#include <cjson/cJSON.h>
#include <stddef.h>

#define AUTH_KEY_BYTES 32
#define AUTH_HEX 65 /* 32 bytes as hex, plus NUL */

typedef struct {
    int enabled;
    unsigned char key[AUTH_KEY_BYTES];
} auth_key;

/* What a credential lets its holder do (docs/security.md). */
typedef enum {
    AUTH_NONE = 0,   /* no credential proved */
    AUTH_WORKER = 1, /* register as a worker and render tiles, nothing else */
    AUTH_CLIENT = 2, /* submit, watch, fetch; cancel its own jobs; never a worker */
    AUTH_ADMIN = 3,  /* a client that may also cancel others' jobs */
    AUTH_CLASSES = 4
} auth_class;

#define AUTH_USERS_MAX 64    /* per-user client tokens in a users folder */
#define AUTH_USER_NAME 64    /* a user's name, NUL included */

/* A client token of one user: only its holder may speak as name. */
typedef struct {
    char name[AUTH_USER_NAME];
    auth_key key;
} auth_user;

/* The coordinator's credentials, one key per class (keys[AUTH_NONE] is
 * unused; a class whose key is not enabled cannot be proved), and the
 * users' own client tokens. paths[] are the token files and users_dir the
 * users folder (NAME.token a user), re-read by auth_keyring_reload. A plain
 * value: copying it copies the keys. */
typedef struct {
    auth_key keys[AUTH_CLASSES];
    const char *paths[AUTH_CLASSES];
    const char *users_dir; /* NULL: no per-user tokens */
    int user_count;
    auth_user users[AUTH_USERS_MAX]; /* sorted by name */
} auth_keyring;

/* Whether any class needs a token (then every peer must prove one and links
 * are sealed). */
int auth_keyring_enabled(const auth_keyring *r);

/* Load every class whose path is set, and the users folder if set.
 * Returns 0, or -1 with "PATH: reason" in err, leaving r as it was. */
int auth_keyring_reload(auth_keyring *r, char *err, size_t err_len);

/* Per-user client tokens from the folder dir (kept by pointer; NULL:
 * none): each file NAME.token is the token of user NAME (1 to 63 letters,
 * digits, '.', '_', '-'), at most AUTH_USERS_MAX; other files are ignored.
 * A client proving a user's token speaks as that user, and only as that
 * user; a user's name may not be claimed with the shared client token.
 * Returns 0, or -1 with "PATH: reason" in err, leaving r as it was. */
int auth_keyring_set_users(auth_keyring *r, const char *dir, char *err, size_t err_len);

/* Set the token files (NULL: none) and load them: both is the one
 * --token-file of old, the worker and the client token at once; worker and
 * client override it for their class. Returns 0, or -1 with "PATH: reason"
 * in err. */
int auth_keyring_load(auth_keyring *r, const char *both, const char *worker, const char *client, const char *admin,
                      char *err, size_t err_len);

/* "worker", "client", "admin" or "none". Can't fail. */
const char *auth_class_name(auth_class c);

/* Check a hello's proof against the ring for the role it claims ("role":
 * "client" or else a worker): proof = auth_proof(key, nonce, "ROLE:NAME").
 * A client proves AUTH_CLIENT with the client token under a name that is no
 * user's, or with the token of the user its name names.
 * Every key is tried and the proof compared in constant time whatever is
 * missing or wrong in hello, so a refusal costs the same whatever caused it.
 * Returns the class proved (AUTH_WORKER for a worker; AUTH_CLIENT or
 * AUTH_ADMIN for a client), or AUTH_NONE; then *offered is the class whose
 * key made the proof when it is the wrong one for the role (a worker token
 * said to be a client), else AUTH_NONE. *key, when a class is proved, is
 * the key that seals the link. Can't fail. */
auth_class auth_check_hello(const auth_keyring *r, const char *nonce, const cJSON *hello, auth_class *offered,
                            const auth_key **key);

/* The key a peer of class cls named name proved (auth_check_hello): a
 * user's own for a client under a user's name, else the class's; NULL when
 * that key is not enabled. Can't fail. */
const auth_key *auth_key_of(const auth_keyring *r, auth_class cls, const char *name);

/* Whether name is one of the users' (--client-tokens). Can't fail. */
int auth_is_user(const auth_keyring *r, const char *name);

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
