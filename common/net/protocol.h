/* protocol.h - the farm's control messages (docs/protocol.md): JSON objects
 * with a "type" inside wire.h's frames, and the build identity peers compare.
 *
 * net/ carries messages and knows nothing of radiance: what a job, an
 * assignment and a rendered tile contain is job/job.h, one layer up.
 *
 * Layer net/: frames, messages, connections, auth, addresses; includes only
 * common/, never render/ (README "Where things are"). */
#ifndef TESSERA_PROTOCOL_H
#define TESSERA_PROTOCOL_H

#include <cjson/cJSON.h>
#include <stddef.h>
#include <stdint.h>

#define PROTOCOL_VERSION 1

/* Lines of a job's event log the coordinator keeps, hence the largest
 * `last` a "logs" request may ask for (the CLI checks it before asking). */
#define PROTOCOL_LOG_LINES_MAX 2000

/* Scenes a worker's hello may claim to hold already ("scenes": bundle
 * hashes; a local farm's forked workers claim the one they were forked
 * with), so that the coordinator does not send their bundles. More are
 * ignored. */
#define PROTOCOL_HELLO_SCENES 8

/* The build's identity, "0.1.0+<git commit>": peers must match exactly,
 * because bit-identical images need the same code on both sides. */
const char *protocol_build_id(void);

/* Parse a 'J' frame's body: a JSON object with a string "type". Returns the
 * tree (cJSON_Delete it) and sets *type, or NULL with the reason in err. */
cJSON *proto_parse_json(const uint8_t *body, size_t len, const char **type, char *err, size_t err_len);

/* A {"type": TYPE} message with nothing else, as a frame (caller frees), or
 * NULL when out of memory. */
uint8_t *proto_frame_simple(const char *type, size_t *frame_len);

/* A {"type": TYPE, "reason": REASON} message ("error", "refused") as a
 * frame (caller frees), or NULL when out of memory. */
uint8_t *proto_frame_reason(const char *type, const char *reason, size_t *frame_len);

#endif
