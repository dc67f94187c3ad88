/* job.h - what a job, a tile assignment and a rendered tile are on the wire
 * (docs/protocol.md): encoded and decoded here, once, for the coordinator,
 * the worker and the job service.
 *
 * The layer above render/ (whose options and tiles it carries) and net/
 * (whose frames and JSON helpers it uses); neither of those includes it.
 * Validation errors name the peer and the field:
 * "worker w1 (127.0.0.1:40312): assign.rect: ...". */
#ifndef TESSERA_JOB_H
#define TESSERA_JOB_H

#include <cjson/cJSON.h>
#include <stddef.h>
#include <stdint.h>

#include "render/adaptive.h"
#include "render/integrator.h"
#include "render/render.h"
#include "render/scene_bundle.h"

/* What a job is: which scene, rendered how. Every field a worker needs to
 * produce the same pixels as the single-process renderer. */
typedef struct {
    uint32_t id;
    char scene_hash[SCENE_BUNDLE_HASH_HEX];
    int width, height, spp, max_depth;
    int roulette_depth; /* render.roulette_depth; SCENE_ROULETTE_DEPTH_DEFAULT when a job does not say */
    uint64_t seed; /* sent as a decimal string: JSON numbers are doubles */
    integrator_options integrator;
    int adaptive; /* a round of adaptive sampling: assignments carry a pixel
                   * mask, results are ADAPTIVE_CHANNELS sums per pixel */
} proto_job;

/* One tile of a job to render, with its sample range. */
typedef struct {
    uint32_t job, tile;
    tile_rect rect;
    uint32_t first, count;
    uint8_t *mask; /* adaptive jobs: one byte per pixel of rect (1 = render it);
                    * sent as "mask", hex digits holding 4 pixels each, bit k
                    * of digit i being pixel 4i + k. NULL otherwise.
                    * proto_assign_parse allocates it; free with free(). */
} proto_assign;

/* A rendered tile's fixed header; pixels follow as width * height *
 * channels little-endian float32 values, row-major, top row first: 3
 * means per pixel, or for adaptive jobs ADAPTIVE_CHANNELS sums. */
typedef struct {
    uint32_t job, tile, width, height;
    trace_stats stats;
    uint32_t channels; /* not in the header: told by the frame's length */
} proto_tile;

#define PROTO_TILE_HEADER_BYTES 48

/* Build {"type": "job", ...} / {"type": "assign", ...}. Return NULL only
 * when out of memory; the caller frees with cJSON_Delete. */
cJSON *proto_job_json(const proto_job *j);
cJSON *proto_assign_json(const proto_assign *a);

/* Read a job / assign message into *out. Return 0, or -1 with
 * "PEER: job.FIELD: what is wrong" in err. */
int proto_job_parse(const cJSON *msg, const char *peer, proto_job *out, char *err, size_t err_len);
int proto_assign_parse(const cJSON *msg, const char *peer, proto_assign *out, char *err, size_t err_len);

/* Encode a tile result as a complete 'T' frame (the caller frees), or NULL
 * when out of memory. rgb holds width * height * t->channels floats. */
uint8_t *proto_tile_frame(const proto_tile *t, const float *rgb, size_t *frame_len);

/* Decode a 'T' body's header and check that its length matches the size it
 * claims with 3 or ADAPTIVE_CHANNELS floats per pixel (set in channels). Returns 0 (the pixels then start at body +
 * PROTO_TILE_HEADER_BYTES), or -1 with the reason in err. */
int proto_tile_parse(const uint8_t *body, size_t len, proto_tile *out, char *err, size_t err_len);

/* Decode the pixels of a 'T' body that proto_tile_parse accepted into out
 * (t->width * t->height * t->channels floats, the caller's). Can't fail. */
void proto_tile_pixels(const uint8_t *body, const proto_tile *t, float *out);

/* Largest 'T' frame (L of wire.h) for tiles of at most side x side pixels. */
size_t proto_tile_frame_max(int side);

#endif
