/* client.c - `tessera submit | status | workers | cancel | fetch | priority
 * | logs`: the
 * command-line client of a running tessera-coordinator (service.c).
 *
 * Plain blocking sockets: one request, one answer, with timeouts, so that a
 * dead coordinator is an error message, never a hang. The address comes from
 * --coordinator, else $TESSERA_COORDINATOR, else 127.0.0.1:7000. */
#define _GNU_SOURCE
#include "client.h"

#include "cli_util.h"

#include <errno.h>
#include <inttypes.h>
#include <netdb.h>
#include <sodium.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/time.h>
#include <time.h>
#include <unistd.h>

#include "net/address.h"
#include "args.h"
#include "fileio.h"
#include "net/auth.h"
#include "image/image.h"
#include "net/protocol.h"
#include "net/seal.h"
#include "render/model_files.h"
#include "render/scene.h"
#include "render/scene_bundle.h"
#include "render/bundle_paths.h"
#include "net/wire.h"
#include "limit.h"
#include "log.h"
#include "image/image_meta.h"

#define DEFAULT_COORDINATOR "127.0.0.1:7000"
#define IO_TIMEOUT_MS 30000
#define MAX_ANSWER LIMIT_ANSWER_BYTES

typedef struct {
    int fd;
    char where[300];
    double max_upload; /* from welcome: the largest scene bundle accepted */
    int refused;       /* the last answer was "refused" (the handshake failed) */
    int sealed;        /* every frame after the welcome is sealed (a token was given) */
    seal_dir tx, rx;   /* keys and frame counters, each way (net/seal.h) */
    const char *client_name; /* --client-name, or NULL */
} cli;

typedef struct {
    const char *coordinator;
    const char *token_file;
    const char *client_name; /* --client-name: who owns the jobs it submits */
    int insecure;            /* a coordinator beyond loopback without a token */
    int json;
    int wait;
    int partial; /* fetch: what is done so far of a running or cancelled job */
    int quiet;   /* submit -q: errors and the final line only */
    int verbose; /* submit -v: the job's size as the coordinator set it */
    const char *out;
    scene_overrides ov;
    int priority, tile_size;
    double noise_threshold; /* submit: adaptive sampling when > 0 */
    int min_spp;            /* and its first round's samples (0: the coordinator's default) */
    image_write_options wo;
    const char *camera; /* --camera NAME: a glTF's camera */
    int last;           /* logs --last N */
} cli_args;

static int cli_fail(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static int cli_fail(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("tessera: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    va_end(ap);
    return 1;
}

static double num(const cJSON *o, const char *k) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsNumber(v) ? v->valuedouble : 0;
}

static const char *str(const cJSON *o, const char *k) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, k);
    return cJSON_IsString(v) ? v->valuestring : "";
}

static int send_raw(cli *c, const uint8_t *p, size_t len) {
    while (len > 0) {
        ssize_t n = send(c->fd, p, len, MSG_NOSIGNAL);
        if (n < 0 && errno == EINTR) continue; /* poll's or recv's: a signal (SIGINT during --wait) */
        if (n <= 0) return cli_fail("lost the coordinator at %s: %s", c->where, strerror(errno));
        p += n;
        len -= (size_t)n;
    }
    return 0;
}

/* How long a read may wait: IO_TIMEOUT_MS, or $TESSERA_CLIENT_TIMEOUT
 * seconds (1 to 86400) when set. */
static int io_timeout_ms(void) {
    const char *e = getenv("TESSERA_CLIENT_TIMEOUT");
    char *end;
    long s = e && *e ? strtol(e, &end, 10) : 0;
    return e && *e && *end == 0 && s >= 1 && s <= 86400 ? (int)s * 1000 : IO_TIMEOUT_MS;
}

static int read_all(cli *c, uint8_t *p, size_t len) {
    while (len > 0) {
        struct pollfd pf = {c->fd, POLLIN, 0};
        int r = poll(&pf, 1, io_timeout_ms());
        if (r == 0)
            return cli_fail("the coordinator at %s did not answer within %d s (TESSERA_CLIENT_TIMEOUT sets the wait)",
                            c->where, io_timeout_ms() / 1000);
        ssize_t n = r > 0 ? recv(c->fd, p, len, 0) : -1;
        if (n < 0 && errno == EINTR) continue; /* poll's or recv's: a signal (SIGINT during --wait) */
        if (n <= 0) return cli_fail("lost the coordinator at %s: %s", c->where, n == 0 ? "connection closed" : strerror(errno));
        p += n;
        len -= (size_t)n;
    }
    return 0;
}

/* Send one whole frame, sealed once the link is. Returns 0 or 1 (printed). */
static int send_all(cli *c, const uint8_t *frame, size_t len) {
    if (!c->sealed) return send_raw(c, frame, len);
    size_t slen;
    uint8_t *s = seal_wrap(&c->tx, frame, len, &slen);
    int rc = s ? send_raw(c, s, slen) : cli_fail("out of memory");
    free(s);
    return rc;
}

/* Read one frame as it came into a malloc'd body (the caller frees).
 * Returns its kind or -1 (printed). */
static int read_raw_frame(cli *c, uint8_t **body, size_t *len) {
    uint8_t hdr[WIRE_HEADER_BYTES];
    if (read_all(c, hdr, sizeof hdr)) return -1;
    size_t l = wire_get_u32(hdr);
    if (l < 1 || l > MAX_ANSWER + (c->sealed ? SEAL_OVERHEAD : 0)) return cli_fail("the coordinator at %s sent a malformed frame", c->where), -1;
    *body = malloc(l);
    if (!*body) return cli_fail("out of memory for a %zu-byte answer", l), -1;
    if (read_all(c, *body, l - 1)) {
        free(*body);
        return -1;
    }
    *len = l - 1;
    return hdr[4];
}

/* Read one frame (opened, when the link is sealed) into a malloc'd body
 * (the caller frees). Returns its kind or -1 (printed: a frame that fails
 * to open ends the connection, naming the fault). */
