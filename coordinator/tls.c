/* tls.c - TLS sessions over memory BIOs for the dashboard (see tls.h). */
#include "tls.h"

#include <errno.h>
#include <openssl/bio.h>
#include <openssl/err.h>
#include <openssl/pem.h>
#include <openssl/ssl.h>
#include <openssl/x509.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

struct tls_config {
    SSL_CTX *ctx;
    int refs;
};

struct tls_conn {
    SSL *ssl;
    BIO *in, *out; /* owned by ssl */
    int shut;
    char err[200];
};

/* OpenSSL's oldest queued error as text ("" when none); the queue is
 * cleared. */
static void ssl_reason(char *out, size_t len) {
    unsigned long e = ERR_get_error();
    const char *r = e ? ERR_reason_error_string(e) : NULL;
    snprintf(out, len, "%s", r ? r : (e ? "unknown OpenSSL error" : ""));
    ERR_clear_error();
}

/* t as "2026-01-01 00:00 UTC", or "?" when it does not parse. */
static void asn1_time_text(const ASN1_TIME *t, char *out, size_t len) {
    struct tm tm;
    if (!t || !ASN1_TIME_to_tm(t, &tm) || !strftime(out, len, "%Y-%m-%d %H:%M UTC", &tm)) snprintf(out, len, "?");
}

/* 0 when path can be opened for reading, else -1 with "WHAT PATH: reason". */
static int readable(const char *what, const char *path, char *err, size_t err_len) {
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, err_len, "%s %s: %s", what, path, strerror(errno));
        return -1;
    }
    fclose(f);
    return 0;
}

/* The certificate and key into ctx, checked. 0, or -1 with the reason. */
static int config_fill(SSL_CTX *ctx, const char *cert_path, const char *key_path, char *err, size_t err_len) {
    char why[160];
    if (readable("certificate", cert_path, err, err_len)) return -1;
    if (SSL_CTX_use_certificate_chain_file(ctx, cert_path) != 1) {
        ssl_reason(why, sizeof why);
        snprintf(err, err_len, "certificate %s: not a PEM certificate chain (%s)", cert_path, why);
        return -1;
    }
    FILE *f = fopen(key_path, "rb");
    if (!f) {
        snprintf(err, err_len, "private key %s: %s", key_path, strerror(errno));
        return -1;
    }
    EVP_PKEY *key = PEM_read_PrivateKey(f, NULL, NULL, NULL);
    fclose(f);
    if (!key) {
        ssl_reason(why, sizeof why);
        snprintf(err, err_len, "private key %s: not a PEM private key (%s)", key_path, why);
        return -1;
    }
    int used = SSL_CTX_use_PrivateKey(ctx, key); /* checks it against the certificate */
    EVP_PKEY_free(key);
    if (used != 1 || SSL_CTX_check_private_key(ctx) != 1) {
        ERR_clear_error();
        snprintf(err, err_len, "private key %s does not match certificate %s", key_path, cert_path);
        return -1;
    }
    X509 *x = SSL_CTX_get0_certificate(ctx);
    if (x && X509_cmp_current_time(X509_get0_notAfter(x)) < 0) {
        char when[64];
        asn1_time_text(X509_get0_notAfter(x), when, sizeof when);
        snprintf(err, err_len, "certificate %s expired on %s", cert_path, when);
        return -1;
    }
    return 0;
}

tls_config *tls_config_load(const char *cert_path, const char *key_path, char *err, size_t err_len) {
    SSL_CTX *ctx = SSL_CTX_new(TLS_server_method());
    tls_config *c = ctx ? calloc(1, sizeof *c) : NULL;
    if (!c) {
        SSL_CTX_free(ctx);
        ERR_clear_error();
        snprintf(err, err_len, "out of memory for a TLS context");
        return NULL;
    }
    SSL_CTX_set_min_proto_version(ctx, TLS1_2_VERSION);
    SSL_CTX_set_options(ctx, SSL_OP_NO_RENEGOTIATION | SSL_OP_CIPHER_SERVER_PREFERENCE | SSL_OP_NO_COMPRESSION);
    if (config_fill(ctx, cert_path, key_path, err, err_len)) {
        SSL_CTX_free(ctx);
        free(c);
        return NULL;
    }
    c->ctx = ctx;
    c->refs = 1;
    return c;
}

tls_config *tls_config_ref(tls_config *c) {
    c->refs++;
    return c;
}

