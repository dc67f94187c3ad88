/* test_protocol.c - the farm's building blocks without sockets: the frame
 * decoder under any split of the byte stream and against lying lengths,
 * scene bundles, tile frames, job and assign messages, HOST:PORT parsing. */
#include <stdlib.h>
#include <string.h>

#include "net/address.h"
#include "job/job.h"
#include "net/protocol.h"
#include "render/scene_bundle.h"
#include "net/wire.h"
#include "harness.h"
#include "util.h"

typedef struct {
    int count;
    int kinds[8];
    size_t lens[8];
    char bodies[8][64];
} frames_seen;

static int collect(void *ctx, int kind, const uint8_t *body, size_t len) {
    frames_seen *f = ctx;
    if (f->count < 8) {
        f->kinds[f->count] = kind;
        f->lens[f->count] = len;
        memcpy(f->bodies[f->count], body, len < 63 ? len : 63);
    }
    f->count++;
    return 0;
}

/* Three frames back to back. */
static size_t three_frames(uint8_t *buf) {
    size_t n = 0, len;
    const char *texts[] = {"{\"type\":\"a\"}", "", "{\"type\":\"ccc\"}"};
    int kinds[] = {WIRE_KIND_JSON, WIRE_KIND_TILE, WIRE_KIND_JSON};
    for (int i = 0; i < 3; i++) {
        uint8_t *f = wire_frame_new(kinds[i], strlen(texts[i]), &len);
        memcpy(f + WIRE_HEADER_BYTES, texts[i], strlen(texts[i]));
        memcpy(buf + n, f, len);
        n += len;
        free(f);
    }
    return n;
}

TEST(wire_decoder_any_split) {
    uint8_t buf[256];
    size_t n = three_frames(buf);
    /* Every way of cutting the stream in two, and one byte at a time. */
    for (size_t cut = 0; cut <= n + 1; cut++) {
        wire_decoder d;
        wire_decoder_init(&d, 1024);
        frames_seen seen = {0};
        char err[128];
        int rc = 0;
        if (cut <= n) {
            rc |= wire_decoder_feed(&d, buf, cut, collect, &seen, err, sizeof err);
            rc |= wire_decoder_feed(&d, buf + cut, n - cut, collect, &seen, err, sizeof err);
        } else {
            for (size_t i = 0; i < n; i++) rc |= wire_decoder_feed(&d, buf + i, 1, collect, &seen, err, sizeof err);
        }
        CHECK(rc == 0 && seen.count == 3, "cut %zu: rc %d, %d frames", cut, rc, seen.count);
        CHECK(seen.kinds[1] == WIRE_KIND_TILE && seen.lens[1] == 0 && seen.lens[2] == 14 &&
                  memcmp(seen.bodies[2], "{\"type\":\"ccc\"}", 14) == 0,
              "cut %zu: frames decoded wrongly", cut);
        CHECK(wire_decoder_pending(&d) == 0, "cut %zu: bytes left over", cut);
        wire_decoder_free(&d);
    }
}

TEST(wire_decoder_refuses_lying_lengths) {
    char err[128];
    wire_decoder d;
    frames_seen seen = {0};
    const uint8_t huge[] = {0xff, 0xff, 0xff, 0xff, 'J'};
    wire_decoder_init(&d, 65537);
    CHECK(wire_decoder_feed(&d, huge, sizeof huge, collect, &seen, err, sizeof err) == -1 &&
              strstr(err, "frame of 4294967295 bytes exceeds the limit of 65537"),
          "4 GiB frame: %s", err);
    CHECK(d.cap <= 4096, "the decoder allocated %zu bytes for a frame it refused", d.cap);
    wire_decoder_free(&d);
    const uint8_t empty[] = {0, 0, 0, 0};
    wire_decoder_init(&d, 65537);
    CHECK(wire_decoder_feed(&d, empty, sizeof empty, collect, &seen, err, sizeof err) == -1 &&
              strstr(err, "is empty"),
          "empty frame: %s", err);
    wire_decoder_free(&d);
    /* A partial frame is visible as pending (a truncated stream). */
    const uint8_t part[] = {10, 0, 0, 0, 'J', '{'};
    wire_decoder_init(&d, 65537);
    CHECK(wire_decoder_feed(&d, part, sizeof part, collect, &seen, err, sizeof err) == 0 &&
              wire_decoder_pending(&d) == sizeof part && seen.count == 0,
          "partial frame not pending");
    wire_decoder_free(&d);
}