static int read_frame(cli *c, uint8_t **body, size_t *len) {
    uint8_t *raw = NULL;
    size_t rlen = 0;
    int kind = read_raw_frame(c, &raw, &rlen);
    if (kind < 0 || !c->sealed) {
        *body = raw;
        *len = rlen;
        return kind;
    }
    uint8_t *plain;
    size_t plen;
    char err[200];
    int rc = seal_open(&c->rx, kind, raw, rlen, &plain, &plen, err, sizeof err);
    free(raw);
    if (rc) return cli_fail("the link to the coordinator at %s is not intact: %s; disconnecting", c->where, err), -1;
    int inner = plain[4];
    memmove(plain, plain + WIRE_HEADER_BYTES, plen - WIRE_HEADER_BYTES);
    *body = plain;
    *len = plen - WIRE_HEADER_BYTES;
    return inner;
}

static int send_json(cli *c, cJSON *m) {
    size_t len;
    uint8_t *f = m ? wire_frame_json(m, &len) : NULL;
    cJSON_Delete(m);
    if (!f) return cli_fail("out of memory");
    int rc = send_all(c, f, len);
    free(f);
    return rc;
}

/* Read the answer to a request: a JSON object of type want, or an error
 * (printed; NULL returned). */
static cJSON *read_answer(cli *c, const char *want) {
    uint8_t *body;
    size_t len;
    int kind = read_frame(c, &body, &len);
    if (kind < 0) return NULL;
    char err[256];
    const char *type;
    cJSON *m = kind == WIRE_KIND_JSON ? proto_parse_json(body, len, &type, err, sizeof err) : NULL;
    free(body);
    if (!m) return cli_fail("the coordinator at %s sent an unexpected answer", c->where), NULL;
    if (strcmp(type, want) == 0) return m;
    const cJSON *r = cJSON_GetObjectItemCaseSensitive(m, "reason");
    char reason[1100]; /* the peer's text, escaped (log.h) */
    log_escape(cJSON_IsString(r) ? r->valuestring : "the coordinator refused the request", reason, sizeof reason);
    c->refused = strcmp(type, "refused") == 0;
    cli_fail("%s", reason);
    cJSON_Delete(m);
    return NULL;
}

/* Answer the challenge, say hello as a client (its name bound to the
 * proof), check the coordinator's proof and seal the link when key is
 * enabled. Returns 0 or 1 (printed). */
static int cli_hello(cli *c, auth_key *key, const char *token) {
    cJSON *ch = read_answer(c, "challenge");
    if (!ch) return 1;
    char nonce[AUTH_HEX], proof[AUTH_HEX], theirs[200], who[160];
    snprintf(theirs, sizeof theirs, "%s", str(ch, "nonce"));
    cJSON_Delete(ch);
    const char *name = getenv("TESSERA_CLIENT_NAME");
    if (!name || !*name) name = "tessera-cli";
    if (c->client_name) name = c->client_name;
    cJSON *h = cJSON_CreateObject();
    cJSON_AddStringToObject(h, "type", "hello");
    cJSON_AddStringToObject(h, "role", "client");
    cJSON_AddNumberToObject(h, "protocol", PROTOCOL_VERSION);
    cJSON_AddStringToObject(h, "build", protocol_build_id());
    cJSON_AddStringToObject(h, "name", name);
    cJSON_AddNumberToObject(h, "threads", 1);
    if (key->enabled) {
        snprintf(who, sizeof who, "client:%.128s", name);
        auth_proof(key, theirs, who, proof);
        auth_nonce(nonce);
        cJSON_AddStringToObject(h, "proof", proof);
        cJSON_AddStringToObject(h, "nonce", nonce);
    }
    if (send_json(c, h)) return 1;
    c->refused = 0;
    cJSON *w = read_answer(c, "welcome");
    if (!w && c->refused && !key->enabled)
        cli_fail("the coordinator at %s requires a token: give its client token file with --token-file F or "
                 "TESSERA_CLIENT_TOKEN_FILE=F", c->where);
    else if (!w && c->refused)
        cli_fail("the coordinator at %s did not accept the token in %s (is it the client or admin token?)", c->where,
                 token);
    int ok = w && (!key->enabled || auth_check(key, nonce, "coordinator", str(w, "proof")));
    c->max_upload = num(w, "max_upload");
    if (w && !ok) cli_fail("the coordinator at %s could not prove it knows the token", c->where);
    cJSON_Delete(w);
    if (ok && key->enabled) { /* every frame after the welcome is sealed, both ways */
        unsigned char down[AUTH_KEY_BYTES], up[AUTH_KEY_BYTES];
        auth_link_keys(key, theirs, nonce, down, up);
        seal_init(&c->tx, up);
        seal_init(&c->rx, down);
        c->sealed = 1;
        sodium_memzero(down, sizeof down);
        sodium_memzero(up, sizeof up);
    }
    sodium_memzero(key, sizeof *key);
    return ok ? 0 : 1;
}

/* Connect, answer the challenge and say hello as a client. Returns 0 or 1
 * (printed). */
static int cli_open(cli *c, const cli_args *args) {
    auth_key key = {0};
    char err[256];
    memset(c, 0, sizeof *c);
    c->fd = -1;
    c->client_name = args->client_name;
    const char *token = args->token_file ? args->token_file : getenv("TESSERA_CLIENT_TOKEN_FILE");
    if (!token || !*token) token = getenv("TESSERA_TOKEN_FILE");
    if (token && *token && auth_key_load(token, &key, err, sizeof err)) return cli_fail("%s", err);
    const char *addr = args->coordinator ? args->coordinator : getenv("TESSERA_COORDINATOR");
    if (!addr || !*addr) addr = DEFAULT_COORDINATOR;
    char host[256], port_s[16];
    int port;
    if (address_parse(addr, host, sizeof host, &port, err, sizeof err)) return cli_fail("--coordinator %s", err);
    if (!key.enabled && !args->insecure && !address_is_loopback(host))
        return cli_fail("--coordinator %s without a token: the scene and the images would cross the network in "
                        "clear; give the client token with --token-file F, or --insecure on a network you trust", addr);
    snprintf(c->where, sizeof c->where, "%s", addr);
    snprintf(port_s, sizeof port_s, "%d", port);
    struct addrinfo hints = {.ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM}, *res;
    int rc = getaddrinfo(host, port_s, &hints, &res);
    if (rc) return cli_fail("cannot reach the coordinator at %s: %s", addr, gai_strerror(rc));
    c->fd = -1;
    int saved = 0;
    for (struct addrinfo *a = res; a && c->fd < 0; a = a->ai_next) {
        c->fd = socket(a->ai_family, a->ai_socktype, 0);
        int ms = io_timeout_ms(); /* Linux applies the send timeout to connect() too */
        struct timeval tv = {ms / 1000, (ms % 1000) * 1000};
        if (c->fd >= 0) setsockopt(c->fd, SOL_SOCKET, SO_SNDTIMEO, &tv, sizeof tv);
        if (c->fd >= 0 && connect(c->fd, a->ai_addr, a->ai_addrlen) != 0) {
            saved = errno;
            close(c->fd);
            c->fd = -1;
        }
    }
    freeaddrinfo(res);
    if (c->fd < 0) return cli_fail("cannot reach the coordinator at %s: %s", addr, strerror(saved));
    return cli_hello(c, &key, token);
}