void tls_config_unref(tls_config *c) {
    if (!c || --c->refs > 0) return;
    SSL_CTX_free(c->ctx);
    free(c);
}

void tls_config_describe(const tls_config *c, char *out, size_t len) {
    X509 *x = SSL_CTX_get0_certificate(c->ctx);
    char subject[256] = "?", when[64] = "?";
    if (x) {
        X509_NAME_oneline(X509_get_subject_name(x), subject, sizeof subject);
        asn1_time_text(X509_get0_notAfter(x), when, sizeof when);
    }
    snprintf(out, len, "%s, expires %s", subject, when);
}

tls_conn *tls_conn_new(tls_config *c) {
    tls_conn *t = calloc(1, sizeof *t);
    if (!t) return NULL;
    t->ssl = SSL_new(c->ctx); /* holds a reference to the context */
    t->in = BIO_new(BIO_s_mem());
    t->out = BIO_new(BIO_s_mem());
    if (!t->ssl || !t->in || !t->out) {
        SSL_free(t->ssl);
        BIO_free(t->in);
        BIO_free(t->out);
        free(t);
        ERR_clear_error();
        return NULL;
    }
    BIO_set_mem_eof_return(t->in, -1); /* an empty input is "more later", not end of file */
    SSL_set_bio(t->ssl, t->in, t->out);
    SSL_set_accept_state(t->ssl);
    return t;
}

void tls_conn_free(tls_conn *t) {
    if (!t) return;
    SSL_free(t->ssl); /* frees both BIOs */
    ERR_clear_error();
    free(t);
}

int tls_conn_feed(tls_conn *t, const void *data, size_t len) {
    const char *p = data;
    while (len) {
        int chunk = len > (1u << 30) ? 1 << 30 : (int)len;
        int n = BIO_write(t->in, p, chunk);
        if (n <= 0) {
            snprintf(t->err, sizeof t->err, "out of memory");
            return -1;
        }
        p += n;
        len -= (size_t)n;
    }
    return 0;
}

/* The reason of SSL call's result rc into t->err. Returns 0 when the call
 * only needs more input, -1 otherwise. */
static int conn_fail(tls_conn *t, int rc) {
    int e = SSL_get_error(t->ssl, rc);
    if (e == SSL_ERROR_WANT_READ) return 0;
    if (e == SSL_ERROR_ZERO_RETURN) snprintf(t->err, sizeof t->err, "the peer closed the session");
    else {
        char why[160];
        ssl_reason(why, sizeof why);
        snprintf(t->err, sizeof t->err, "TLS error: %s", why[0] ? why : "protocol error");
    }
    ERR_clear_error();
    return -1;
}

ssize_t tls_conn_read(tls_conn *t, void *out, size_t cap) {
    t->err[0] = '\0';
    int n = SSL_read(t->ssl, out, cap > (1u << 30) ? 1 << 30 : (int)cap);
    if (n > 0) return n;
    return conn_fail(t, n);
}

int tls_conn_write(tls_conn *t, const void *data, size_t len) {
    t->err[0] = '\0';
    if (!SSL_is_init_finished(t->ssl)) {
        snprintf(t->err, sizeof t->err, "the TLS handshake is not done");
        return -1;
    }
    const char *p = data;
    while (len) { /* a memory BIO takes everything: no partial writes */
        int chunk = len > (1u << 24) ? 1 << 24 : (int)len;
        int n = SSL_write(t->ssl, p, chunk);
        if (n <= 0) {
            conn_fail(t, n);
            return -1;
        }
        p += n;
        len -= (size_t)n;
    }
    return 0;
}

void tls_conn_shutdown(tls_conn *t) {
    if (t->shut || !SSL_is_init_finished(t->ssl)) return;
    t->shut = 1;
    SSL_shutdown(t->ssl); /* 0: our close_notify is queued; we do not wait for the peer's */
    ERR_clear_error();
}

size_t tls_conn_pending(const tls_conn *t) { return BIO_ctrl_pending(t->out); }

size_t tls_conn_take(tls_conn *t, void *out, size_t cap) {
    int n = BIO_read(t->out, out, cap > (1u << 30) ? 1 << 30 : (int)cap);
    return n > 0 ? (size_t)n : 0;
}

int tls_conn_established(const tls_conn *t) { return SSL_is_init_finished(t->ssl) ? 1 : 0; }

const char *tls_conn_error(const tls_conn *t) { return t->err; }
