/* fuzz_frames.c - libFuzzer target: what a peer can send. The bytes are
 * fed to a frame decoder in pieces whose sizes come from the input, and
 * every frame goes through the parsers a coordinator or worker applies:
 * JSON control messages (job, assign with and without an adaptive mask),
 * tiles of means or of adaptive sums, scene bundles. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "job/job.h"
#include "net/protocol.h"
#include "render/scene_bundle.h"
#include "net/wire.h"

static int on_frame(void *ctx, int kind, const uint8_t *body, size_t len) {
    (void)ctx;
    char err[512];
    if (kind == WIRE_KIND_JSON) {
        const char *type;
        cJSON *m = proto_parse_json(body, len, &type, err, sizeof err);
        if (m) {
            proto_job j;
            proto_assign a;
            if (strcmp(type, "job") == 0) proto_job_parse(m, "fuzz", &j, err, sizeof err);
            if (strcmp(type, "assign") == 0 && proto_assign_parse(m, "fuzz", &a, err, sizeof err) == 0)
                free(a.mask);
            cJSON_Delete(m);
        }
    } else if (kind == WIRE_KIND_TILE) {
        proto_tile t;
        if (proto_tile_parse(body, len, &t, err, sizeof err) == 0 &&
            ((t.channels != 3 && t.channels != ADAPTIVE_CHANNELS) ||
             len != PROTO_TILE_HEADER_BYTES + (size_t)t.width * t.height * 4 * t.channels))
            abort(); /* accepted a tile whose size does not match */
    } else if (kind == WIRE_KIND_SCENE) {
        scene_bundle b;
        if (scene_bundle_parse(body, len, &b, err, sizeof err) == 0) scene_bundle_free(&b);
    }
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    size_t step = 1 + data[0] % 64; /* how the stream is cut into reads */
    wire_decoder d;
    wire_decoder_init(&d, 1 << 20);
    char err[256];
    for (size_t off = 1; off < size; off += step) {
        size_t n = size - off < step ? size - off : step;
        if (wire_decoder_feed(&d, data + off, n, on_frame, NULL, err, sizeof err) != 0) break;
    }
    if (d.cap > (2u << 20)) abort(); /* more memory than one frame's limit */
    wire_decoder_free(&d);
    return 0;
}
