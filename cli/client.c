/* client.c - `tessera submit | status | workers | cancel | fetch`: the
 * command-line client of a running tessera-coordinator (service.c).
 *
 * Plain blocking sockets: one request, one answer, with timeouts, so that a
 * dead coordinator is an error message, never a hang. The address comes from
 * --coordinator, else $TESSERA_COORDINATOR, else 127.0.0.1:7000. */
#define _GNU_SOURCE
#include "client.h"

#include "cli_util.h"

#include <errno.h>
#include <getopt.h>
#include <netdb.h>
#include <poll.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/socket.h>
#include <time.h>
#include <unistd.h>

#include "net/address.h"
#include "args.h"
#include "net/auth.h"
#include "image/image.h"
#include "net/protocol.h"
#include "render/scene.h"
#include "render/scene_bundle.h"
#include "net/wire.h"
#include "limit.h"
#include "image/image_meta.h"

#define DEFAULT_COORDINATOR "127.0.0.1:7000"
#define IO_TIMEOUT_MS 30000
#define MAX_ANSWER LIMIT_ANSWER_BYTES

typedef struct {
    int fd;
    char where[300];
    double max_upload; /* from welcome: the largest scene bundle accepted */
} cli;

typedef struct {
    const char *coordinator;
    const char *token_file;
    int json;
    int wait;
    int partial; /* fetch: what is done so far of a running or cancelled job */
    const char *out;
    scene_overrides ov;
    int priority, tile_size;
    image_write_options wo;
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

static int send_all(cli *c, const uint8_t *p, size_t len) {
    while (len > 0) {
        ssize_t n = send(c->fd, p, len, MSG_NOSIGNAL);
        if (n <= 0) return cli_fail("lost the coordinator at %s: %s", c->where, strerror(errno));
        p += n;
        len -= (size_t)n;
    }
    return 0;
}

static int read_all(cli *c, uint8_t *p, size_t len) {
    while (len > 0) {
        struct pollfd pf = {c->fd, POLLIN, 0};
        int r = poll(&pf, 1, IO_TIMEOUT_MS);
        if (r == 0) return cli_fail("the coordinator at %s did not answer within %d s", c->where, IO_TIMEOUT_MS / 1000);
        ssize_t n = r > 0 ? recv(c->fd, p, len, 0) : -1;
        if (n <= 0) return cli_fail("lost the coordinator at %s: %s", c->where, n == 0 ? "connection closed" : strerror(errno));
        p += n;
        len -= (size_t)n;
    }
    return 0;
}

/* Read one frame into a malloc'd body (the caller frees). Returns its kind
 * or -1 (printed). */
static int read_frame(cli *c, uint8_t **body, size_t *len) {
    uint8_t hdr[WIRE_HEADER_BYTES];
    if (read_all(c, hdr, sizeof hdr)) return -1;
    size_t l = wire_get_u32(hdr);
    if (l < 1 || l > MAX_ANSWER) return cli_fail("the coordinator at %s sent a malformed frame", c->where), -1;
    *body = malloc(l);
    if (!*body) return cli_fail("out of memory for a %zu-byte answer", l), -1;
    if (read_all(c, *body, l - 1)) {
        free(*body);
        return -1;
    }
    *len = l - 1;
    return hdr[4];
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
    cli_fail("%s", cJSON_IsString(r) ? r->valuestring : "the coordinator refused the request");
    cJSON_Delete(m);
    return NULL;
}

/* Connect, answer the challenge and say hello as a client. Returns 0 or 1
 * (printed). */
static int cli_open(cli *c, const cli_args *args) {
    auth_key key = {0};
    char err[256];
    const char *token = args->token_file ? args->token_file : getenv("TESSERA_TOKEN_FILE");
    if (token && *token && auth_key_load(token, &key, err, sizeof err)) return cli_fail("%s", err);
    const char *addr = args->coordinator ? args->coordinator : getenv("TESSERA_COORDINATOR");
    if (!addr || !*addr) addr = DEFAULT_COORDINATOR;
    char host[256], port_s[16];
    int port;
    if (address_parse(addr, host, sizeof host, &port, err, sizeof err)) return cli_fail("--coordinator %s", err);
    snprintf(c->where, sizeof c->where, "%s", addr);
    snprintf(port_s, sizeof port_s, "%d", port);
    struct addrinfo hints = {.ai_family = AF_UNSPEC, .ai_socktype = SOCK_STREAM}, *res;
    int rc = getaddrinfo(host, port_s, &hints, &res);
    if (rc) return cli_fail("cannot reach the coordinator at %s: %s", addr, gai_strerror(rc));
    c->fd = -1;
    int saved = 0;
    for (struct addrinfo *a = res; a && c->fd < 0; a = a->ai_next) {
        c->fd = socket(a->ai_family, a->ai_socktype, 0);
        if (c->fd >= 0 && connect(c->fd, a->ai_addr, a->ai_addrlen) != 0) {
            saved = errno;
            close(c->fd);
            c->fd = -1;
        }
    }
    freeaddrinfo(res);
    if (c->fd < 0) return cli_fail("cannot reach the coordinator at %s: %s", addr, strerror(saved));
    cJSON *ch = read_answer(c, "challenge");
    if (!ch) return 1;
    char nonce[AUTH_HEX], proof[AUTH_HEX], theirs[200];
    snprintf(theirs, sizeof theirs, "%s", str(ch, "nonce"));
    cJSON_Delete(ch);
    cJSON *h = cJSON_CreateObject();
    cJSON_AddStringToObject(h, "type", "hello");
    cJSON_AddStringToObject(h, "role", "client");
    cJSON_AddNumberToObject(h, "protocol", PROTOCOL_VERSION);
    cJSON_AddStringToObject(h, "build", protocol_build_id());
    cJSON_AddStringToObject(h, "name", "tessera-cli");
    cJSON_AddNumberToObject(h, "threads", 1);
    if (key.enabled) {
        auth_proof(&key, theirs, "client:tessera-cli", proof);
        auth_nonce(nonce);
        cJSON_AddStringToObject(h, "proof", proof);
        cJSON_AddStringToObject(h, "nonce", nonce);
    }
    if (send_json(c, h)) return 1;
    cJSON *w = read_answer(c, "welcome");
    int ok = w && (!key.enabled || auth_check(&key, nonce, "coordinator", str(w, "proof")));
    c->max_upload = num(w, "max_upload");
    if (w && !ok) cli_fail("the coordinator at %s could not prove it knows the token", c->where);
    cJSON_Delete(w);
    return ok ? 0 : 1;
}

static void cli_close(cli *c) {
    if (c->fd >= 0) close(c->fd);
}

/* ---- requests ------------------------------------------------------------------ */

static cJSON *request(cli *c, const char *type, long job, const char *want) {
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", type);
    if (job >= 0) cJSON_AddNumberToObject(m, "job", (double)job);
    return send_json(c, m) ? NULL : read_answer(c, want);
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
        if (e && partial && strcmp(type, "partial") == 0) { /* the image follows */
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
    uint32_t w = len >= 8 ? wire_get_u32(body) : 0, h = len >= 8 ? wire_get_u32(body + 4) : 0;
    image img;
    if (kind != 'I' || w == 0 || h == 0 || len != 8 + (size_t)w * h * 12 || image_alloc(&img, (int)w, (int)h)) {
        free(body);
        return cli_fail("job %ld: the coordinator sent a malformed image", job);
    }
    for (size_t i = 0; i < (size_t)w * h * 3; i++) img.rgb[i] = wire_get_f32(body + 8 + 4 * i);
    free(body);
    char err[1024];
    int rc = image_write(out, &img, wo, err, sizeof err);
    image_free(&img);
    if (rc) return cli_fail("%s", err);
    return 0;
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

/* Poll until the job ends; returns its final status object (caller frees)
 * or NULL (printed). */
static cJSON *wait_job(cli *c, long job) {
    int tty = isatty(STDERR_FILENO);
    for (;;) {
        cJSON *st = request(c, "status", job, "status");
        if (!st) return NULL;
        cJSON *j = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(st, "jobs"), 0);
        if (!j) {
            cJSON_Delete(st);
            return cli_fail("job %ld vanished from the coordinator", job), NULL;
        }
        if (tty)
            cli_progress((int)num(j, "tiles_done"), (int)num(j, "tiles_total"), num(j, "samples_per_s"),
                         (int)num(st, "workers"), num(j, "eta_s"), 0);
        if (strcmp(str(j, "state"), "running") != 0) {
            if (tty) fputc('\n', stderr);
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
    scene_bundle b;
    if (scene_bundle_read(scene_path, &b, err, sizeof err)) return cli_fail("%s", err);
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
    cJSON_AddStringToObject(m, "name", scene_path);
    if (a->ov.width > 0) cJSON_AddNumberToObject(m, "width", a->ov.width);
    if (a->ov.height > 0) cJSON_AddNumberToObject(m, "height", a->ov.height);
    if (a->ov.spp > 0) cJSON_AddNumberToObject(m, "spp", a->ov.spp);
    if (a->ov.max_depth > 0) cJSON_AddNumberToObject(m, "max_depth", a->ov.max_depth);
    if (a->ov.has_seed) {
        char seed[32];
        snprintf(seed, sizeof seed, "%llu", (unsigned long long)a->ov.seed);
        cJSON_AddStringToObject(m, "seed", seed);
    }
    cJSON_AddNumberToObject(m, "priority", a->priority);
    if (a->tile_size > 0) cJSON_AddNumberToObject(m, "tile_size", a->tile_size);
    cJSON *r = rc == 0 && send_json(&c, m) == 0 ? read_answer(&c, "submitted") : NULL;
    if (rc) cJSON_Delete(m);
    if (!r) {
        cli_close(&c);
        return 1;
    }
    long job = (long)num(r, "job");
    cJSON_Delete(r);
    if (!a->wait) {
        if (a->json) printf("{\"job\": %ld}\n", job);
        else printf("job %ld\n", job);
        cli_close(&c);
        return 0;
    }
    if (!a->json) fprintf(stderr, "job %ld submitted\n", job);
    cJSON *fin = wait_job(&c, job);
    rc = fin ? 0 : 1;
    if (fin && strcmp(str(fin, "state"), "done") != 0)
        rc = cli_fail("job %ld %s%s%s", job, str(fin, "state"), str(fin, "error")[0] ? ": " : "", str(fin, "error"));
    const char *out = a->out;
    if (!out) {
        cli_default_output(scene_path, out_default, sizeof out_default);
        out = out_default;
    }
    image_write_options wo = a->wo;
    if (rc == 0) rc = fetch_to(&c, job, out, &wo, 0);
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
static cJSON *ask(const cli_args *a, const char *type, long job, const char *want) {
    cli c;
    if (cli_open(&c, a)) return NULL;
    cJSON *r = request(&c, type, job, want);
    cli_close(&c);
    return r;
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
            char tiles[32], eta[32];
            snprintf(tiles, sizeof tiles, "%d/%d", (int)num(j, "tiles_done"), (int)num(j, "tiles_total"));
            snprintf(eta, sizeof eta, "%.0fs", num(j, "eta_s"));
            printf("%-5d %-9s %8d %13s %10.3f %7s  %s%s%s\n", (int)num(j, "job"), str(j, "state"), (int)num(j, "priority"),
                   tiles, num(j, "samples_per_s") / 1e6, strcmp(str(j, "state"), "running") ? "-" : eta,
                   str(j, "name"), str(j, "error")[0] ? "  error: " : "", str(j, "error"));
        }
        printf("%d workers connected\n", (int)num(st, "workers"));
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
            char seen[80];
            snprintf(seen, sizeof seen, "%.1fs ago%s", num(w, "last_seen_s"),
                     cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(w, "stalled")) ? " (stalled)" : "");
            if (num(w, "quarantined") > 0) /* its tiles failed an audit (--audit) */
                snprintf(seen + strlen(seen), sizeof seen - strlen(seen), " QUARANTINED in %d jobs",
                         (int)num(w, "quarantined"));
            printf("%-20s %-22s %7d %7d %10.3f %10s\n", str(w, "name"), str(w, "address"), (int)num(w, "threads"),
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

static void usage(FILE *f) {
    fprintf(f,
            "usage: tessera submit SCENE.json [--spp N] [--width W --height H] [--max-depth N] [--seed N]\n"
            "                      [--tile-size N] [--priority P] [--wait] [-o OUT] [--tonemap NAME]\n"
            "                      [--exposure S] [--quality Q] [--png16]\n"
            "       tessera status [JOB]\n"
            "       tessera workers\n"
            "       tessera cancel JOB\n"
            "       tessera fetch JOB -o OUT [--partial] [--tonemap NAME] [--exposure S] [--quality Q] [--png16]\n"
            "\n"
            "Talk to a running tessera-coordinator. Every command takes --coordinator HOST:PORT\n"
            "(default: $TESSERA_COORDINATOR, else " DEFAULT_COORDINATOR "), --token-file F (default:\n"
            "$TESSERA_TOKEN_FILE) and --json for scripts.\n"
            "submit uploads the scene and its meshes and prints the job id; with --wait it shows\n"
            "progress and writes the image to OUT on this machine (format from the extension).\n"
            "fetch --partial writes what a running or cancelled job has done so far; the tiles\n"
            "not yet rendered are black and named in a warning.\n");
}

static long parse_num(const char *what, const char *s, long lo, long hi) { return args_long("tessera", what, s, lo, hi); }

enum { C_COORD = 300, C_JSON, C_WAIT, C_SPP, C_WIDTH, C_HEIGHT, C_DEPTH, C_SEED, C_PRIORITY, C_TONEMAP, C_EXPOSURE,
       C_TILE, C_TOKEN, C_QUALITY, C_PNG16, C_PARTIAL };

int client_main(int argc, char **argv) {
    static const struct option opts[] = {
        {"coordinator", required_argument, 0, C_COORD}, {"json", no_argument, 0, C_JSON},
        {"wait", no_argument, 0, C_WAIT}, {"spp", required_argument, 0, C_SPP},
        {"width", required_argument, 0, C_WIDTH}, {"height", required_argument, 0, C_HEIGHT},
        {"max-depth", required_argument, 0, C_DEPTH}, {"seed", required_argument, 0, C_SEED},
        {"priority", required_argument, 0, C_PRIORITY}, {"tonemap", required_argument, 0, C_TONEMAP},
        {"exposure", required_argument, 0, C_EXPOSURE}, {"output", required_argument, 0, 'o'},
        {"tile-size", required_argument, 0, C_TILE}, {"token-file", required_argument, 0, C_TOKEN},
        {"quality", required_argument, 0, C_QUALITY}, {"png16", no_argument, 0, C_PNG16}, {"partial", no_argument, 0, C_PARTIAL},
        {"help", no_argument, 0, 'h'}, {0, 0, 0, 0}};
    const char *cmd = argv[0];
    cli_args a = {.ov = {-1, -1, -1, -1, 0, 0}, .wo = {.tonemap = {.kind = TONEMAP_REINHARD}}};
    int c;
    optind = 1;
    while ((c = getopt_long(argc, argv, "o:h", opts, NULL)) != -1) {
        switch (c) {
        case C_COORD: a.coordinator = optarg; break;
        case C_JSON: a.json = 1; break;
        case C_WAIT: a.wait = 1; break;
        case C_SPP: a.ov.spp = (int)parse_num("--spp", optarg, 1, LIMIT_SPP); break;
        case C_WIDTH: a.ov.width = (int)parse_num("--width", optarg, 1, LIMIT_SIDE); break;
        case C_HEIGHT: a.ov.height = (int)parse_num("--height", optarg, 1, LIMIT_SIDE); break;
        case C_DEPTH: a.ov.max_depth = (int)parse_num("--max-depth", optarg, 1, LIMIT_DEPTH); break;
        case C_SEED:
            a.ov.seed = (uint64_t)parse_num("--seed", optarg, 0, 0x7fffffffffffffffL);
            a.ov.has_seed = 1;
            break;
        case C_PRIORITY: a.priority = (int)parse_num("--priority", optarg, -1000000, 1000000); break;
        case C_TONEMAP:
            if (tonemap_parse(optarg, &a.wo.tonemap.kind)) {
                fprintf(stderr, "tessera: --tonemap: unknown operator \"%s\" (known: %s)\n", optarg, TONEMAP_NAMES);
                return 2;
            }
            break;
        case C_EXPOSURE: a.wo.tonemap.exposure_stops = (float)parse_num("--exposure", optarg, -64, 64); break;
        case C_TOKEN: a.token_file = optarg; break;
        case C_QUALITY: a.wo.jpeg_quality = (int)parse_num("--quality", optarg, 1, 100); break;
        case C_PNG16: a.wo.png16 = 1; break;
        case C_PARTIAL: a.partial = 1; break;
        case C_TILE: a.tile_size = (int)parse_num("--tile-size", optarg, 1, 4096); break;
        case 'o': a.out = optarg; break;
        case 'h': usage(stdout); return 0;
        default: usage(stderr); return 2;
        }
    }
    int nargs = argc - optind;
    const char *arg = nargs > 0 ? argv[optind] : NULL;
    if (strcmp(cmd, "submit") == 0 && nargs == 1) return do_submit(&a, arg);
    if (strcmp(cmd, "status") == 0 && nargs <= 1) return do_status(&a, arg ? parse_num("JOB", arg, 1, UINT32_MAX) : -1);
    if (strcmp(cmd, "workers") == 0 && nargs == 0) return do_workers(&a);
    if (strcmp(cmd, "cancel") == 0 && nargs == 1) return do_cancel(&a, parse_num("JOB", arg, 1, UINT32_MAX));
    if (strcmp(cmd, "fetch") == 0 && nargs == 1) return do_fetch(&a, parse_num("JOB", arg, 1, UINT32_MAX));
    fprintf(stderr, "tessera %s: wrong number of arguments\n", cmd);
    usage(stderr);
    return 2;
}