static void cli_close(cli *c) {
    if (c->fd >= 0) close(c->fd);
    seal_wipe(&c->tx);
    seal_wipe(&c->rx);
}

/* ---- requests ------------------------------------------------------------------ */

/* A listing the coordinator sent as pages ("more": true on all but the
 * last, docs/protocol.md): read the rest and append their arrays under key
 * to first's. Returns first, or NULL (printed; first freed). */
static cJSON *read_pages(cli *c, cJSON *first, const char *want, const char *key) {
    cJSON *all = cJSON_GetObjectItemCaseSensitive(first, key);
    while (first && cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(first, "more"))) {
        cJSON *next = read_answer(c, want);
        if (!next) {
            cJSON_Delete(first);
            return NULL;
        }
        cJSON *arr = cJSON_GetObjectItemCaseSensitive(next, key), *item;
        while (all && arr && (item = cJSON_DetachItemViaPointer(arr, arr->child)) != NULL) cJSON_AddItemToArray(all, item);
        cJSON_ReplaceItemInObjectCaseSensitive(first, "more", cJSON_CreateBool(
                                                                  cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(next, "more"))));
        cJSON_Delete(next);
    }
    cJSON_DeleteItemFromObjectCaseSensitive(first, "more");
    return first;
}

/* A request message: type, and job when job >= 0 (the caller may add
 * fields before sending it). */
static cJSON *request_new(const char *type, long job) {
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", type);
    if (job >= 0) cJSON_AddNumberToObject(m, "job", (double)job);
    return m;
}

/* Send m (taken) and read the answer of type want, every page of it.
 * Returns it, or NULL (printed). */
static cJSON *request_send(cli *c, cJSON *m, const char *want) {
    cJSON *r = send_json(c, m) ? NULL : read_answer(c, want);
    const char *key = strcmp(want, "status") == 0    ? "jobs"
                      : strcmp(want, "workers") == 0 ? "workers"
                      : strcmp(want, "logs") == 0    ? "lines"
                                                     : NULL;
    return r && key ? read_pages(c, r, want, key) : r;
}

static cJSON *request(cli *c, const char *type, long job, const char *want) {
    return request_send(c, request_new(type, job), want);
}


static void print_json(const cJSON *m) {
    char *t = cJSON_Print(m);
    if (t) puts(t);
    free(t);
}

/* Warn that a partial image's missing tiles are black, naming them. */
static void warn_partial(const cJSON *p, const char *out) {
    int total = (int)num(p, "tiles_total"), done = (int)num(p, "tiles_done"), ts = (int)num(p, "tile_size");
    if (done >= total) return;
    fprintf(stderr,
            "tessera: warning: job %d is %s: %d of %d tiles are not rendered yet and are black in %s: "
            "tiles %s (%dx%d pixels each, numbered row by row from the top left)\n",
            (int)num(p, "job"), str(p, "state"), total - done, total, out, str(p, "missing"), ts, ts);
}

/* Receive the D frames of a streamed image into the open file fd (tmp
 * names it) until image_end, checking the byte count and BLAKE2b-256
 * against it and against the image message's size. Returns 0 or 1. */
static int receive_stream(cli *c, long job, const cJSON *head, int fd, const char *tmp) {
    double want = num(head, "bytes");
    uint64_t got = 0;
    crypto_generichash_state hs;
    crypto_generichash_init(&hs, NULL, 0, 32);
    for (;;) {
        uint8_t *body;
        size_t len;
        int kind = read_frame(c, &body, &len);
        if (kind < 0) return 1;
        if (kind == WIRE_KIND_DATA) {
            crypto_generichash_update(&hs, body, len);
            got += len;
            int over = (double)got > want, werr = over ? 0 : file_write_all(fd, body, len);
            free(body);
            if (over) return cli_fail("job %ld: the coordinator sent more than the %.0f bytes it announced", job, want);
            if (werr) return cli_fail("%s: cannot write: %s", tmp, strerror(werr));
            continue;
        }
        char err[256], hex[65];
        const char *type;
        cJSON *e = kind == WIRE_KIND_JSON ? proto_parse_json(body, len, &type, err, sizeof err) : NULL;
        free(body);
        if (!e) return cli_fail("job %ld: the coordinator sent a malformed image stream", job);
        unsigned char h[32];
        crypto_generichash_final(&hs, h, sizeof h);
        sodium_bin2hex(hex, sizeof hex, h, sizeof h);
        int end = strcmp(type, "image_end") == 0, ok = end && (double)got == want && num(e, "bytes") == want &&
                                                     strcmp(str(e, "blake2b"), hex) == 0;
        if (!ok) {
            const cJSON *r = cJSON_GetObjectItemCaseSensitive(e, "reason");
            if (end) cli_fail("job %ld: the image arrived damaged (%" PRIu64 " of %.0f bytes, BLAKE2b %s against %s)", job,
                              got, want, hex, str(e, "blake2b"));
            else cli_fail("%s", cJSON_IsString(r) ? r->valuestring : "unexpected answer during fetch");
        }
        cJSON_Delete(e);
        return ok ? 0 : 1;
    }
}

/* A streamed image (fetch.h on the coordinator): written as it arrives to
 * a temporary file beside out, checked, then renamed to out (PFM, the
 * format it comes in) or converted to out's format. Returns 0 or 1. */
