/* json_field.c - typed, validated reads of cJSON fields with precise errors. */
#include "json_field.h"

#include "args.h"

#include <math.h>
#include <stdarg.h>
#include <stdio.h>
#include <string.h>

cJSON *jf_parse(json_ctx *ctx, const char *text, size_t len) {
    const char *end = NULL;
    cJSON *root = cJSON_ParseWithLengthOpts(text, len + 1, &end, 1) /* + the NUL */;
    if (root) return root;
    if (!end || end < text || end > text + len) end = text + len;
    size_t line = 1, col = 1;
    for (const char *p = text; p < end; p++) {
        if (*p == '\n') {
            line++;
            col = 1;
        } else {
            col++;
        }
    }
    char near[24];
    size_t n = 0;
    for (const char *p = end; p < text + len && n < sizeof near - 1 && *p != '\n'; p++)
        near[n++] = (*p >= 32 && *p < 127) ? *p : '?';
    near[n] = '\0';
    if (n == 0)
        snprintf(ctx->err, ctx->err_len, "%s:%zu:%zu: syntax error: unexpected end of input", ctx->file,
                 line, col);
    else
        snprintf(ctx->err, ctx->err_len, "%s:%zu:%zu: syntax error near '%s'", ctx->file, line, col, near);
    return NULL;
}

int jf_fail(json_ctx *ctx, const char *where, const char *key, const char *fmt, ...) {
    char msg[384];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    const char *dot = (where[0] && key) ? "." : "";
    snprintf(ctx->err, ctx->err_len, "%s: %s%s%s: %s", ctx->file, where, dot, key ? key : "", msg);
    return -1;
}

int jf_check_object(json_ctx *ctx, const cJSON *obj, const char *where, const char *const *allowed) {
    if (!cJSON_IsObject(obj)) return jf_fail(ctx, where[0] ? where : "(top level)", NULL, "expected an object");
    for (const cJSON *it = obj->child; it; it = it->next) {
        int known = 0;
        for (const char *const *a = allowed; *a; a++)
            if (strcmp(*a, it->string) == 0) known = 1;
        if (!known) {
            const char *near = args_closest(it->string, allowed);
            if (near)
                return jf_fail(ctx, where, it->string, "unknown field (did you mean %s%s%s?)", where,
                               where[0] ? "." : "", near);
            return jf_fail(ctx, where, it->string, "unknown field");
        }
        for (const cJSON *o = obj->child; o != it; o = o->next)
            if (strcmp(o->string, it->string) == 0) return jf_fail(ctx, where, it->string, "field given twice");
    }
    return 0;
}

/* The field named key, or NULL. Lookups are case-sensitive. */
static const cJSON *field(const cJSON *obj, const char *key) {
    return cJSON_GetObjectItemCaseSensitive(obj, key);
}

int jf_number(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int required,
              double def, double lo, double hi, double *out) {
    const cJSON *f = field(obj, key);
    if (!f) {
        if (required) return jf_fail(ctx, where, key, "missing (expected a number)");
        *out = def;
        return 0;
    }
    if (!cJSON_IsNumber(f)) return jf_fail(ctx, where, key, "expected a number");
    double v = f->valuedouble;
    if (!isfinite(v)) return jf_fail(ctx, where, key, "number is not finite");
    if (v < lo || v > hi) return jf_fail(ctx, where, key, "expected a number from %g to %g, got %g", lo, hi, v);
    *out = v;
    return 0;
}

int jf_int(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int required,
           long long def, long long lo, long long hi, long long *out) {
    const cJSON *f = field(obj, key);
    if (!f) {
        if (required) return jf_fail(ctx, where, key, "missing (expected an integer)");
        *out = def;
        return 0;
    }
    double v = cJSON_IsNumber(f) ? f->valuedouble : NAN;
    if (!isfinite(v) || v != floor(v)) return jf_fail(ctx, where, key, "expected an integer");
    if (v < (double)lo || v > (double)hi)
        return jf_fail(ctx, where, key, "expected an integer from %lld to %lld, got %.17g", lo, hi, v);
    *out = (long long)v;
    return 0;
}

int jf_vec3(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int required,
            const double def[3], double lo, double hi, double out[3]) {
    const cJSON *f = field(obj, key);
    if (!f) {
        if (required) return jf_fail(ctx, where, key, "missing (expected [x, y, z])");
        memcpy(out, def, 3 * sizeof(double));
        return 0;
    }
    if (!cJSON_IsArray(f) || cJSON_GetArraySize(f) != 3)
        return jf_fail(ctx, where, key, "expected an array of three numbers");
    int i = 0;
    for (const cJSON *e = f->child; e; e = e->next, i++) {
        if (!cJSON_IsNumber(e)) return jf_fail(ctx, where, key, "element %d is not a number", i);
        if (!isfinite(e->valuedouble)) return jf_fail(ctx, where, key, "element %d is not finite", i);
        if (e->valuedouble < lo || e->valuedouble > hi)
            return jf_fail(ctx, where, key, "element %d is %g, expected a value from %g to %g", i,
                           e->valuedouble, lo, hi);
        out[i] = e->valuedouble;
    }
    return 0;
}

int jf_bool(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int def, int *out) {
    const cJSON *f = field(obj, key);
    if (!f) {
        *out = def;
        return 0;
    }
    if (!cJSON_IsBool(f)) return jf_fail(ctx, where, key, "expected true or false");
    *out = cJSON_IsTrue(f);
    return 0;
}

int jf_string(json_ctx *ctx, const cJSON *obj, const char *where, const char *key, int required,
              const char **out) {
    const cJSON *f = field(obj, key);
    if (!f) {
        if (required) return jf_fail(ctx, where, key, "missing (expected a string)");
        *out = NULL;
        return 0;
    }
    if (!cJSON_IsString(f)) return jf_fail(ctx, where, key, "expected a string");
    *out = f->valuestring;
    return 0;
}