TEST(scene_bundle_round_trip_and_hash) {
    util_write_temp("tri.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n");
    const char *path = util_write_temp(
        "bundle.json", "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -3], \"look_at\": [0, 0, 0], \"fov\": 40},"
                       " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
                       " \"shapes\": [{\"type\": \"mesh\", \"file\": \"tri.obj\", \"material\": \"w\"},"
                       "  {\"type\": \"mesh\", \"file\": \"tri.obj\", \"material\": \"w\", \"translate\": [1, 0, 0]},"
                       "  {\"type\": \"sphere\", \"center\": [0, 2, 0], \"radius\": 0.3, \"emission\": [1, 1, 1]}]}");
    scene_bundle b, c;
    char err[512], h1[SCENE_BUNDLE_HASH_HEX], h2[SCENE_BUNDLE_HASH_HEX];
    CHECK(scene_bundle_read(path, &b, err, sizeof err) == 0, "%s", err);
    CHECK(b.count == 2, "the mesh named twice should be read once: %zu entries", b.count);
    size_t len;
    uint8_t *bytes = scene_bundle_serialise(&b, &len);
    CHECK(bytes && scene_bundle_parse(bytes, len, &c, err, sizeof err) == 0, "%s", err);
    CHECK(c.count == 2 && strcmp(c.files[1].name, "tri.obj") == 0 && c.files[1].len == b.files[1].len &&
              memcmp(c.files[1].data, b.files[1].data, b.files[1].len) == 0,
          "round trip lost the mesh");
    scene *s = scene_load_bundle(&c, NULL, err, sizeof err);
    CHECK(s && s->triangle_count == 2 && s->sphere_count == 1, "scene from the bundle: %s", s ? "wrong counts" : err);
    scene_free(s);
    scene_bundle_hash(bytes, len, h1);
    CHECK(strlen(h1) == 64, "hash %s", h1);
    bytes[len - 2] ^= 1; /* one bit of the mesh */
    scene_bundle_hash(bytes, len, h2);
    CHECK(strcmp(h1, h2) != 0, "hash ignores the content");
    for (size_t cut = 0; cut < len; cut += 7) {
        scene_bundle t;
        CHECK(scene_bundle_parse(bytes, cut, &t, err, sizeof err) == -1, "truncated bundle (%zu of %zu) accepted", cut,
              len);
    }
    free(bytes);
    scene_bundle_free(&b);
    scene_bundle_free(&c);
    /* A missing mesh is reported against its field, as without bundles. */
    path = util_write_temp("nomesh.json", "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -3], \"look_at\": [0, 0, 0], \"fov\": 40},"
                                          " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
                                          " \"shapes\": [{\"type\": \"mesh\", \"file\": \"gone.obj\", \"material\": \"w\"}]}");
    s = scene_load(path, NULL, err, sizeof err);
    CHECK(!s && strstr(err, "shapes[0].file") && strstr(err, "gone.obj"), "missing mesh: %s", err);
}