static int fetch_stream(cli *c, long job, const cJSON *head, const char *out, image_write_options *wo) {
    char tmp[4200], err[1024];
    snprintf(tmp, sizeof tmp, "%s.XXXXXX.pfm", out);
    int fd = mkstemps(tmp, 4);
    if (fd < 0) return cli_fail("%s: cannot create: %s", tmp, strerror(errno));
    mode_t mask = umask(0);
    umask(mask);
    fchmod(fd, 0666 & ~mask); /* as any file the client writes, not mkstemps' 0600 */
    int rc = receive_stream(c, job, head, fd, tmp);
    if (rc == 0 && (fsync(fd) != 0 || close(fd) != 0)) rc = cli_fail("%s: %s", tmp, strerror(errno));
    else if (rc) close(fd);
    const char *dot = strrchr(out, '.');
    if (rc == 0 && dot && strcasecmp(dot, ".pfm") == 0) {
        if (rename(tmp, out) != 0) rc = cli_fail("%s: cannot rename to %s: %s", tmp, out, strerror(errno));
    } else if (rc == 0) {
        image img;
        rc = image_read(tmp, &img, err, sizeof err) ? cli_fail("%s", err) : 0;
        if (rc == 0 && image_write(out, &img, wo, err, sizeof err)) rc = cli_fail("%s", err);
        if (rc == 0 || img.rgb) image_free(&img);
    }
    unlink(tmp); /* gone already when renamed */
    return rc;
}

/* Fetch a job's image (partial: what is done so far, with a warning) and
 * write it to out. Returns 0 or 1. */
static int fetch_image(cli *c, long job, const char *out, image_write_options *wo, int partial) {
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", "fetch");
    cJSON_AddNumberToObject(m, "job", (double)job);
    if (partial) cJSON_AddTrueToObject(m, "partial");
    if (send_json(c, m)) return 1;
    uint8_t *body;
    size_t len;
    int kind = read_frame(c, &body, &len);
    if (kind < 0) return 1;
    while (kind == WIRE_KIND_JSON) {
        char err[256];
        const char *type;
        cJSON *e = proto_parse_json(body, len, &type, err, sizeof err);
        free(body);
        if (e && strcmp(type, "image") == 0) { /* a finished job's image, in chunks */
            int rc = fetch_stream(c, job, e, out, wo);
            cJSON_Delete(e);
            return rc;
        }
        if (e && partial && strcmp(type, "partial") == 0) { /* the image follows, streamed */
            warn_partial(e, out);
            cJSON_Delete(e);
            if ((kind = read_frame(c, &body, &len)) < 0) return 1;
            partial = 0;
            continue;
        }
        const cJSON *r = cJSON_GetObjectItemCaseSensitive(e, "reason");
        cli_fail("%s", cJSON_IsString(r) ? r->valuestring : "unexpected answer to fetch");
        cJSON_Delete(e);
        return 1;
    }
    free(body);
    return cli_fail("job %ld: the coordinator sent a malformed answer to fetch", job);
}

/* fetch_image with the job's scene, spp and seed in the file's header
 * (image_meta.h): the same header as `tessera render` writes. */
static int fetch_to(cli *c, long job, const char *out, image_write_options *wo, int partial) {
    cJSON *st = request(c, "status", job, "status");
    if (!st) return 1;
    const cJSON *j = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(st, "jobs"), 0);
    image_meta meta;
    image_meta_apply(&meta, str(j, "name"), (int)num(j, "spp"), strtoull(str(j, "seed"), NULL, 10), wo);
    int rc = fetch_image(c, job, out, wo, partial);
    cJSON_Delete(st);
    return rc;
}

/* SIGINT while `submit --wait` waits: set by the handler, acted on between
 * polls (the job is cancelled on the coordinator). */
static volatile sig_atomic_t interrupted;

static void on_interrupt(int sig) {
    interrupted = sig;
    signal(sig, SIG_DFL); /* a second Ctrl-C ends the client at once */
}

/* Catch (on = 1) or stop catching SIGINT and SIGTERM. */
static void catch_interrupts(int on) {
    struct sigaction sa = {.sa_handler = on ? on_interrupt : SIG_DFL}; /* no SA_RESTART: a sleep ends early */
    sigemptyset(&sa.sa_mask);
    sigaction(SIGINT, &sa, NULL);
    sigaction(SIGTERM, &sa, NULL);
}

/* Cancel the job after an interrupt; returns 128 + the signal. */
static int cancel_interrupted(cli *c, long job) {
    int sig = interrupted;
    cJSON *r = request(c, "cancel", job, "cancelled");
    if (r) fprintf(stderr, "tessera: interrupted: job %ld cancelled on the coordinator\n", job);
    else fprintf(stderr, "tessera: interrupted: job %ld could not be cancelled (see above); "
                         "`tessera status %ld` shows it\n", job, job);
    cJSON_Delete(r);
    return 128 + sig;
}

/* Poll until the job ends; returns its final status object (caller frees)
 * or NULL (printed). A SIGINT or SIGTERM meanwhile returns NULL with
 * `interrupted` set. */
static cJSON *wait_job(cli *c, long job, int quiet) {
    cli_progress_state ps;
    cli_progress_init(&ps);
    for (;;) {
        if (interrupted) return NULL;
        cJSON *st = request(c, "status", job, "status");
        if (!st) return NULL;
        cJSON *j = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(st, "jobs"), 0);
        if (!j) {
            cJSON_Delete(st);
            return cli_fail("job %ld vanished from the coordinator", job), NULL;
        }
        int ended = strcmp(str(j, "state"), "running") != 0 && strcmp(str(j, "state"), "queued") != 0;
        if (!quiet)
            cli_progress_show(&ps, (int)num(j, "tiles_done"), (int)num(j, "tiles_total"), num(j, "samples_per_s"),
                              (int)num(st, "workers"), num(j, "eta_s"), ended);
        if (ended) {
            cJSON *copy = cJSON_Duplicate(j, 1);
            cJSON_Delete(st);
            return copy;
        }
        cJSON_Delete(st);
        struct timespec ts = {0, 250000000};
        nanosleep(&ts, NULL);
    }
}

