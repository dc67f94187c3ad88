/* model_files.c - naming, listing and splitting the files of a model. */
#include "model_files.h"

#include <cjson/cJSON.h>
#include <ctype.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>

model_kind model_kind_of(const char *name) {
    const char *dot = strrchr(name, '.');
    if (!dot || strchr(dot, '/')) return MODEL_NONE;
    if (strcasecmp(dot, ".gltf") == 0) return MODEL_GLTF;
    if (strcasecmp(dot, ".glb") == 0) return MODEL_GLB;
    if (strcasecmp(dot, ".obj") == 0) return MODEL_OBJ;
    if (strcasecmp(dot, ".mtl") == 0) return MODEL_MTL;
    return MODEL_NONE;
}

static int hexval(int c) {
    if (c >= '0' && c <= '9') return c - '0';
    c = tolower(c);
    return c >= 'a' && c <= 'f' ? c - 'a' + 10 : -1;
}

/* Remove "." segments and "x/.." pairs in place; a leading "/" stays. */
static void normalise(char *p) {
    char *segs[512];
    int n = 0;
    char buf[4096];
    snprintf(buf, sizeof buf, "%s", p);
    for (char *tok = strtok(buf, "/"); tok; tok = strtok(NULL, "/")) {
        if (strcmp(tok, ".") == 0) continue;
        if (strcmp(tok, "..") == 0 && n > 0 && strcmp(segs[n - 1], "..") != 0) {
            n--;
            continue;
        }
        if (n < 512) segs[n++] = tok;
    }
    char out[4096];
    size_t used = 0;
    int absolute = p[0] == '/';
    out[0] = '\0';
    for (int i = 0; i < n && used < sizeof out; i++)
        used += (size_t)snprintf(out + used, sizeof out - used, "%s%s", i || absolute ? "/" : "", segs[i]);
    snprintf(p, 4096, "%s", out);
}

int model_join(const char *base, const char *rel, int percent_decode, char *out, size_t out_len) {
    char dec[4096];
    size_t k = 0;
    for (size_t i = 0; rel[i] && k + 1 < sizeof dec; i++) {
        int h1, h2;
        if (percent_decode && rel[i] == '%' && (h1 = hexval(rel[i + 1])) >= 0 && (h2 = hexval(rel[i + 2])) >= 0) {
            dec[k++] = (char)(h1 * 16 + h2);
            i += 2;
        } else {
            dec[k++] = rel[i] == '\\' ? '/' : rel[i];
        }
    }
    dec[k] = '\0';
    if (k == 0 || dec[0] == '/' || memchr(dec, '\0', k)) return -1;
    const char *slash = strrchr(base, '/');
    char joined[4096];
    int n = slash ? snprintf(joined, sizeof joined, "%.*s/%s", (int)(slash - base), base, dec)
                  : snprintf(joined, sizeof joined, "%s", dec);
    if (n < 0 || (size_t)n >= sizeof joined) return -1;
    normalise(joined);
    if (strlen(joined) + 1 > out_len || !joined[0]) return -1;
    snprintf(out, out_len, "%s", joined);
    return 0;
}

int model_glb_chunks(const char *name, const char *data, size_t len, const char **json, size_t *json_len,
                     const char **bin, size_t *bin_len, char *err, size_t err_len) {
    const uint8_t *p = (const uint8_t *)data;
#define U32(o) ((uint32_t)p[o] | (uint32_t)p[(o) + 1] << 8 | (uint32_t)p[(o) + 2] << 16 | (uint32_t)p[(o) + 3] << 24)
    *bin = NULL;
    *bin_len = 0;
    if (len < 20 || memcmp(data, "glTF", 4) != 0) {
        snprintf(err, err_len, "%s: not a binary glTF (no \"glTF\" header)%s", name, len < 20 ? ", or truncated" : "");
        return -1;
    }
    if (U32(4) != 2) {
        snprintf(err, err_len, "%s: binary glTF version %u (only 2 is supported)", name, U32(4));
        return -1;
    }
    if (U32(8) != len) {
        snprintf(err, err_len, "%s: truncated or padded .glb: its header says %u bytes, the file has %zu", name,
                 U32(8), len);
        return -1;
    }
    size_t jl = U32(12);
    if (U32(16) != 0x4E4F534Au || jl > len - 20) {
        snprintf(err, err_len, "%s: .glb: the first chunk is not a JSON chunk that fits in the file", name);
        return -1;
    }
    *json = data + 20;
    *json_len = jl;
    size_t off = 20 + jl;
    if (len - off >= 8) {
        size_t bl = U32(off);
        if (U32(off + 4) == 0x004E4942u) {
            if (bl > len - off - 8) {
                snprintf(err, err_len, "%s: .glb: the BIN chunk is longer than the file (truncated)", name);
                return -1;
            }
            *bin = data + off + 8;
            *bin_len = bl;
        }
    }
#undef U32
    return 0;
}

