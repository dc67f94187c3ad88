/* loadgen.c - a load generator for the coordinator: N simulated workers on
 * one libuv loop that answer every tile instantly (with black pixels).
 *
 *   loadgen --connect HOST:PORT [--connections N] [--token-file F]
 *
 * With --token-file each simulated worker answers the challenge with the
 * token and seals its link as a real worker does (conn_seal), so the cost
 * of encryption shows in the figures.
 *
 * Prints how many tiles the coordinator scheduled and stitched per second
 * and the time from a worker's "ready" to the "assign" it gets back (p50,
 * p99, max): the coordinator's own cost per tile, with rendering taken out. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <uv.h>

#include "net/address.h"
#include "net/auth.h"
#include "net/conn.h"
#include "job/job.h"
#include "net/protocol.h"
#include "net/wire.h"

typedef struct {
    conn *c;
    uv_connect_t req;
    int index;
    double ready_at; /* when our last "ready" went out */
    char challenge[200], nonce[AUTH_HEX]; /* with a token: the handshake's nonces */
} sim;

static auth_key key; /* --token-file: prove it and seal every link */

static uv_loop_t *loop;
static int open_conns, connections = 500;
static unsigned long tiles;
static double *lat;
static size_t lat_n, lat_cap;
static double first_assign = -1, last_tile;
static struct sockaddr_storage target;

static double now(void) { return (double)uv_hrtime() / 1e9; }

static void send_json_text(sim *s, const char *text) {
    size_t len, n = strlen(text);
    uint8_t *f = wire_frame_new(WIRE_KIND_JSON, n, &len);
    if (!f) return;
    memcpy(f + WIRE_HEADER_BYTES, text, n);
    conn_send(s->c, f, len);
}

static void send_ready(sim *s) {
    s->ready_at = now();
    send_json_text(s, "{\"type\":\"ready\",\"slots\":1}");
}

static void on_assign(sim *s, const cJSON *m) {
    char err[256];
    proto_assign a;
    if (proto_assign_parse(m, "coordinator", &a, err, sizeof err)) {
        fprintf(stderr, "loadgen: %s\n", err);
        return;
    }
    double t = now();
    if (first_assign < 0) first_assign = t;
    if (lat_n == lat_cap) {
        lat_cap = lat_cap ? 2 * lat_cap : 65536;
        lat = realloc(lat, lat_cap * sizeof *lat);
    }
    lat[lat_n++] = t - s->ready_at;
    int w = tile_width(&a.rect), h = tile_height(&a.rect);
    float *rgb = calloc((size_t)w * (size_t)h * 3, sizeof(float));
    proto_tile pt = {a.job, a.tile, (uint32_t)w, (uint32_t)h, {(uint64_t)w * (uint64_t)h * a.count, 0, 0, 0}, 3};
    size_t len;
    uint8_t *f = proto_tile_frame(&pt, rgb, &len);
    free(rgb);
    if (f) conn_send(s->c, f, len);
    tiles++;
    last_tile = now();
    send_ready(s);
}

/* hello as worker load-INDEX, with a proof and a nonce when there is a token. */
static void send_hello(sim *s) {
    char hello[600], name[32], who[48], proof[AUTH_HEX], extra[200] = "";
    snprintf(name, sizeof name, "load-%d", s->index);
    if (key.enabled) {
        snprintf(who, sizeof who, "worker:%s", name);
        auth_proof(&key, s->challenge, who, proof);
        auth_nonce(s->nonce);
        snprintf(extra, sizeof extra, ",\"proof\":\"%s\",\"nonce\":\"%s\"", proof, s->nonce);
    }
    snprintf(hello, sizeof hello, "{\"type\":\"hello\",\"protocol\":%d,\"build\":\"%s\",\"name\":\"%s\",\"threads\":1%s}",
             PROTOCOL_VERSION, protocol_build_id(), name, extra);
    send_json_text(s, hello);
}

