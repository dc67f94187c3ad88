/* auth.c - token-based challenge-response over libsodium (see auth.h). */
#include "auth.h"

#include <ctype.h>
#include <dirent.h>
#include <errno.h>
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

/* The 32 bytes of a hex proof in got; 0, or -1 when proof is not 64 hex
 * digits (got is then zeros, so the caller can compare all the same). */
static int proof_parse(const char *proof, unsigned char got[32]) {
    size_t n = 0;
    memset(got, 0, 32);
    if (!proof || strlen(proof) != 64 || sodium_hex2bin(got, 32, proof, 64, NULL, &n, NULL) != 0 || n != 32) {
        memset(got, 0, 32);
        return -1;
    }
    return 0;
}

int auth_check(const auth_key *k, const char *nonce, const char *who, const char *proof) {
    unsigned char want[32], got[32];
    int bad = proof_parse(proof, got);
    proof_bytes(k, nonce, who, want); /* even for a malformed proof: the same work either way */
    return (sodium_memcmp(want, got, sizeof want) == 0) & !bad;
}

int auth_keyring_enabled(const auth_keyring *r) {
    for (int c = AUTH_WORKER; c < AUTH_CLASSES; c++)
        if (r->keys[c].enabled) return 1;
    return r->user_count > 0;
}

/* Whether name is a user's name: 1 to AUTH_USER_NAME - 1 of [A-Za-z0-9._-]. */
static int user_name_ok(const char *name, size_t n) {
    if (n < 1 || n >= AUTH_USER_NAME) return 0;
    for (size_t i = 0; i < n; i++)
        if (!isalnum((unsigned char)name[i]) && !strchr("._-", name[i])) return 0;
    return 1;
}

static int user_cmp(const void *a, const void *b) {
    return strcmp(((const auth_user *)a)->name, ((const auth_user *)b)->name);
}

/* Read the users folder dir into users[] (sorted), *count of them. Returns
 * 0, or -1 with "PATH: reason" in err. */
static int users_load(const char *dir, auth_user *users, int *count, char *err, size_t err_len) {
    *count = 0;
    DIR *d = opendir(dir);
    if (!d) {
        snprintf(err, err_len, "%s: cannot open the users folder: %s", dir, strerror(errno));
        return -1;
    }
    struct dirent *e;
    int rc = 0;
    while (rc == 0 && (e = readdir(d)) != NULL) {
        size_t n = strlen(e->d_name);
        if (n <= 6 || strcmp(e->d_name + n - 6, ".token") != 0 || !user_name_ok(e->d_name, n - 6)) continue;
        if (*count == AUTH_USERS_MAX) {
            snprintf(err, err_len, "%s: more than %d user tokens", dir, AUTH_USERS_MAX);
            rc = -1;
            break;
        }
        auth_user *u = &users[*count];
        char path[4096];
        snprintf(path, sizeof path, "%s/%s", dir, e->d_name);
        snprintf(u->name, sizeof u->name, "%.*s", (int)(n - 6), e->d_name);
        if (auth_key_load(path, &u->key, err, err_len)) rc = -1;
        else (*count)++;
    }
    closedir(d);
    qsort(users, (size_t)*count, sizeof *users, user_cmp);
    return rc;
}

/* users[0..count) into r, the slots after them zeroed. */
static void users_store(auth_keyring *r, const auth_user *users, int count) {
    memcpy(r->users, users, (size_t)count * sizeof *users);
    sodium_memzero(r->users + count, (size_t)(AUTH_USERS_MAX - count) * sizeof *users);
    r->user_count = count;
}

int auth_keyring_reload(auth_keyring *r, char *err, size_t err_len) {
    auth_key fresh[AUTH_CLASSES] = {{0}};
    auth_user users[AUTH_USERS_MAX];
    int count = 0, rc = 0;
    for (int c = AUTH_WORKER; c < AUTH_CLASSES && rc == 0; c++)
        if (r->paths[c] && auth_key_load(r->paths[c], &fresh[c], err, err_len)) rc = -1;
    if (rc == 0 && r->users_dir) rc = users_load(r->users_dir, users, &count, err, err_len);
    if (rc == 0) {
        memcpy(r->keys, fresh, sizeof fresh);
        users_store(r, users, count);
    }
    sodium_memzero(fresh, sizeof fresh);
    sodium_memzero(users, sizeof users);
    return rc;
}