static int do_submit(const cli_args *a, const char *scene_path) {
    char err[1024], hash[SCENE_BUNDLE_HASH_HEX], out_default[512];
    const char *out = a->out;
    if (!out) {
        cli_default_output(scene_path, out_default, sizeof out_default);
        out = out_default;
    }
    if (a->wait && image_check_path(out, err, sizeof err)) /* before the upload and the wait */
        return cli_fail("%s (nothing submitted)", err);
    scene_bundle b;
    cli_note_terminal_scene(scene_path);
    if (scene_bundle_read(scene_path, &b, err, sizeof err)) return cli_fail("%s", err);
    if ((a->camera && model_bundle_select_camera(&b, a->camera, err, sizeof err)) ||
        bundle_paths_check(&b, scene_path, err, sizeof err)) { /* never send a file from outside the scene's folder */
        scene_bundle_free(&b);
        return cli_fail("%s", err);
    }
    for (size_t i = 0; a->verbose && i < b.count; i++) { /* -v: every file that leaves this machine */
        char name[600];
        log_escape(i == 0 ? scene_path : b.files[i].name, name, sizeof name);
        fprintf(stderr, "sending %s (%zu bytes)\n", name, b.files[i].len);
    }
    size_t len;
    uint8_t *bytes = scene_bundle_serialise(&b, &len);
    scene_bundle_free(&b);
    if (!bytes) return cli_fail("%s: the scene and its meshes are too large to send", scene_path);
    scene_bundle_hash(bytes, len, hash);
    cli c;
    if (cli_open(&c, a)) {
        free(bytes);
        return 1;
    }
    if (c.max_upload > 0 && (double)len > c.max_upload) {
        free(bytes);
        cli_close(&c);
        return cli_fail("%s: the scene and its meshes are %.1f MiB; the coordinator accepts at most %.1f MiB "
                        "(its --max-upload)", scene_path, (double)len / 1048576.0, c.max_upload / 1048576.0);
    }
    size_t flen;
    uint8_t *frame = wire_frame_new(WIRE_KIND_SCENE, len, &flen);
    int rc = frame ? 0 : cli_fail("out of memory");
    if (frame) {
        memcpy(frame + WIRE_HEADER_BYTES, bytes, len);
        rc = send_all(&c, frame, flen);
    }
    free(frame);
    free(bytes);
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", "submit");
    cJSON_AddStringToObject(m, "scene", hash);
    cJSON_AddStringToObject(m, "name", strcmp(scene_path, "-") ? scene_path : "<stdin>");
    if (a->ov.width > 0) cJSON_AddNumberToObject(m, "width", a->ov.width);
    if (a->ov.height > 0) cJSON_AddNumberToObject(m, "height", a->ov.height);
    if (a->ov.spp > 0) cJSON_AddNumberToObject(m, "spp", a->ov.spp);
    if (a->ov.max_depth > 0) cJSON_AddNumberToObject(m, "max_depth", a->ov.max_depth);
    if (a->ov.has_roulette_depth) cJSON_AddNumberToObject(m, "roulette_depth", a->ov.roulette_depth);
    if (a->ov.has_seed) {
        char seed[32];
        snprintf(seed, sizeof seed, "%llu", (unsigned long long)a->ov.seed);
        cJSON_AddStringToObject(m, "seed", seed);
    }
    cJSON_AddNumberToObject(m, "priority", a->priority);
    const char *user = getenv("USER"); /* who submits, shown by status and the dashboard */
    if (!user || !*user) user = getenv("LOGNAME");
    if (user && *user && strlen(user) < 64) cJSON_AddStringToObject(m, "user", user);
    if (a->tile_size > 0) cJSON_AddNumberToObject(m, "tile_size", a->tile_size);
    if (a->noise_threshold > 0) cJSON_AddNumberToObject(m, "noise_threshold", a->noise_threshold);
    if (a->min_spp > 0) cJSON_AddNumberToObject(m, "min_spp", a->min_spp);
    cJSON *r = rc == 0 && send_json(&c, m) == 0 ? read_answer(&c, "submitted") : NULL;
    if (rc) cJSON_Delete(m);
    if (!r) {
        cli_close(&c);
        return 1;
    }
    long job = (long)num(r, "job");
    if (str(r, "note")[0] && !a->quiet) { /* e.g. queued until its frame fits the coordinator's --max-memory */
        char note[600];
        log_escape(str(r, "note"), note, sizeof note);
        fprintf(stderr, "job %ld: %s\n", job, note);
    }
    if (a->verbose && num(r, "width") > 0)
        fprintf(stderr, "job %ld: %gx%g%s\n", job, num(r, "width"), num(r, "height"),
                (a->ov.width > 0) != (a->ov.height > 0) ? " (one side given: the other keeps the scene's aspect ratio)"
                                                        : "");
    cJSON_Delete(r);
    if (!a->wait) {
        if (a->json) printf("{\"job\": %ld}\n", job);
        else printf("job %ld\n", job);
        cli_close(&c);
        return 0;
    }
    if (!a->json && !a->quiet) fprintf(stderr, "job %ld submitted\n", job);
    catch_interrupts(1);
    cJSON *fin = wait_job(&c, job, a->quiet);
    catch_interrupts(0);
    if (!fin && interrupted) {
        rc = cancel_interrupted(&c, job);
        cli_close(&c);
        return rc;
    }
    rc = fin ? 0 : 1;
    if (fin && strcmp(str(fin, "state"), "done") != 0)
        rc = cli_fail("job %ld %s%s%s", job, str(fin, "state"), str(fin, "error")[0] ? ": " : "", str(fin, "error"));
    image_write_options wo = a->wo;
    if (rc == 0 && (rc = fetch_to(&c, job, out, &wo, 0)) != 0 && !a->quiet)
        fprintf(stderr, "job %ld: the image stays on the coordinator: tessera fetch %ld -o OUT\n", job, job);
    if (rc == 0) {
        if (a->json) printf("{\"job\": %ld, \"image\": \"%s\"}\n", job, out);
        else printf("job %ld done, image: %s\n", job, out);
    }
    cJSON_Delete(fin);
    cli_close(&c);
    return rc;
}

/* One request on a connection of its own: the answer of type want, or
 * NULL (printed). */
/* Connect, send m (taken), read the answer want, close. */
static cJSON *ask_msg(const cli_args *a, cJSON *m, const char *want) {
    cli c;
    if (cli_open(&c, a)) {
        cJSON_Delete(m);
        return NULL;
    }
    cJSON *r = request_send(&c, m, want);
    cli_close(&c);
    return r;
}

static cJSON *ask(const cli_args *a, const char *type, long job, const char *want) {
    return ask_msg(a, request_new(type, job), want);
}

