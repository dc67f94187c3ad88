/* job.c - encode and validate jobs, assignments and tile results (job.h). */
#include "job.h"

#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <math.h>
#include <string.h>

#include "json_field.h"
#include "net/wire.h"
#include "limit.h"

cJSON *proto_job_json(const proto_job *j) {
    char seed[32];
    snprintf(seed, sizeof seed, "%" PRIu64, j->seed);
    cJSON *m = cJSON_CreateObject();
    if (!m || !cJSON_AddStringToObject(m, "type", "job") || !cJSON_AddNumberToObject(m, "job", j->id) ||
        !cJSON_AddStringToObject(m, "scene", j->scene_hash) || !cJSON_AddNumberToObject(m, "width", j->width) ||
        !cJSON_AddNumberToObject(m, "height", j->height) || !cJSON_AddNumberToObject(m, "spp", j->spp) ||
        !cJSON_AddNumberToObject(m, "max_depth", j->max_depth) ||
        !cJSON_AddNumberToObject(m, "roulette_depth", j->roulette_depth) ||
        !cJSON_AddStringToObject(m, "seed", seed) ||
        !cJSON_AddBoolToObject(m, "nee", !j->integrator.no_nee) ||
        !cJSON_AddBoolToObject(m, "mis", !j->integrator.no_mis) ||
        !cJSON_AddStringToObject(m, "sampler", sampler_name(j->integrator.sampler)) ||
        (j->adaptive && !cJSON_AddBoolToObject(m, "adaptive", 1))) {
        cJSON_Delete(m);
        return NULL;
    }
    return m;
}

/* Add "mask" (see proto_assign) to m. Returns 1, or 0 when out of memory. */
static int add_mask(cJSON *m, const proto_assign *a) {
    size_t px = (size_t)tile_width(&a->rect) * (size_t)tile_height(&a->rect), digits = (px + 3) / 4;
    char *hex = malloc(digits + 1);
    if (!hex) return 0;
    for (size_t i = 0; i < digits; i++) {
        unsigned v = 0;
        for (size_t k = 0; k < 4 && 4 * i + k < px; k++) v |= (unsigned)(a->mask[4 * i + k] != 0) << k;
        hex[i] = "0123456789abcdef"[v];
    }
    hex[digits] = '\0';
    int ok = cJSON_AddStringToObject(m, "mask", hex) != NULL;
    free(hex);
    return ok;
}

cJSON *proto_assign_json(const proto_assign *a) {
    cJSON *m = cJSON_CreateObject(), *rect = cJSON_CreateArray();
    int ok = m && rect && cJSON_AddItemToObject(m, "rect", rect);
    if (!ok) cJSON_Delete(rect);
    const int r[4] = {a->rect.x0, a->rect.y0, a->rect.x1, a->rect.y1};
    for (int i = 0; i < 4 && ok; i++) ok = cJSON_AddItemToArray(rect, cJSON_CreateNumber(r[i]));
    if (!ok || !cJSON_AddStringToObject(m, "type", "assign") || !cJSON_AddNumberToObject(m, "job", a->job) ||
        !cJSON_AddNumberToObject(m, "tile", a->tile) || !cJSON_AddNumberToObject(m, "first", a->first) ||
        !cJSON_AddNumberToObject(m, "count", a->count) || (a->mask && !add_mask(m, a))) {
        cJSON_Delete(m);
        return NULL;
    }
    return m;
}