int auth_keyring_set_users(auth_keyring *r, const char *dir, char *err, size_t err_len) {
    auth_user users[AUTH_USERS_MAX];
    int count = 0;
    if (dir && users_load(dir, users, &count, err, err_len)) {
        sodium_memzero(users, sizeof users);
        return -1;
    }
    r->users_dir = dir;
    users_store(r, users, count);
    sodium_memzero(users, sizeof users);
    return 0;
}

int auth_keyring_load(auth_keyring *r, const char *both, const char *worker, const char *client, const char *admin,
                      char *err, size_t err_len) {
    memset(r, 0, sizeof *r);
    r->paths[AUTH_WORKER] = worker ? worker : both;
    r->paths[AUTH_CLIENT] = client ? client : both;
    r->paths[AUTH_ADMIN] = admin;
    return auth_keyring_reload(r, err, err_len);
}

const char *auth_class_name(auth_class c) {
    static const char *const names[] = {"none", "worker", "client", "admin"};
    return c >= AUTH_NONE && c < AUTH_CLASSES ? names[c] : "none";
}

/* hello's string field key, or "" (so that the work does not depend on it). */
static const char *hello_str(const cJSON *hello, const char *key) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(hello, key);
    return cJSON_IsString(v) && v->valuestring ? v->valuestring : "";
}

auth_class auth_check_hello(const auth_keyring *r, const char *nonce, const cJSON *hello, auth_class *offered,
                            const auth_key **key) {
    const char *role = hello_str(hello, "role"), *name = hello_str(hello, "name");
    int client = strcmp(role, "client") == 0;
    char who[160];
    snprintf(who, sizeof who, "%s:%.128s", client ? "client" : "worker", name);
    unsigned char got[32], want[32];
    int bad = proof_parse(hello_str(hello, "proof"), got);
    int ok[AUTH_CLASSES] = {0};
    for (int c = AUTH_WORKER; c < AUTH_CLASSES; c++) { /* every class, enabled or not: constant work */
        proof_bytes(&r->keys[c], nonce, who, want);
        ok[c] = (sodium_memcmp(want, got, sizeof want) == 0) & !bad & r->keys[c].enabled;
    }
    /* The users' tokens: every one tried (the work depends on their count,
     * never on the proof); a match counts only for the user named. */
    const auth_key *user_key = NULL;
    int reserved = 0; /* the name is a user's: the shared client token may not claim it */
    for (int u = 0; u < r->user_count; u++) {
        const auth_user *us = &r->users[u];
        proof_bytes(&us->key, nonce, who, want);
        int match = (sodium_memcmp(want, got, sizeof want) == 0) & !bad & us->key.enabled;
        int named = client && strcmp(us->name, name) == 0;
        reserved |= named;
        if (match & named) user_key = &us->key;
    }
    sodium_memzero(want, sizeof want);
    ok[AUTH_CLIENT] &= !reserved;
    auth_class proved = AUTH_NONE;
    if (client) proved = ok[AUTH_ADMIN] ? AUTH_ADMIN : (ok[AUTH_CLIENT] || user_key) ? AUTH_CLIENT : AUTH_NONE;
    else proved = ok[AUTH_WORKER] ? AUTH_WORKER : AUTH_NONE;
    *offered = AUTH_NONE;
    if (proved == AUTH_NONE)
        *offered = ok[AUTH_WORKER] ? AUTH_WORKER : ok[AUTH_ADMIN] ? AUTH_ADMIN : ok[AUTH_CLIENT] ? AUTH_CLIENT : AUTH_NONE;
    *key = proved == AUTH_NONE ? NULL : proved == AUTH_CLIENT && !ok[AUTH_CLIENT] ? user_key : &r->keys[proved];
    return proved;
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

/* users[] index of name, or -1. */
static int user_index(const auth_keyring *r, const char *name) {
    for (int u = 0; name && u < r->user_count; u++)
        if (strcmp(r->users[u].name, name) == 0) return u;
    return -1;
}

int auth_is_user(const auth_keyring *r, const char *name) { return user_index(r, name) >= 0; }

const auth_key *auth_key_of(const auth_keyring *r, auth_class cls, const char *name) {
    if (cls <= AUTH_NONE || cls >= AUTH_CLASSES) return NULL;
    int u = cls == AUTH_CLIENT ? user_index(r, name) : -1;
    if (u >= 0) return &r->users[u].key;
    return r->keys[cls].enabled ? &r->keys[cls] : NULL;
}