static int do_status(const cli_args *a, long job) {
    cJSON *st = ask(a, "status", job, "status");
    if (!st) return 1;
    if (a->json) {
        print_json(st);
    } else {
        printf("%-5s %-9s %8s %13s %10s %7s  %s\n", "JOB", "STATE", "PRIORITY", "TILES", "MSAMPLES/S", "ETA", "SCENE");
        const cJSON *j;
        cJSON_ArrayForEach(j, cJSON_GetObjectItemCaseSensitive(st, "jobs")) {
            char tiles[32], eta[32], state[40], name[1100], error[2100]; /* peers' text, escaped (log.h) */
            snprintf(tiles, sizeof tiles, "%d/%d", (int)num(j, "tiles_done"), (int)num(j, "tiles_total"));
            snprintf(eta, sizeof eta, "%.0fs", num(j, "eta_s"));
            log_escape(str(j, "state"), state, sizeof state);
            log_escape(str(j, "name"), name, sizeof name);
            log_escape(str(j, "error"), error, sizeof error);
            printf("%-5d %-9s %8d %13s %10.3f %7s  %s%s%s\n", (int)num(j, "job"), state, (int)num(j, "priority"),
                   tiles, num(j, "samples_per_s") / 1e6, strcmp(state, "running") ? "-" : eta,
                   name, error[0] ? "  error: " : "", error);
        }
        printf("%d worker%s connected\n", (int)num(st, "workers"), (int)num(st, "workers") == 1 ? "" : "s");
    }
    cJSON_Delete(st);
    return 0;
}

static int do_workers(const cli_args *a) {
    cJSON *ws = ask(a, "workers", -1, "workers");
    if (!ws) return 1;
    if (a->json) {
        print_json(ws);
    } else {
        printf("%-20s %-22s %7s %7s %10s %10s\n", "NAME", "ADDRESS", "THREADS", "TILES", "MSAMPLES/S", "LAST SEEN");
        const cJSON *w;
        cJSON_ArrayForEach(w, cJSON_GetObjectItemCaseSensitive(ws, "workers")) {
            char seen[160], name[300], address[300]; /* peers' text, escaped (log.h) */
            snprintf(seen, sizeof seen, "%.1fs ago%s", num(w, "last_seen_s"),
                     cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(w, "stalled")) ? " (stalled)" : "");
            if (num(w, "quarantined") > 0) /* its tiles failed an audit (--audit) */
                snprintf(seen + strlen(seen), sizeof seen - strlen(seen), " QUARANTINED in %d jobs",
                         (int)num(w, "quarantined"));
            if (num(w, "blocklisted") > 0) /* it failed too often on a running job (farm_block.c) */
                snprintf(seen + strlen(seen), sizeof seen - strlen(seen), " BLOCKLISTED in %d jobs (retry in %.0fs)",
                         (int)num(w, "blocklisted"), num(w, "retry_s"));
            log_escape(str(w, "name"), name, sizeof name);
            log_escape(str(w, "address"), address, sizeof address);
            printf("%-20s %-22s %7d %7d %10.3f %10s\n", name, address, (int)num(w, "threads"),
                   (int)num(w, "tiles"), num(w, "samples_per_s") / 1e6, seen);
        }
    }
    cJSON_Delete(ws);
    return 0;
}

static int do_cancel(const cli_args *a, long job) {
    cJSON *r = ask(a, "cancel", job, "cancelled");
    if (!r) return 1;
    if (a->json) printf("{\"job\": %ld, \"state\": \"cancelled\"}\n", job);
    else printf("job %ld cancelled\n", job);
    cJSON_Delete(r);
    return 0;
}

static int do_priority(const cli_args *a, long job, long priority) {
    cJSON *m = request_new("priority", job);
    cJSON_AddNumberToObject(m, "priority", (double)priority);
    cJSON *r = ask_msg(a, m, "priority");
    if (!r) return 1;
    if (a->json) printf("{\"job\": %ld, \"priority\": %d}\n", job, (int)num(r, "priority"));
    else printf("job %ld: priority %d\n", job, (int)num(r, "priority"));
    cJSON_Delete(r);
    return 0;
}

/* tessera logs JOB: one line per event, "HH:MM:SS.mmm text", local time. */
static int do_logs(const cli_args *a, long job) {
    cJSON *m = request_new("logs", job);
    if (a->last > 0) cJSON_AddNumberToObject(m, "last", a->last);
    cJSON *r = ask_msg(a, m, "logs");
    if (!r) return 1;
    if (a->json) {
        print_json(r);
        cJSON_Delete(r);
        return 0;
    }
    if (num(r, "dropped") > 0) printf("(%.0f earlier lines not shown)\n", num(r, "dropped"));
    const cJSON *l;
    cJSON_ArrayForEach(l, cJSON_GetObjectItemCaseSensitive(r, "lines")) {
        double t = num(l, "t");
        time_t secs = (time_t)t;
        struct tm tm;
        char when[32], text[600]; /* the coordinator's text (worker names): escaped (log.h) */
        strftime(when, sizeof when, "%H:%M:%S", localtime_r(&secs, &tm));
        log_escape(str(l, "text"), text, sizeof text);
        printf("%s.%03d %s\n", when, (int)((t - (double)secs) * 1000), text);
    }
    printf("job %ld is %s\n", job, str(r, "state"));
    cJSON_Delete(r);
    return 0;
}

static int do_fetch(const cli_args *a, long job) {
    if (!a->out) return cli_fail("fetch: -o OUT is required"), 2;
    cli c;
    if (cli_open(&c, a)) return 1;
    image_write_options wo = a->wo;
    int rc = fetch_to(&c, job, a->out, &wo, a->partial);
    cli_close(&c);
    if (rc == 0) printf(a->json ? "{\"job\": %ld, \"image\": \"%s\"}\n" : "job %ld, image: %s\n", job, a->out);
    return rc;
}

/* ---- command line ------------------------------------------------------------------ */

#define COMMON_OPTIONS_HELP                                                                              \
    "      --coordinator HOST:PORT  the coordinator (default: $TESSERA_COORDINATOR, else " DEFAULT_COORDINATOR ")\n" \
    "      --token-file F       the client (or admin) token (default: $TESSERA_CLIENT_TOKEN_FILE,\n"     \
    "                           else $TESSERA_TOKEN_FILE); with one, every frame is encrypted\n"        \
    "      --client-name NAME   who this client is: jobs belong to the name that submitted them\n"       \
    "                           (default: $TESSERA_CLIENT_NAME, else tessera-cli)\n"                   \
    "      --insecure           allow a coordinator beyond loopback without a token (in clear)\n"     \
    "      --json               machine-readable output\n"                                             \
    "  -h, --help               this text\n"

