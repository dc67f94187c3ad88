/* protocol.c - the farm's JSON control messages and the build identity. */
#include "protocol.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "build_id.h"
#include "version.h"
#include "wire.h"

const char *protocol_build_id(void) { return TESSERA_VERSION "+" TESSERA_BUILD_ID; }

cJSON *proto_parse_json(const uint8_t *body, size_t len, const char **type, char *err, size_t err_len) {
    cJSON *m = cJSON_ParseWithLength((const char *)body, len);
    if (!m) {
        snprintf(err, err_len, "malformed JSON message (%zu bytes)", len);
        return NULL;
    }
    const cJSON *t = cJSON_GetObjectItemCaseSensitive(m, "type");
    if (!cJSON_IsObject(m) || !cJSON_IsString(t)) {
        snprintf(err, err_len, "JSON message without a string \"type\"");
        cJSON_Delete(m);
        return NULL;
    }
    *type = t->valuestring;
    return m;
}

uint8_t *proto_frame_simple(const char *type, size_t *frame_len) {
    cJSON *m = cJSON_CreateObject();
    uint8_t *f = m && cJSON_AddStringToObject(m, "type", type) ? wire_frame_json(m, frame_len) : NULL;
    cJSON_Delete(m);
    return f;
}

uint8_t *proto_frame_reason(const char *type, const char *reason, size_t *frame_len) {
    cJSON *m = cJSON_CreateObject();
    uint8_t *f = m && cJSON_AddStringToObject(m, "type", type) && cJSON_AddStringToObject(m, "reason", reason)
                     ? wire_frame_json(m, frame_len)
                     : NULL;
    cJSON_Delete(m);
    return f;
}