TEST(tile_frame_round_trip) {
    float rgb[2 * 3 * 3];
    for (int i = 0; i < 18; i++) rgb[i] = (float)i * 0.25f + 1e-30f;
    proto_tile t = {7, 42, 2, 3, {11, 22, 33, 44}, 3}, u;
    size_t len;
    uint8_t *f = proto_tile_frame(&t, rgb, &len);
    char err[256];
    CHECK(len == WIRE_HEADER_BYTES + PROTO_TILE_HEADER_BYTES + 72 && f[4] == WIRE_KIND_TILE, "frame length %zu", len);
    CHECK(wire_get_u32(f) == len - 4, "length field");
    const uint8_t *body = f + WIRE_HEADER_BYTES;
    CHECK(proto_tile_parse(body, len - WIRE_HEADER_BYTES, &u, err, sizeof err) == 0, "%s", err);
    CHECK(u.job == 7 && u.tile == 42 && u.width == 2 && u.height == 3 && u.stats.samples == 11 &&
              u.stats.bad_samples == 44,
          "header fields");
    for (int i = 0; i < 18; i++)
        CHECK(wire_get_f32(body + PROTO_TILE_HEADER_BYTES + 4 * i) == rgb[i], "pixel float %d", i);
    CHECK(proto_tile_parse(body, len - WIRE_HEADER_BYTES - 4, &u, err, sizeof err) == -1 &&
              strstr(err, "do not match"),
          "short tile accepted: %s", err);
    free(f);
}

TEST(job_and_assign_messages) {
    proto_job j = {.id = 3, .width = 640, .height = 480, .spp = 64, .max_depth = 12,
                   .seed = 18446744073709551615ull, .integrator = {.no_nee = 1}};
    memset(j.scene_hash, 'a', 64);
    j.scene_hash[64] = '\0';
    cJSON *m = proto_job_json(&j);
    proto_job k;
    char err[256];
    CHECK(proto_job_parse(m, "coordinator", &k, err, sizeof err) == 0, "%s", err);
    CHECK(k.seed == j.seed && k.integrator.no_nee == 1 && k.integrator.no_mis == 0 && k.width == 640 &&
              strcmp(k.scene_hash, j.scene_hash) == 0,
          "job round trip (a 64-bit seed must survive JSON)");
    CHECK(k.roulette_depth == 0 && k.max_depth == 12, "roulette_depth 0 (from the camera hit) lost: %d",
          k.roulette_depth);
    /* A job journaled before roulette_depth: the default, not 0. */
    cJSON_DeleteItemFromObject(m, "roulette_depth");
    CHECK(proto_job_parse(m, "coordinator", &k, err, sizeof err) == 0 &&
              k.roulette_depth == SCENE_ROULETTE_DEPTH_DEFAULT,
          "a job without roulette_depth: %s, %d", err, k.roulette_depth);
    cJSON_AddNumberToObject(m, "roulette_depth", 1025);
    CHECK(proto_job_parse(m, "coordinator", &k, err, sizeof err) == -1 &&
              strstr(err, "coordinator: job.roulette_depth: expected an integer from 0 to 1024"),
          "roulette_depth 1025: %s", err);
    cJSON_ReplaceItemInObject(m, "roulette_depth", cJSON_CreateNumber(7));
    cJSON_ReplaceItemInObject(m, "seed", cJSON_CreateString("-1"));
    CHECK(proto_job_parse(m, "coordinator", &k, err, sizeof err) == -1 && strstr(err, "coordinator: job.seed"),
          "negative seed: %s", err);
    cJSON_Delete(m);
    proto_assign a = {3, 9, {8, 16, 16, 24}, 0, 64, NULL}, b;
    m = proto_assign_json(&a);
    CHECK(proto_assign_parse(m, "w", &b, err, sizeof err) == 0 && b.rect.x1 == 16 && b.rect.y0 == 16 &&
              b.count == 64 && b.mask == NULL,
          "assign round trip: %s", err);
    cJSON_ReplaceItemInObject(m, "rect", cJSON_Parse("[8, 16, 8, 24]"));
    CHECK(proto_assign_parse(m, "w", &b, err, sizeof err) == -1 && strstr(err, "assign.rect: empty"), "%s", err);
    cJSON_Delete(m);
}

/* Adaptive rounds: the job says so, the assignment carries the pixel mask
 * (4 pixels per hex digit), and a tile of sums has 6 floats per pixel. */