#define IMAGE_OPTIONS_HELP                                                                               \
    "  -o, --output OUT         the image to write; its extension names the format\n"                   \
    "      --tonemap NAME       8-bit outputs: " TONEMAP_NAMES "\n"                                      \
    "      --exposure STOPS     scale radiance by 2^STOPS before tone mapping\n"                         \
    "      --quality Q          JPEG quality, 1 to 100\n"                                                \
    "      --png16              16-bit PNG instead of 8-bit\n"

static void usage_submit(FILE *f) {
    fprintf(f, "usage: tessera submit SCENE.json|MODEL.glb|MODEL.gltf|MODEL.obj [--wait [-o OUT]] [options]\n"
               "\n"
               "Upload a scene and its meshes to a running tessera-coordinator and print the job id\n"
               "(SCENE.json \"-\": from stdin, meshes relative to the current folder). With --wait,\n"
               "show progress (a bar on a terminal, else a plain line every 5 s), then fetch the\n"
               "image to OUT (default: SCENE's name with .png). SIGINT while waiting cancels the\n"
               "job on the coordinator and exits with status 130.\n"
               "\n"
               "options:\n"
               "      --spp N, --max-depth N, --roulette-depth N, --seed N   override the scene's render settings\n"
               "      --width W, --height H  image size; given one, the other keeps the aspect ratio\n"
               "      --tile-size N        tile side in pixels (default: the coordinator's)\n"
               "      --priority P         higher runs first (default 0)\n"
               "      --noise-threshold E  adaptive sampling, as tessera render's (the same image)\n"
               "      --min-spp N          adaptive: samples every pixel takes first (default 16)\n"
               "      --camera NAME        glTF: render from this camera (default: the first)\n"
               "      --wait               wait for the job and write its image\n"
               "  -q, --quiet              errors and the final line only (no progress, no notes)\n"
               "  -v, --verbose            name each file sent (path and bytes) and the job's size\n"
               IMAGE_OPTIONS_HELP COMMON_OPTIONS_HELP);
}

static void usage_status(FILE *f) {
    fprintf(f, "usage: tessera status [JOB] [options]\n"
               "\n"
               "The coordinator's jobs (or one): state (queued, running, done, failed, cancelled),\n"
               "tiles, speed over the time the job rendered, and the time left.\n"
               "\n"
               "options:\n" COMMON_OPTIONS_HELP);
}

static void usage_workers(FILE *f) {
    fprintf(f, "usage: tessera workers [options]\n"
               "\n"
               "The workers connected to the coordinator: threads, tiles, speed, last heard from.\n"
               "\n"
               "options:\n" COMMON_OPTIONS_HELP);
}

static void usage_cancel(FILE *f) {
    fprintf(f, "usage: tessera cancel JOB [options]\n"
               "\n"
               "Stop a queued or running job; its finished tiles stay (fetch --partial).\n"
               "\n"
               "options:\n" COMMON_OPTIONS_HELP);
}

static void usage_priority(FILE *f) {
    fprintf(f, "usage: tessera priority JOB P [options]\n"
               "\n"
               "Change a queued or running job's priority (an integer from -1000000 to 1000000;\n"
               "higher runs first). Its tiles not yet handed out go before those of lower\n"
               "priorities from now on; the change is saved with the job. A negative P\n"
               "follows \"--\": tessera priority 7 -- -5\n"
               "\n"
               "options:\n" COMMON_OPTIONS_HELP);
}

static void usage_logs(FILE *f) {
    fprintf(f, "usage: tessera logs JOB [options]\n"
               "\n"
               "The job's event log: submitted, tiles handed out (and backup copies), done,\n"
               "requeued after a failure, workers joining and leaving, priority changes, the\n"
               "end. The coordinator keeps the last %d lines of each job while it runs;\n"
               "the dashboard's job page shows the same lines.\n"
               "\n"
               "options:\n"
               "      --last N             only the newest N lines\n"
               COMMON_OPTIONS_HELP,
            PROTOCOL_LOG_LINES_MAX);
}

static void usage_fetch(FILE *f) {
    fprintf(f, "usage: tessera fetch JOB -o OUT [options]\n"
               "\n"
               "Write a finished job's image to OUT on this machine. --partial writes what a\n"
               "running or cancelled job has done so far; the tiles not yet rendered are black\n"
               "and named in a warning.\n"
               "\n"
               "options:\n"
               "      --partial            what is done so far\n"
               IMAGE_OPTIONS_HELP COMMON_OPTIONS_HELP);
}

static int parse_tonemap_opt(const char *v, void *dest, char *err, size_t n) {
    if (tonemap_parse(v, dest) == 0) return 0;
    snprintf(err, n, "unknown operator \"%s\" (known: %s)", v, TONEMAP_NAMES);
    return -1;
}

/* One subcommand: its name, help, the options it takes (names in the table
 * of all options) and how many positional arguments. */
typedef struct {
    const char *name;
    void (*help)(FILE *out);
    const char *const *options;
    int min_args, max_args;
    const char *args_error;
} client_command;

static const char *const common_opts[] = {"coordinator", "token-file", "client-name", "insecure", "json", NULL};
static const char *const submit_opts[] = {"spp", "width", "height", "max-depth", "roulette-depth", "seed", "priority", "tile-size",
                                          "noise-threshold", "min-spp", "wait", "quiet", "verbose", "output", "tonemap", "exposure", "quality",
                                          "png16", "camera", NULL};
static const char *const fetch_opts[] = {"partial", "output", "tonemap", "exposure", "quality", "png16", NULL};
static const char *const no_opts[] = {NULL};
static const char *const logs_opts[] = {"last", NULL};

static const client_command commands[] = {
    {"submit", usage_submit, submit_opts, 1, 1, "expected exactly one scene file"},
    {"status", usage_status, no_opts, 0, 1, "expected at most one job number"},
    {"workers", usage_workers, no_opts, 0, 0, "takes no arguments"},
    {"cancel", usage_cancel, no_opts, 1, 1, "expected one job number"},
    {"fetch", usage_fetch, fetch_opts, 1, 1, "expected one job number"},
    {"priority", usage_priority, no_opts, 2, 2, "expected a job number and a priority"},
    {"logs", usage_logs, logs_opts, 1, 1, "expected one job number"},
};