static int on_frame(conn *c, int kind, const uint8_t *body, size_t len) {
    sim *s = conn_data(c);
    if (kind != WIRE_KIND_JSON) return 0; /* the scene */
    const char *type;
    char err[256];
    cJSON *m = proto_parse_json(body, len, &type, err, sizeof err);
    if (!m) return 0;
    if (strcmp(type, "challenge") == 0 && key.enabled) {
        const cJSON *n = cJSON_GetObjectItemCaseSensitive(m, "nonce");
        snprintf(s->challenge, sizeof s->challenge, "%s", cJSON_IsString(n) ? n->valuestring : "");
        send_hello(s);
    } else if (strcmp(type, "welcome") == 0) {
        conn_set_max_frame(c, SCENE_BUNDLE_MAX_BYTES + 1);
        if (key.enabled) {
            unsigned char down[AUTH_KEY_BYTES], up[AUTH_KEY_BYTES];
            auth_link_keys(&key, s->challenge, s->nonce, down, up);
            conn_seal(c, up, down);
        }
        send_ready(s);
    } else if (strcmp(type, "assign") == 0) {
        on_assign(s, m);
    } else if (strcmp(type, "refused") == 0 || strcmp(type, "error") == 0) {
        const cJSON *r = cJSON_GetObjectItemCaseSensitive(m, "reason");
        fprintf(stderr, "loadgen: %s: %s\n", type, cJSON_IsString(r) ? r->valuestring : "?");
    }
    cJSON_Delete(m);
    return 0;
}

static void on_close(conn *c, const char *reason) {
    (void)reason;
    free(conn_data(c));
    open_conns--;
}

static const conn_callbacks cbs = {on_frame, on_close};

static void on_connected(uv_connect_t *req, int status) {
    sim *s = req->data;
    if (status != 0 || conn_start(s->c) != 0) {
        fprintf(stderr, "loadgen: connection %d: %s\n", s->index, uv_strerror(status));
        conn_close(s->c, "connect failed", 0);
        return;
    }
    uv_tcp_nodelay(conn_tcp(s->c), 1);
    if (!key.enabled) send_hello(s); /* else after the challenge */
}

static int cmp_double(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int main(int argc, char **argv) {
    const char *addr = NULL, *token = NULL;
    for (int i = 1; i < argc; i++) {
        if (strcmp(argv[i], "--connect") == 0 && i + 1 < argc) addr = argv[++i];
        else if (strcmp(argv[i], "--token-file") == 0 && i + 1 < argc) token = argv[++i];
        else if (strcmp(argv[i], "--connections") == 0 && i + 1 < argc) connections = atoi(argv[++i]);
        else {
            fprintf(stderr, "usage: loadgen --connect HOST:PORT [--connections N] [--token-file F]\n");
            return 2;
        }
    }
    char host[256], err[256];
    int port;
    if (!addr || connections < 1 || address_parse(addr, host, sizeof host, &port, err, sizeof err) ||
        uv_ip4_addr(host, port, (struct sockaddr_in *)&target)) {
        fprintf(stderr, "loadgen: --connect IPv4:PORT and --connections N >= 1 are required\n");
        return 2;
    }
    if (token && auth_key_load(token, &key, err, sizeof err)) {
        fprintf(stderr, "loadgen: --token-file %s\n", err);
        return 2;
    }
    loop = uv_default_loop();
    for (int i = 0; i < connections; i++) {
        sim *s = calloc(1, sizeof *s);
        s->index = i;
        s->c = conn_new(loop, &cbs, s, WIRE_JSON_MAX + 1);
        s->req.data = s;
        uv_tcp_connect(&s->req, conn_tcp(s->c), (struct sockaddr *)&target, on_connected);
        open_conns++;
    }
    uv_run(loop, UV_RUN_DEFAULT);
    double secs = last_tile - first_assign;
    qsort(lat, lat_n, sizeof *lat, cmp_double);
    double p50 = lat_n ? lat[lat_n / 2] : 0, p99 = lat_n ? lat[(size_t)(0.99 * (double)(lat_n - 1))] : 0;
    printf("loadgen: %d connections, %lu tiles in %.2f s: %.0f tiles/s; ready->assign p50 %.3f ms, p99 %.3f ms, "
           "max %.3f ms\n",
           connections, tiles, secs, secs > 0 ? (double)tiles / secs : 0, p50 * 1e3, p99 * 1e3,
           lat_n ? lat[lat_n - 1] * 1e3 : 0);
    free(lat);
    return tiles > 0 ? 0 : 1;
}
