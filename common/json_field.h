/* json_field.h - typed, validated reads of cJSON fields, with errors that
 * name the file and the field ("scenes/x.json: render.spp: expected an
 * integer from 1 to 16777216, got -3").
 *
 * `where` is the path of the object being read ("render", "shapes[3]"), or ""
 * at the top level. Every getter returns 0 on success and -1 after writing
 * the error into ctx->err. A field that is absent gets `def` unless
 * `required`, which makes its absence an error. */
#ifndef TESSERA_JSON_FIELD_H
#define TESSERA_JSON_FIELD_H

#include <cjson/cJSON.h>
#include <stddef.h>

typedef struct {
    const char *file;
    char *err;
    size_t err_len;
} json_ctx;

/* Parse text (len bytes followed by a NUL) as JSON. Returns the tree (free with cJSON_Delete) or NULL with
 * "FILE:LINE:COLUMN: syntax error near '...'" in ctx->err. */
cJSON *jf_parse(json_ctx *ctx, const char *text, size_t len);

/* Write "FILE: WHERE.KEY: message" (KEY may be NULL). Returns -1. */
int jf_fail(json_ctx *ctx, const char *where, const char *key, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));

/* Check that obj is a JSON object whose keys are all in the NULL-terminated
 * list `allowed`, each at most once. */
int jf_check_object(json_ctx *ctx, const cJSON *obj, const char *where, const char *const *allowed);

int jf_number(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int required,
              double def, double lo, double hi, double *out);
int jf_int(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int required,
           long long def, long long lo, long long hi, long long *out);
/* Three finite numbers, each within [lo, hi]. */
int jf_vec3(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int required,
            const double def[3], double lo, double hi, double out[3]);
int jf_bool(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int def, int *out);
/* *out points into the cJSON tree; NULL when absent and not required. */
int jf_string(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int required,
              const char **out);

#endif