static int gltf_refs(const char *name, const char *json, size_t len, int (*cb)(void *, const char *), void *ctx) {
    cJSON *root = cJSON_ParseWithLength(json, len);
    static const char *const lists[] = {"buffers", "images"};
    int rc = 0;
    for (int l = 0; l < 2 && !rc; l++) {
        const cJSON *e;
        cJSON_ArrayForEach(e, cJSON_GetObjectItemCaseSensitive(root, lists[l])) {
            const cJSON *uri = cJSON_GetObjectItemCaseSensitive(e, "uri");
            char full[4096];
            if (!cJSON_IsString(uri) || strncmp(uri->valuestring, "data:", 5) == 0) continue;
            if (model_join(name, uri->valuestring, 1, full, sizeof full)) continue;
            if ((rc = cb(ctx, full))) break;
        }
    }
    cJSON_Delete(root);
    return rc;
}

/* The line in data[0, len) that holds position p: its start, after
 * spaces and tabs, in *start, and its end (the '\n' or len) returned, if
 * only spaces and tabs come before p on it; else (size_t)-1. */
static size_t line_of(const char *data, size_t len, size_t p, size_t *start) {
    size_t q = p;
    while (q > 0 && (data[q - 1] == ' ' || data[q - 1] == '\t')) q--;
    if (q > 0 && data[q - 1] != '\n') return (size_t)-1;
    *start = p;
    const char *nl = memchr(data + p, '\n', len - p);
    return nl ? (size_t)(nl - data) : len;
}

/* OBJ "mtllib a.mtl b.mtl" and MTL "map_Kd [-options] file": the file is
 * the last word of the line. The keyword's first letter is looked for
 * with memchr, not every line's start: an OBJ's vertex and face lines
 * have no letter m (a 217 MB OBJ scanned line by line took 0.1 s of one
 * core before its parse could start). */
static int text_refs(const char *name, const char *data, size_t len, const char *keyword, int all_words,
                     int (*cb)(void *, const char *), void *ctx) {
    size_t kl = strlen(keyword);
    for (size_t i = 0; i < len;) {
        const char *m = memchr(data + i, keyword[0], len - i);
        if (!m) break;
        size_t s, e = line_of(data, len, (size_t)(m - data), &s);
        if (e == (size_t)-1 || !(e - s > kl && strncmp(data + s, keyword, kl) == 0 &&
                                 (data[s + kl] == ' ' || data[s + kl] == '\t'))) {
            i = (size_t)(m - data) + 1;
            continue;
        }
        char line[4096];
        snprintf(line, sizeof line, "%.*s", (int)(e - s - kl), data + s + kl);
        char *words[64];
        int n = 0;
        for (char *w = strtok(line, " \t\r"); w && n < 64; w = strtok(NULL, " \t\r")) words[n++] = w;
        for (int k = all_words ? 0 : n - 1; k >= 0 && k < n; k++) {
            char full[4096];
            if (model_join(name, words[k], 0, full, sizeof full)) continue;
            int rc = cb(ctx, full);
            if (rc) return rc;
        }
        i = e + 1;
    }
    return 0;
}

int model_references(const char *name, const char *data, size_t len, int (*cb)(void *ctx, const char *name),
                     void *ctx) {
    switch (model_kind_of(name)) {
    case MODEL_GLTF:
        return gltf_refs(name, data, len, cb, ctx);
    case MODEL_GLB: {
        const char *json, *bin;
        size_t jl, bl;
        char err[256];
        if (model_glb_chunks(name, data, len, &json, &jl, &bin, &bl, err, sizeof err)) return 0;
        return gltf_refs(name, json, jl, cb, ctx);
    }
    case MODEL_OBJ:
        return text_refs(name, data, len, "mtllib", 1, cb, ctx);
    case MODEL_MTL:
        return text_refs(name, data, len, "map_Kd", 0, cb, ctx);
    default:
        return 0;
    }
}

char *model_scene_json(const char *path, const char *camera, size_t *len) {
    const char *slash = strrchr(path, '/');
    cJSON *root = cJSON_CreateObject(), *imp = cJSON_AddObjectToObject(root, "import");
    if (!imp || !cJSON_AddStringToObject(imp, "file", slash ? slash + 1 : path) ||
        (camera && !cJSON_AddStringToObject(imp, "camera", camera))) {
        cJSON_Delete(root);
        return NULL;
    }
    char *text = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    if (text) *len = strlen(text);
    return text;
}

int model_bundle_select_camera(scene_bundle *b, const char *camera, char *err, size_t err_len) {
    const char *path = b->files[0].name;
    if (b->count > 1 && b->files[1].streamed) path = b->files[1].name; /* a model from stdin or a pipe */
    if (model_kind_of(path) == MODEL_NONE || model_kind_of(path) == MODEL_MTL) {
        snprintf(err, err_len, "%s: --camera applies to glTF and OBJ files, not to a JSON scene", path);
        return -1;
    }
    size_t len;
    char *text = model_scene_json(path, camera, &len);
    if (!text) {
        snprintf(err, err_len, "%s: out of memory", path);
        return -1;
    }
    free(b->files[0].data);
    b->files[0].data = text;
    b->files[0].len = len;
    return 0;
}