TEST(adaptive_messages) {
    proto_job j = {.id = 5, .width = 64, .height = 64, .spp = 256, .max_depth = 8, .adaptive = 1};
    memset(j.scene_hash, 'b', 64);
    j.scene_hash[64] = '\0';
    cJSON *m = proto_job_json(&j);
    proto_job k;
    char err[256];
    CHECK(proto_job_parse(m, "c", &k, err, sizeof err) == 0 && k.adaptive == 1, "adaptive flag lost: %s", err);
    cJSON_Delete(m);
    uint8_t mask[5 * 3];
    for (int i = 0; i < 15; i++) mask[i] = (uint8_t)((i * 7) % 3 == 0);
    proto_assign a = {5, 2, {10, 20, 15, 23}, 32, 32, mask}, b;
    m = proto_assign_json(&a);
    const cJSON *hex = cJSON_GetObjectItemCaseSensitive(m, "mask");
    CHECK(cJSON_IsString(hex) && strlen(hex->valuestring) == 4, "15 pixels should take 4 hex digits");
    CHECK(proto_assign_parse(m, "w", &b, err, sizeof err) == 0 && b.mask && memcmp(b.mask, mask, 15) == 0 &&
              b.first == 32,
          "mask round trip: %s", err);
    free(b.mask);
    cJSON_ReplaceItemInObject(m, "mask", cJSON_CreateString("fff"));
    CHECK(proto_assign_parse(m, "w", &b, err, sizeof err) == -1 && strstr(err, "assign.mask: expected 4 hex digits"),
          "short mask: %s", err);
    cJSON_ReplaceItemInObject(m, "mask", cJSON_CreateString("ffgf"));
    CHECK(proto_assign_parse(m, "w", &b, err, sizeof err) == -1 && strstr(err, "hex"), "bad digit: %s", err);
    cJSON_Delete(m);
    float sums[2 * 2 * ADAPTIVE_CHANNELS];
    for (int i = 0; i < 24; i++) sums[i] = (float)i;
    proto_tile t = {5, 2, 2, 2, {1, 2, 3, 4}, ADAPTIVE_CHANNELS}, u;
    size_t len;
    uint8_t *f = proto_tile_frame(&t, sums, &len);
    CHECK(f && proto_tile_parse(f + WIRE_HEADER_BYTES, len - WIRE_HEADER_BYTES, &u, err, sizeof err) == 0 &&
              u.channels == ADAPTIVE_CHANNELS,
          "sums tile: %s", err);
    CHECK(proto_tile_parse(f + WIRE_HEADER_BYTES, len - WIRE_HEADER_BYTES - 4, &u, err, sizeof err) == -1,
          "a tile 4 bytes short was accepted");
    free(f);
}

TEST(address_parsing) {
    char host[64], err[128];
    int port;
    CHECK(address_parse("coordinator:7000", host, sizeof host, &port, err, sizeof err) == 0 &&
              strcmp(host, "coordinator") == 0 && port == 7000,
          "name:port");
    CHECK(address_parse("[::1]:80", host, sizeof host, &port, err, sizeof err) == 0 && strcmp(host, "::1") == 0 &&
              port == 80,
          "[v6]:port");
    CHECK(address_parse(":0", host, sizeof host, &port, err, sizeof err) == 0 && strcmp(host, "0.0.0.0") == 0,
          ":port");
    CHECK(address_parse("host", host, sizeof host, &port, err, sizeof err) == -1 && strstr(err, "HOST:PORT"),
          "no port: %s", err);
    CHECK(address_parse("h:70000", host, sizeof host, &port, err, sizeof err) == -1 && strstr(err, "0 to 65535"),
          "big port: %s", err);
    char text[80];
    address_format("::1", 7000, text, sizeof text);
    CHECK(strcmp(text, "[::1]:7000") == 0 && address_parse(text, host, sizeof host, &port, err, sizeof err) == 0 &&
              strcmp(host, "::1") == 0 && port == 7000,
          "an IPv6 address printed as %s", text);
    address_format("10.0.0.2", 80, text, sizeof text);
    CHECK(strcmp(text, "10.0.0.2:80") == 0, "an IPv4 address printed as %s", text);
}