int proto_job_parse(const cJSON *msg, const char *peer, proto_job *out, char *err, size_t err_len) {
    static const char *const keys[] = {"type", "job", "scene", "width", "height", "spp",
                                       "max_depth", "roulette_depth", "seed", "nee", "mis", "sampler",
                                       "adaptive", NULL};
    json_ctx c = {peer, err, err_len};
    long long id, w, h, spp, depth, roulette;
    const char *hash, *seed, *sampler; /* sampler: NULL (sobol) in jobs journaled before samplers */
    int nee, mis, adaptive = 0;
    memset(out, 0, sizeof *out);
    if (jf_check_object(&c, msg, "job", keys) || jf_int(&c, msg, "job", "job", 1, 0, 0, UINT32_MAX, &id) ||
        jf_string(&c, msg, "job", "scene", 1, &hash) || jf_int(&c, msg, "job", "width", 1, 0, 1, LIMIT_SIDE, &w) ||
        jf_int(&c, msg, "job", "height", 1, 0, 1, LIMIT_SIDE, &h) ||
        jf_int(&c, msg, "job", "spp", 1, 0, 1, LIMIT_SPP, &spp) ||
        jf_int(&c, msg, "job", "max_depth", 1, 0, 1, LIMIT_DEPTH, &depth) ||
        /* absent in jobs journaled before it: the default then */
        jf_int(&c, msg, "job", "roulette_depth", 0, SCENE_ROULETTE_DEPTH_DEFAULT, 0, LIMIT_DEPTH, &roulette) ||
        jf_string(&c, msg, "job", "seed", 1, &seed) || jf_bool(&c, msg, "job", "nee", 1, &nee) ||
        jf_bool(&c, msg, "job", "mis", 1, &mis) || jf_string(&c, msg, "job", "sampler", 0, &sampler) ||
        jf_bool(&c, msg, "job", "adaptive", 0, &adaptive))
        return -1;
    out->adaptive = adaptive;
    if (!sampler) out->integrator.sampler = SAMPLER_SOBOL; /* journaled before samplers had names */
    else if (sampler_parse(sampler, &out->integrator.sampler) != 0)
        return jf_fail(&c, "job", "sampler", "expected \"sobol-global\", \"sobol\" or \"random\", got \"%s\"",
                       sampler);
    if (strlen(hash) != SCENE_BUNDLE_HASH_HEX - 1 || strspn(hash, "0123456789abcdef") != strlen(hash))
        return jf_fail(&c, "job", "scene", "expected a 64-digit hex hash");
    char *end;
    errno = 0;
    unsigned long long sv = strtoull(seed, &end, 10);
    if (errno || end == seed || *end || seed[0] == '-')
        return jf_fail(&c, "job", "seed", "expected a decimal integer string, got \"%s\"", seed);
    out->id = (uint32_t)id;
    memcpy(out->scene_hash, hash, SCENE_BUNDLE_HASH_HEX);
    out->width = (int)w;
    out->height = (int)h;
    out->spp = (int)spp;
    out->max_depth = (int)depth;
    out->roulette_depth = (int)roulette;
    out->seed = sv;
    out->integrator.no_nee = !nee;
    out->integrator.no_mis = !mis;
    return 0;
}

/* Decode an assignment's "mask" into out->mask (allocated). Returns 0, or
 * -1 with the reason (wrong length, not hex, out of memory) in the context. */
static int parse_mask(json_ctx *c, const char *hex, proto_assign *out) {
    size_t px = (size_t)tile_width(&out->rect) * (size_t)tile_height(&out->rect), digits = (px + 3) / 4;
    if (strlen(hex) != digits)
        return jf_fail(c, "assign", "mask", "expected %zu hex digits for %zu pixels, got %zu", digits, px,
                       strlen(hex));
    if (strspn(hex, "0123456789abcdef") != digits)
        return jf_fail(c, "assign", "mask", "expected lower-case hex digits only");
    if (!(out->mask = malloc(px))) return jf_fail(c, "assign", "mask", "out of memory");
    for (size_t i = 0; i < px; i++) {
        char d = hex[i / 4];
        unsigned v = (unsigned)(d <= '9' ? d - '0' : d - 'a' + 10);
        out->mask[i] = (uint8_t)((v >> (i % 4)) & 1u);
    }
    return 0;
}