static int listed(const char *name, const char *const *names) {
    for (; *names; names++)
        if (strcmp(*names, name) == 0) return 1;
    return 0;
}

/* Refuse image options that do not apply to out's format (exit 2). */
static void check_image_options(const char *prog, const cli_args *a) {
    const char *out = a->out ? a->out : "x.png", *dot = strrchr(out, '.');
    const char *ext = dot ? dot + 1 : "";
    if (a->wo.png16 && strcasecmp(ext, "png") != 0)
        args_usage_error(prog, "--png16 applies to .png output, not \"%s\"", out);
    if (a->wo.jpeg_quality && strcasecmp(ext, "jpg") != 0 && strcasecmp(ext, "jpeg") != 0)
        args_usage_error(prog, "--quality applies to .jpg output, not \"%s\"", out);
}

int client_main(int argc, char **argv) {
    cli_args a = {.ov = {-1, -1, -1, -1, 0, 0}, .wo = {.tonemap = {.kind = TONEMAP_REINHARD}}};
    const arg_spec all[] = {
        {.name = "coordinator", .kind = ARG_STRING, .dest = &a.coordinator},
        {.name = "token-file", .kind = ARG_STRING, .dest = &a.token_file},
        {.name = "client-name", .kind = ARG_STRING, .dest = &a.client_name},
        {.name = "insecure", .kind = ARG_FLAG, .dest = &a.insecure},
        {.name = "json", .kind = ARG_FLAG, .dest = &a.json},
        {.name = "wait", .kind = ARG_FLAG, .dest = &a.wait},
        {.name = "quiet", .short_name = 'q', .kind = ARG_FLAG, .dest = &a.quiet},
        {.name = "verbose", .short_name = 'v', .kind = ARG_FLAG, .dest = &a.verbose},
        {.name = "spp", .kind = ARG_INT, .dest = &a.ov.spp, .lo = 1, .hi = LIMIT_SPP},
        {.name = "width", .kind = ARG_INT, .dest = &a.ov.width, .lo = 1, .hi = LIMIT_SIDE},
        {.name = "height", .kind = ARG_INT, .dest = &a.ov.height, .lo = 1, .hi = LIMIT_SIDE},
        {.name = "max-depth", .kind = ARG_INT, .dest = &a.ov.max_depth, .lo = 1, .hi = LIMIT_DEPTH},
        {.name = "roulette-depth", .kind = ARG_INT, .dest = &a.ov.roulette_depth, .lo = 0, .hi = LIMIT_DEPTH,
         .given = &a.ov.has_roulette_depth},
        {.name = "seed", .kind = ARG_U64, .dest = &a.ov.seed, .given = &a.ov.has_seed},
        {.name = "priority", .kind = ARG_INT, .dest = &a.priority, .lo = -LIMIT_PRIORITY, .hi = LIMIT_PRIORITY},
        {.name = "tile-size", .kind = ARG_INT, .dest = &a.tile_size, .lo = 1, .hi = 4096},
        {.name = "noise-threshold", .kind = ARG_DOUBLE, .dest = &a.noise_threshold, .lo = 1e-6, .hi = 1e6},
        {.name = "min-spp", .kind = ARG_INT, .dest = &a.min_spp, .lo = 2, .hi = LIMIT_SPP},
        {.name = "output", .short_name = 'o', .kind = ARG_STRING, .dest = &a.out},
        {.name = "tonemap", .kind = ARG_CUSTOM, .dest = &a.wo.tonemap.kind, .parse = parse_tonemap_opt},
        {.name = "exposure", .kind = ARG_FLOAT, .dest = &a.wo.tonemap.exposure_stops, .lo = -64, .hi = 64},
        {.name = "quality", .kind = ARG_INT, .dest = &a.wo.jpeg_quality, .lo = 1, .hi = 100},
        {.name = "png16", .kind = ARG_FLAG, .dest = &a.wo.png16},
        {.name = "partial", .kind = ARG_FLAG, .dest = &a.partial},
        {.name = "camera", .kind = ARG_STRING, .dest = &a.camera},
        {.name = "last", .kind = ARG_INT, .dest = &a.last, .lo = 1, .hi = PROTOCOL_LOG_LINES_MAX},
        {NULL}};
    const client_command *cmd = NULL;
    for (size_t i = 0; i < sizeof commands / sizeof commands[0]; i++)
        if (strcmp(argv[0], commands[i].name) == 0) cmd = &commands[i];
    if (!cmd) return 2; /* tessera.c only calls with the names above */
    arg_spec specs[sizeof all / sizeof all[0]];
    int n = 0;
    for (const arg_spec *s = all; s->name; s++)
        if (listed(s->name, common_opts) || listed(s->name, cmd->options)) specs[n++] = *s;
    specs[n] = (arg_spec){NULL};
    char prog[32];
    snprintf(prog, sizeof prog, "tessera %s", cmd->name);
    const char *pos[2];
    int nargs = args_parse(prog, argc, argv, specs, cmd->help, pos, 2);
    if (nargs < cmd->min_args || nargs > cmd->max_args) args_usage_error(prog, "%s", cmd->args_error);
    check_image_options(prog, &a);
    const char *arg = nargs > 0 ? pos[0] : NULL;
    long job = arg && strcmp(cmd->name, "submit") != 0 ? args_long(prog, "JOB", arg, 1, UINT32_MAX) : -1;
    if (strcmp(cmd->name, "submit") == 0) return do_submit(&a, arg);
    if (strcmp(cmd->name, "status") == 0) return do_status(&a, job);
    if (strcmp(cmd->name, "workers") == 0) return do_workers(&a);
    if (strcmp(cmd->name, "cancel") == 0) return do_cancel(&a, job);
    if (strcmp(cmd->name, "priority") == 0)
        return do_priority(&a, job, args_long(prog, "P", pos[1], -LIMIT_PRIORITY, LIMIT_PRIORITY));
    if (strcmp(cmd->name, "logs") == 0) return do_logs(&a, job);
    if (!a.out) args_usage_error(prog, "-o OUT is required");
    return do_fetch(&a, job);
}
