/* tls.h - TLS for the dashboard's HTTP server (http.h), by OpenSSL with
 * memory BIOs: the server keeps its own libuv sockets and hands this module
 * the bytes it reads (ciphertext in, plaintext out) and the bytes it wants
 * to send (plaintext in, ciphertext out). No socket is touched here.
 *
 * TLS 1.2 and 1.3 only, OpenSSL's default cipher lists (forward secrecy),
 * no renegotiation. A certificate file is PEM, the server's certificate
 * first and then its chain; the key file is a PEM private key matching it.
 *
 * Ownership: a tls_config is reference counted (tls_config_ref/unref): a
 * server holds one reference, and every connection made from it holds the
 * underlying OpenSSL context, so swapping a server's config (a certificate
 * renewed, SIGHUP) leaves the open connections on the old one. One loop
 * thread per connection; configs may be shared. */
#ifndef TESSERA_TLS_H
#define TESSERA_TLS_H

#include <stddef.h>
#include <sys/types.h>

typedef struct tls_config tls_config;
typedef struct tls_conn tls_conn;

/* Load a certificate chain and its private key. Returns a config with one
 * reference, or NULL with the reason naming the file in err ("certificate
 * /etc/t/cert.pem: No such file or directory", "private key /etc/t/key.pem
 * does not match certificate /etc/t/cert.pem", "certificate ... expired on
 * 2026-01-01 00:00 UTC"). */
tls_config *tls_config_load(const char *cert_path, const char *key_path, char *err, size_t err_len);

/* Take one more reference. Returns c. */
tls_config *tls_config_ref(tls_config *c);

/* Drop one reference; the last frees the config. NULL is fine. */
void tls_config_unref(tls_config *c);

/* The certificate's subject and expiry ("CN=tessera.example, expires
 * 2027-11-27 10:00 UTC") into out, for logs. Can't fail. */
void tls_config_describe(const tls_config *c, char *out, size_t len);

/* A server-side session on config c (which it keeps alive), or NULL when
 * out of memory. */
tls_conn *tls_conn_new(tls_config *c);

/* Free the session. NULL is fine. */
void tls_conn_free(tls_conn *t);

/* Hand over len bytes read from the peer. Returns 0, or -1 when out of
 * memory. */
int tls_conn_feed(tls_conn *t, const void *data, size_t len);

/* Decrypt what has been fed into out. Returns the number of plaintext
 * bytes (> 0), 0 when more input is needed (a handshake in progress, a
 * partial record), or -1 when the session is over: a protocol error or the
 * peer's close_notify (tls_conn_error says which). Handshake replies it
 * produced wait in tls_conn_pending. */
ssize_t tls_conn_read(tls_conn *t, void *out, size_t cap);

/* Encrypt len bytes for the peer (into tls_conn_pending). Returns 0, or -1
 * (tls_conn_error) when the handshake is not done or on error. */
int tls_conn_write(tls_conn *t, const void *data, size_t len);

/* Send close_notify (into tls_conn_pending); once only. Can't fail. */
void tls_conn_shutdown(tls_conn *t);

/* Bytes waiting to be sent to the peer. */
size_t tls_conn_pending(const tls_conn *t);

/* Move up to cap waiting bytes into out. Returns how many. */
size_t tls_conn_take(tls_conn *t, void *out, size_t cap);

/* 1 once the handshake is complete. */
int tls_conn_established(const tls_conn *t);

/* The reason of the last -1, or "" (valid until the next call on t). */
const char *tls_conn_error(const tls_conn *t);

#endif