int proto_assign_parse(const cJSON *msg, const char *peer, proto_assign *out, char *err, size_t err_len) {
    static const char *const keys[] = {"type", "job", "tile", "rect", "first", "count", "mask", NULL};
    const char *mask;
    json_ctx c = {peer, err, err_len};
    long long job, tile, first, count;
    memset(out, 0, sizeof *out);
    if (jf_check_object(&c, msg, "assign", keys) || jf_int(&c, msg, "assign", "job", 1, 0, 0, UINT32_MAX, &job) ||
        jf_int(&c, msg, "assign", "tile", 1, 0, 0, UINT32_MAX, &tile) ||
        jf_int(&c, msg, "assign", "first", 1, 0, 0, LIMIT_SPP, &first) ||
        jf_int(&c, msg, "assign", "count", 1, 0, 1, LIMIT_SPP, &count) ||
        jf_string(&c, msg, "assign", "mask", 0, &mask))
        return -1;
    const cJSON *rect = cJSON_GetObjectItemCaseSensitive(msg, "rect");
    int r[4];
    if (!cJSON_IsArray(rect) || cJSON_GetArraySize(rect) != 4)
        return jf_fail(&c, "assign", "rect", "expected [x0, y0, x1, y1]");
    for (int i = 0; i < 4; i++) {
        const cJSON *v = cJSON_GetArrayItem(rect, i);
        if (!cJSON_IsNumber(v) || !(v->valuedouble >= 0 && v->valuedouble <= LIMIT_SIDE) ||
            v->valuedouble != floor(v->valuedouble))
            return jf_fail(&c, "assign", "rect", "expected 4 integers from 0 to 32768");
        r[i] = (int)v->valuedouble;
    }
    if (r[2] <= r[0] || r[3] <= r[1]) return jf_fail(&c, "assign", "rect", "empty rectangle");
    out->job = (uint32_t)job;
    out->tile = (uint32_t)tile;
    out->rect = (tile_rect){r[0], r[1], r[2], r[3]};
    out->first = (uint32_t)first;
    out->count = (uint32_t)count;
    return mask ? parse_mask(&c, mask, out) : 0;
}

uint8_t *proto_tile_frame(const proto_tile *t, const float *rgb, size_t *frame_len) {
    size_t n = (size_t)t->width * t->height * t->channels;
    uint8_t *f = wire_frame_new(WIRE_KIND_TILE, PROTO_TILE_HEADER_BYTES + 4 * n, frame_len);
    if (!f) return NULL;
    uint8_t *p = f + WIRE_HEADER_BYTES;
    wire_put_u32(p, t->job);
    wire_put_u32(p + 4, t->tile);
    wire_put_u32(p + 8, t->width);
    wire_put_u32(p + 12, t->height);
    wire_put_u64(p + 16, t->stats.samples);
    wire_put_u64(p + 24, t->stats.rays);
    wire_put_u64(p + 32, t->stats.shadow_rays);
    wire_put_u64(p + 40, t->stats.bad_samples);
    for (size_t i = 0; i < n; i++) wire_put_f32(p + PROTO_TILE_HEADER_BYTES + 4 * i, rgb[i]);
    return f;
}

int proto_tile_parse(const uint8_t *body, size_t len, proto_tile *out, char *err, size_t err_len) {
    if (len < PROTO_TILE_HEADER_BYTES) {
        snprintf(err, err_len, "tile frame of %zu bytes is shorter than its header", len);
        return -1;
    }
    out->job = wire_get_u32(body);
    out->tile = wire_get_u32(body + 4);
    out->width = wire_get_u32(body + 8);
    out->height = wire_get_u32(body + 12);
    out->stats.samples = wire_get_u64(body + 16);
    out->stats.rays = wire_get_u64(body + 24);
    out->stats.shadow_rays = wire_get_u64(body + 32);
    out->stats.bad_samples = wire_get_u64(body + 40);
    uint64_t px = (uint64_t)out->width * out->height;
    out->channels = PROTO_TILE_HEADER_BYTES + px * 12 == len                     ? 3
                    : PROTO_TILE_HEADER_BYTES + px * 4 * ADAPTIVE_CHANNELS == len ? ADAPTIVE_CHANNELS
                                                                                  : 0;
    if (out->width == 0 || out->height == 0 || out->width > LIMIT_SIDE || out->height > LIMIT_SIDE || !out->channels) {
        snprintf(err, err_len, "tile %u of job %u: %ux%u pixels do not match the frame's %zu bytes", out->tile,
                 out->job, out->width, out->height, len);
        return -1;
    }
    return 0;
}

void proto_tile_pixels(const uint8_t *body, const proto_tile *t, float *out) {
    size_t n = (size_t)t->width * t->height * t->channels;
    for (size_t i = 0; i < n; i++) out[i] = wire_get_f32(body + PROTO_TILE_HEADER_BYTES + 4 * i);
}

size_t proto_tile_frame_max(int side) {
    return 1 + PROTO_TILE_HEADER_BYTES + (size_t)side * (size_t)side * 4 * ADAPTIVE_CHANNELS;
}
