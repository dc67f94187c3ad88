/* import.c - glTF and OBJ models through Assimp, plus the glTF JSON fields
 * Assimp 5.2's C API leaves out (see import.h). */
#include "import.h"

#include <assimp/cfileio.h>
#include <assimp/cimport.h>
#include <assimp/material.h>
#include <assimp/postprocess.h>
#include <assimp/scene.h>
#include <cjson/cJSON.h>
#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model_files.h"
#include "rng.h"

#define IMPORT_LUMENS_PER_WATT 683.0
#define MAX_NODE_VISITS 1000000 /* bounds the node walk of a malformed (cyclic) hierarchy */

/* Extensions whose meaning is honoured (or, for a required one, safe to
 * render without: KHR_materials_emissive_strength etc. are read below). */
static const char *const supported_ext[] = {
    "KHR_materials_emissive_strength", "KHR_materials_transmission", "KHR_materials_ior",
    "KHR_lights_punctual", "KHR_texture_transform", NULL};

typedef struct {
    const scene_bundle *b;   /* NULL when importing from memory */
    const char *name;        /* the model file */
    const char *data;        /* its bytes */
    size_t len;
    char *err;
    size_t err_len;
    cJSON *gltf;             /* glTF JSON (glTF and GLB only) */
    const char *bin;         /* GLB BIN chunk */
    size_t bin_len;
    uint8_t **buffers;       /* glTF buffers decoded on demand (data: URIs) */
    size_t *buffer_lens;
    int buffer_count;
    int *tex_slot;           /* glTF texture index * 2 + srgb -> slot + 1 */
    int tex_slot_count;
    const import_options *opt;
    import_model *m;
    size_t tri_cap;
    size_t normal_cap;       /* of m->normals, in normals */
    uint32_t *normal_slots;  /* hash set of m->normals: index + 1, 0 = empty */
    size_t slot_cap;         /* a power of two, at least twice normal_count */
    size_t visits;
} importer;

static int fail(importer *im, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static int fail(importer *im, const char *fmt, ...) {
    char msg[768];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(msg, sizeof msg, fmt, ap);
    va_end(ap);
    snprintf(im->err, im->err_len, "%s: %s", im->name, msg);
    return -1;
}

/* ---- files: the bundle behind Assimp's file callbacks ------------------- */

typedef struct {
    const char *data;
    size_t len, pos;
} mem_file;

static const scene_bundle_file *bundle_lookup(const importer *im, const char *name) {
    return im->b ? scene_bundle_find(im->b, name) : NULL;
}

static size_t mf_read(struct aiFile *f, char *buf, size_t size, size_t count) {
    mem_file *m = (mem_file *)f->UserData;
    if (size == 0) return 0;
    size_t n = (m->len - m->pos) / size;
    if (n > count) n = count;
    memcpy(buf, m->data + m->pos, n * size);
    m->pos += n * size;
    return n;
}
static size_t mf_write(struct aiFile *f, const char *buf, size_t size, size_t count) {
    (void)f, (void)buf, (void)size, (void)count;
    return 0;
}
static size_t mf_tell(struct aiFile *f) { return ((mem_file *)f->UserData)->pos; }
static size_t mf_size(struct aiFile *f) { return ((mem_file *)f->UserData)->len; }
static void mf_flush(struct aiFile *f) { (void)f; }
static enum aiReturn mf_seek(struct aiFile *f, size_t off, enum aiOrigin origin) {
    mem_file *m = (mem_file *)f->UserData;
    size_t base = origin == aiOrigin_SET ? 0 : origin == aiOrigin_CUR ? m->pos : m->len;
    if (off > m->len - base) return aiReturn_FAILURE;
    m->pos = base + off;
    return aiReturn_SUCCESS;
}

static struct aiFile *io_open(struct aiFileIO *io, const char *path, const char *mode) {
    importer *im = (importer *)io->UserData;
    if (strchr(mode, 'w')) return NULL;
    const char *data = NULL;
    size_t len = 0;
    char norm[4096];
    if (strcmp(path, im->name) == 0) {
        data = im->data;
        len = im->len;
    } else {
        const scene_bundle_file *f = bundle_lookup(im, path);
        if (!f && model_join(path, path[0] == '.' && path[1] == '/' ? path + 2 : path, 0, norm, sizeof norm) == 0)
            f = bundle_lookup(im, norm); /* already relative to the scene; only normalised */
        if (!f) {
            const char *slash = strrchr(path, '/');
            if (model_join(path, slash ? slash + 1 : path, 0, norm, sizeof norm) == 0) f = bundle_lookup(im, norm);
        }
        if (!f || !f->data) return NULL;
        data = f->data;
        len = f->len;
    }
    struct aiFile *af = calloc(1, sizeof *af);
    mem_file *mf = calloc(1, sizeof *mf);
    if (!af || !mf) {
        free(af);
        free(mf);
        return NULL;
    }
    mf->data = data;
    mf->len = len;
    af->ReadProc = mf_read;
    af->WriteProc = mf_write;
    af->TellProc = mf_tell;
    af->FileSizeProc = mf_size;
    af->SeekProc = mf_seek;
    af->FlushProc = mf_flush;
    af->UserData = (aiUserData)mf;
    return af;
}

static void io_close(struct aiFileIO *io, struct aiFile *f) {
    (void)io;
    if (!f) return;
    free(f->UserData);
    free(f);
}

/* A file the model references by uri/path relative to itself: its bytes,
 * or NULL with the error set. */
static const char *referenced_file(importer *im, const char *rel, int percent, size_t *len, const char *field) {
    char full[4096];
    if (model_join(im->name, rel, percent, full, sizeof full)) {
        fail(im, "%s: bad file reference \"%s\"", field, rel);
        return NULL;
    }
    const scene_bundle_file *f = im->b ? scene_bundle_find(im->b, full) : NULL;
    if (!f) {
        fail(im, "%s: %s: missing (not in the scene bundle)", field, full);
        return NULL;
    }
    if (!f->data) {
        fail(im, "%s: %s", field, f->error);
        return NULL;
    }
    *len = f->len;
    return f->data;
}

/* ---- glTF JSON ----------------------------------------------------------- */

static double num_or(const cJSON *o, const char *key, double dflt) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    return cJSON_IsNumber(v) && isfinite(v->valuedouble) ? v->valuedouble : dflt;
}

/* The integer at o[key]: dflt when the key is absent or not a number, -1
 * when it is a number but not an integer an int can hold (-1 is never a
 * valid index or component type, so callers reject it as they would any
 * bad value; converting such a double straight to int is undefined). */
static int int_or(const cJSON *o, const char *key, int dflt) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(o, key);
    if (!cJSON_IsNumber(v)) return dflt;
    double d = v->valuedouble;
    return d >= -2147483648.0 && d <= 2147483647.0 && d == floor(d) ? (int)d : -1;
}

static const cJSON *ext_of(const cJSON *o, const char *ext) {
    return cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(o, "extensions"), ext);
}

static int check_extensions(importer *im) {
    const cJSON *e;
    char unsupported[512] = "";
    size_t used = 0;
    cJSON_ArrayForEach(e, cJSON_GetObjectItemCaseSensitive(im->gltf, "extensionsRequired")) {
        if (!cJSON_IsString(e)) return fail(im, "extensionsRequired: expected strings");
        if (strcmp(e->valuestring, "KHR_draco_mesh_compression") == 0)
            return fail(im, "Draco-compressed meshes (KHR_draco_mesh_compression) are not supported; "
                            "export without mesh compression");
        int ok = 0;
        for (const char *const *s = supported_ext; *s; s++) ok |= strcmp(*s, e->valuestring) == 0;
        if (!ok && used < sizeof unsupported)
            used += (size_t)snprintf(unsupported + used, sizeof unsupported - used, "%s%s", used ? ", " : "",
                                     e->valuestring);
    }
    if (used) return fail(im, "unsupported extensions marked required: %s", unsupported);
    cJSON_ArrayForEach(e, cJSON_GetObjectItemCaseSensitive(im->gltf, "extensionsUsed"))
        if (cJSON_IsString(e) && strcmp(e->valuestring, "KHR_draco_mesh_compression") == 0)
            return fail(im, "Draco-compressed meshes (KHR_draco_mesh_compression) are not supported; "
                            "export without mesh compression");
    return 0;
}

static int b64_value(int c) {
    if (c >= 'A' && c <= 'Z') return c - 'A';
    if (c >= 'a' && c <= 'z') return c - 'a' + 26;
    if (c >= '0' && c <= '9') return c - '0' + 52;
    if (c == '+' || c == '-') return 62;
    if (c == '/' || c == '_') return 63;
    return -1;
}

/* Decode the base64 payload of a data: URI; malloc'd, or NULL. */
static uint8_t *data_uri(const char *uri, size_t *len) {
    const char *comma = strchr(uri, ',');
    if (!comma || !strstr(uri, ";base64")) return NULL;
    const char *p = comma + 1;
    size_t n = strlen(p);
    uint8_t *out = malloc(n / 4 * 3 + 3);
    if (!out) return NULL;
    size_t k = 0;
    uint32_t acc = 0;
    int bits = 0;
    for (size_t i = 0; i < n && p[i] != '='; i++) {
        int v = b64_value((unsigned char)p[i]);
        if (v < 0) {
            free(out);
            return NULL;
        }
        acc = (acc << 6) | (uint32_t)v;
        bits += 6;
        if (bits >= 8) {
            bits -= 8;
            out[k++] = (uint8_t)(acc >> bits);
        }
    }
    *len = k;
    return out;
}

/* The longest data: URI header (the characters before its comma) Assimp
 * reads right: 5.2 keeps the payload's offset in a signed char, so a
 * payload starting past offset 127 is read from the wrong place ("Invalid
 * base64 char value: 18446744073709551488", and 260 bytes leaked inside
 * Assimp; found by fuzz_gltf). Measured with a media type padded to each
 * length: 126 imports, 127 fails. */
#define DATA_URI_MAX_HEADER 126

/* Where a base64 payload (the text after a data: URI's comma) stops being
 * base64: the offset of its first byte that is neither of the alphabet
 * (b64_value) nor padding, of padding that does not end a multiple of 4
 * characters, or of anything after the padding; -1 when it is all base64. */
static long base64_fault(const char *p) {
    size_t i = 0;
    while (p[i] && p[i] != '=' && b64_value((unsigned char)p[i]) >= 0) i++;
    if (!p[i]) return -1;
    if (p[i] != '=') return (long)i;
    size_t first = i;
    while (p[i] == '=' && i - first < 2) i++;
    return p[i] ? (long)i : i % 4 ? (long)first : -1;
}

/* Refuse, naming the field, any data: URI of buffers[] and images[] that
 * Assimp would misread: no comma, a header longer than
 * DATA_URI_MAX_HEADER, or a base64 payload with a byte that is not
 * base64 (Assimp 5.2 leaked 90 bytes on bytes past 0x7f after the
 * padding; found by fuzz_gltf). Returns 0 or -1 (im's error set). */
static int check_data_uris(importer *im) {
    static const char *const arrays[] = {"buffers", "images"};
    for (int a = 0; a < 2; a++) {
        int i = 0;
        const cJSON *e;
        cJSON_ArrayForEach(e, cJSON_GetObjectItemCaseSensitive(im->gltf, arrays[a])) {
            const cJSON *uri = cJSON_GetObjectItemCaseSensitive(e, "uri");
            if (cJSON_IsString(uri) && strncmp(uri->valuestring, "data:", 5) == 0) {
                const char *comma = strchr(uri->valuestring, ',');
                if (!comma) return fail(im, "%s[%d].uri: a data: URI without a comma before its data", arrays[a], i);
                if (comma - uri->valuestring > DATA_URI_MAX_HEADER)
                    return fail(im, "%s[%d].uri: the data: URI's header (media type and encoding, before the comma) "
                                    "is %td characters; at most %d are read",
                                arrays[a], i, comma - uri->valuestring, DATA_URI_MAX_HEADER);
                long bad = strstr(uri->valuestring, ";base64") ? base64_fault(comma + 1) : -1;
                if (bad >= 0)
                    return fail(im, "%s[%d].uri: the data: URI's base64 is not base64 from its byte %ld on (0x%02x)",
                                arrays[a], i, bad, (unsigned char)comma[1 + bad]);
            }
            i++;
        }
    }
    return 0;
}

/* Bytes of buffer i (GLB BIN chunk, data: URI or bundle file). */
static const uint8_t *gltf_buffer(importer *im, int i, size_t *len) {
    const cJSON *bufs = cJSON_GetObjectItemCaseSensitive(im->gltf, "buffers");
    const cJSON *bf = cJSON_GetArrayItem(bufs, i);
    char field[64];
    snprintf(field, sizeof field, "buffers[%d]", i);
    if (!cJSON_IsObject(bf)) {
        fail(im, "%s: no such buffer", field);
        return NULL;
    }
    const cJSON *uri = cJSON_GetObjectItemCaseSensitive(bf, "uri");
    if (!cJSON_IsString(uri)) {
        if (!im->bin) fail(im, "%s: no uri and no GLB BIN chunk", field);
        *len = im->bin_len;
        return (const uint8_t *)im->bin;
    }
    if (strncmp(uri->valuestring, "data:", 5) != 0) {
        char f2[80];
        snprintf(f2, sizeof f2, "%s.uri", field);
        return (const uint8_t *)referenced_file(im, uri->valuestring, 1, len, f2);
    }
    if (!im->buffers) {
        int n = cJSON_GetArraySize(bufs);
        im->buffers = calloc((size_t)n + 1, sizeof *im->buffers);
        im->buffer_lens = calloc((size_t)n + 1, sizeof *im->buffer_lens);
        im->buffer_count = n;
        if (!im->buffers || !im->buffer_lens) {
            fail(im, "out of memory");
            return NULL;
        }
    }
    if (!im->buffers[i]) im->buffers[i] = data_uri(uri->valuestring, &im->buffer_lens[i]);
    if (!im->buffers[i]) fail(im, "%s.uri: not a base64 data: URI", field);
    *len = im->buffer_lens[i];
    return im->buffers[i];
}

/* Bytes of image i: a uri (file or data:) or a bufferView. */
static const uint8_t *gltf_image(importer *im, int i, size_t *len, uint8_t **owned) {
    const cJSON *img = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(im->gltf, "images"), i);
    char field[64];
    snprintf(field, sizeof field, "images[%d]", i);
    *owned = NULL;
    if (!cJSON_IsObject(img)) {
        fail(im, "%s: no such image", field);
        return NULL;
    }
    const cJSON *uri = cJSON_GetObjectItemCaseSensitive(img, "uri");
    if (cJSON_IsString(uri)) {
        if (strncmp(uri->valuestring, "data:", 5) == 0) {
            *owned = data_uri(uri->valuestring, len);
            if (!*owned) fail(im, "%s.uri: not a base64 data: URI", field);
            return *owned;
        }
        char f2[80];
        snprintf(f2, sizeof f2, "%s.uri", field);
        return (const uint8_t *)referenced_file(im, uri->valuestring, 1, len, f2);
    }
    const cJSON *bv = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(im->gltf, "bufferViews"),
                                         int_or(img, "bufferView", -1));
    if (!cJSON_IsObject(bv)) {
        fail(im, "%s: neither a uri nor a valid bufferView", field);
        return NULL;
    }
    size_t blen;
    const uint8_t *buf = gltf_buffer(im, int_or(bv, "buffer", -1), &blen);
    if (!buf) return NULL;
    double off = num_or(bv, "byteOffset", 0), n = num_or(bv, "byteLength", -1);
    if (!(off >= 0 && n >= 0 && off + n <= (double)blen)) {
        fail(im, "%s: bufferView [%g, %g) lies outside its buffer of %zu bytes", field, off, off + n, blen);
        return NULL;
    }
    *len = (size_t)n;
    return buf + (size_t)off;
}

/* Components per element of an accessor type, 0 if unknown. */
static int type_components(const char *t) {
    static const struct {
        const char *name;
        int n;
    } types[] = {{"SCALAR", 1}, {"VEC2", 2}, {"VEC3", 3}, {"VEC4", 4}, {"MAT2", 4}, {"MAT3", 9}, {"MAT4", 16}};
    for (size_t i = 0; i < sizeof types / sizeof types[0]; i++)
        if (strcmp(t, types[i].name) == 0) return types[i].n;
    return 0;
}

static int component_size(int ct) {
    switch (ct) {
    case 5120: case 5121: return 1;
    case 5122: case 5123: return 2;
    case 5125: case 5126: return 4;
    default: return 0;
    }
}

/* Every buffer holds at least its declared byteLength; every bufferView
 * lies inside its buffer; every accessor inside its bufferView. */
static int check_buffers_and_accessors(importer *im) {
    const cJSON *bufs = cJSON_GetObjectItemCaseSensitive(im->gltf, "buffers");
    const cJSON *views = cJSON_GetObjectItemCaseSensitive(im->gltf, "bufferViews");
    int nb = cJSON_GetArraySize(bufs), i = 0;
    const cJSON *e;
    for (i = 0; i < nb; i++) {
        size_t len;
        double declared = num_or(cJSON_GetArrayItem(bufs, i), "byteLength", -1);
        if (!gltf_buffer(im, i, &len)) return -1;
        if (!(declared >= 0) || declared > (double)len)
            return fail(im, "buffers[%d]: byteLength %g but the data has %zu bytes", i, declared, len);
    }
    i = 0;
    cJSON_ArrayForEach(e, views) {
        double b = num_or(e, "buffer", -1), off = num_or(e, "byteOffset", 0), n = num_or(e, "byteLength", -1);
        if (!(b >= 0 && b < nb) || !(off >= 0 && n >= 0) ||
            off + n > num_or(cJSON_GetArrayItem(bufs, (int)b), "byteLength", -1))
            return fail(im, "bufferViews[%d]: not inside buffer %g", i, b);
        i++;
    }
    i = 0;
    cJSON_ArrayForEach(e, cJSON_GetObjectItemCaseSensitive(im->gltf, "accessors")) {
        const cJSON *type = cJSON_GetObjectItemCaseSensitive(e, "type");
        int ct = int_or(e, "componentType", 0), nc = cJSON_IsString(type) ? type_components(type->valuestring) : 0;
        double count = num_or(e, "count", -1), off = num_or(e, "byteOffset", 0);
        if (!component_size(ct) || !nc)
            return fail(im, "accessors[%d]: bad componentType %g or type", i, num_or(e, "componentType", 0));
        if (!(count >= 1 && count <= 4294967295.0 && count == floor(count)))
            return fail(im, "accessors[%d]: bad count %g", i, count);
        const cJSON *bvj = cJSON_GetObjectItemCaseSensitive(e, "bufferView");
        if (bvj) {
            const cJSON *bv = cJSON_GetArrayItem(views, int_or(e, "bufferView", -1));
            if (!cJSON_IsNumber(bvj) || !bv) return fail(im, "accessors[%d].bufferView: no such bufferView", i);
            double elem = (double)component_size(ct) * nc, stride = num_or(bv, "byteStride", elem);
            if (!(off >= 0) || stride < elem || off + stride * (count - 1) + elem > num_or(bv, "byteLength", -1))
                return fail(im, "accessors[%d]: %g elements of %g bytes from offset %g overrun bufferView %g "
                                "(%g bytes)", i, count, elem, off, num_or(e, "bufferView", -1), num_or(bv, "byteLength", -1));
        }
        i++;
    }
    return 0;
}

/* Each primitive's attributes have the types the glTF spec allows. */
static int check_primitives(importer *im) {
    const cJSON *accs = cJSON_GetObjectItemCaseSensitive(im->gltf, "accessors"), *mesh;
    int mi = 0;
    cJSON_ArrayForEach(mesh, cJSON_GetObjectItemCaseSensitive(im->gltf, "meshes")) {
        const cJSON *prim;
        int pi = 0;
        cJSON_ArrayForEach(prim, cJSON_GetObjectItemCaseSensitive(mesh, "primitives")) {
            const cJSON *attrs = cJSON_GetObjectItemCaseSensitive(prim, "attributes"), *a;
            if (ext_of(prim, "KHR_draco_mesh_compression"))
                return fail(im, "meshes[%d].primitives[%d]: Draco-compressed (KHR_draco_mesh_compression), not "
                                "supported; export without mesh compression", mi, pi);
            if (!cJSON_GetObjectItemCaseSensitive(attrs, "POSITION"))
                return fail(im, "meshes[%d].primitives[%d]: no POSITION attribute", mi, pi);
            cJSON_ArrayForEach(a, attrs) {
                const cJSON *acc = cJSON_GetArrayItem(accs, cJSON_IsNumber(a) ? a->valueint : -1);
                if (!acc) return fail(im, "meshes[%d].primitives[%d].attributes.%s: no such accessor", mi, pi, a->string);
                int ct = int_or(acc, "componentType", 0);
                const cJSON *t = cJSON_GetObjectItemCaseSensitive(acc, "type");
                const char *ts = cJSON_IsString(t) ? t->valuestring : "";
                int need_vec3_float = strcmp(a->string, "POSITION") == 0 || strcmp(a->string, "NORMAL") == 0;
                int is_uv = strncmp(a->string, "TEXCOORD_", 9) == 0;
                if ((need_vec3_float && (ct != 5126 || strcmp(ts, "VEC3") != 0)) ||
                    (is_uv && (strcmp(ts, "VEC2") != 0 || (ct != 5126 && ct != 5121 && ct != 5123))))
                    return fail(im, "meshes[%d].primitives[%d].attributes.%s: accessor of %s componentType %d is "
                                    "not allowed here", mi, pi, a->string, ts, ct);
            }
            const cJSON *ij = cJSON_GetObjectItemCaseSensitive(prim, "indices");
            if (ij) {
                const cJSON *acc = cJSON_GetArrayItem(accs, cJSON_IsNumber(ij) ? ij->valueint : -1);
                const cJSON *t = cJSON_GetObjectItemCaseSensitive(acc, "type");
                int ct = int_or(acc, "componentType", 0);
                if (!acc || !cJSON_IsString(t) || strcmp(t->valuestring, "SCALAR") != 0 ||
                    (ct != 5121 && ct != 5123 && ct != 5125))
                    return fail(im, "meshes[%d].primitives[%d].indices: must be a SCALAR accessor of unsigned "
                                    "byte, short or int (componentType %d)", mi, pi, ct);
            }
            pi++;
        }
        mi++;
    }
    return 0;
}

static texture_wrap wrap_of(double gl) {
    return gl == 33071 ? WRAP_CLAMP : gl == 33648 ? WRAP_MIRROR : WRAP_REPEAT;
}

/* Decode texture ti of the glTF (once per colour space): returns its slot
 * + 1 in m->textures, or 0 with the error set. */
static uint32_t gltf_texture(importer *im, int ti, int srgb, const char *field) {
    const cJSON *texs = cJSON_GetObjectItemCaseSensitive(im->gltf, "textures");
    const cJSON *t = cJSON_GetArrayItem(texs, ti);
    if (ti < 0 || !cJSON_IsObject(t)) {
        fail(im, "%s.index: no texture %d", field, ti);
        return 0;
    }
    if (!im->tex_slot) {
        im->tex_slot_count = 2 * cJSON_GetArraySize(texs);
        im->tex_slot = calloc((size_t)im->tex_slot_count + 1, sizeof(int));
        if (!im->tex_slot) {
            fail(im, "out of memory");
            return 0;
        }
    }
    if (im->tex_slot[2 * ti + srgb]) return (uint32_t)im->tex_slot[2 * ti + srgb];
    uint8_t *owned;
    size_t len;
    const cJSON *src = cJSON_GetObjectItemCaseSensitive(t, "source");
    if (!cJSON_IsNumber(src)) {
        fail(im, "textures[%d]: no source image (only PNG and JPEG images are supported)", ti);
        return 0;
    }
    const uint8_t *data = gltf_image(im, src->valueint, &len, &owned);
    if (!data) return 0;
    texture *nt = realloc(im->m->textures, (im->m->texture_count + 1) * sizeof *nt);
    if (!nt) {
        free(owned);
        fail(im, "out of memory");
        return 0;
    }
    im->m->textures = nt;
    char what[96], e2[512];
    snprintf(what, sizeof what, "images[%d]", src->valueint);
    texture *tx = &nt[im->m->texture_count];
    int rc = texture_decode(data, len, what, tx, e2, sizeof e2);
    free(owned);
    if (rc) {
        fail(im, "%s", e2);
        return 0;
    }
    tx->srgb = srgb;
    const cJSON *smp = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(im->gltf, "samplers"),
                                          int_or(t, "sampler", -1));
    tx->wrap_s = wrap_of(num_or(smp, "wrapS", 10497));
    tx->wrap_t = wrap_of(num_or(smp, "wrapT", 10497));
    im->m->texture_count++;
    im->tex_slot[2 * ti + srgb] = (int)im->m->texture_count;
    return im->m->texture_count;
}

/* A textureInfo field: 0 when absent, else slot + 1; -1 on error. */
static long texinfo(importer *im, const cJSON *info, int srgb, const char *field) {
    if (!info) return 0;
    if (num_or(info, "texCoord", 0) != 0)
        fprintf(stderr, "warning: %s: %s uses TEXCOORD_%g; TEXCOORD_0 is used instead\n", im->name, field,
                num_or(info, "texCoord", 0));
    uint32_t slot = gltf_texture(im, int_or(info, "index", -1), srgb, field);
    return slot ? (long)slot : -1;
}

static void texture_transform(const cJSON *info, material *m) {
    const cJSON *x = ext_of(info, "KHR_texture_transform");
    if (!x) return;
    const cJSON *off = cJSON_GetObjectItemCaseSensitive(x, "offset"), *sc = cJSON_GetObjectItemCaseSensitive(x, "scale");
    double ox = 0, oy = 0, sx = 1, sy = 1, r = num_or(x, "rotation", 0);
    if (cJSON_IsArray(off) && cJSON_GetArraySize(off) == 2) {
        ox = cJSON_GetArrayItem(off, 0)->valuedouble;
        oy = cJSON_GetArrayItem(off, 1)->valuedouble;
    }
    if (cJSON_IsArray(sc) && cJSON_GetArraySize(sc) == 2) {
        sx = cJSON_GetArrayItem(sc, 0)->valuedouble;
        sy = cJSON_GetArrayItem(sc, 1)->valuedouble;
    }
    /* uv' = T(offset) R(rotation) S(scale) uv, as KHR_texture_transform defines. */
    double c = cos(r), s = sin(r);
    float M[6] = {(float)(c * sx), (float)(s * sy), (float)ox, (float)(-s * sx), (float)(c * sy), (float)oy};
    memcpy(m->uv_xform, M, sizeof M);
    m->has_uv_xform = 1;
}

/* Mean linear colour of a texture (emissive textures: see gltf_material). */
static vec3 texture_mean(const texture *t) {
    double sum[3] = {0, 0, 0};
    size_t n = (size_t)t->width * (size_t)t->height;
    for (size_t i = 0; i < n; i++)
        for (int c = 0; c < 3; c++) sum[c] += texture_srgb_to_linear(t->rgba[4 * i + c]);
    return vec3_make((float)(sum[0] / n), (float)(sum[1] / n), (float)(sum[2] / n));
}

static int gltf_material(importer *im, const cJSON *mj, int index, import_material *out) {
    char field[64];
    snprintf(field, sizeof field, "materials[%d]", index);
    material *m = &out->mat;
    memset(out, 0, sizeof *out);
    m->kind = MATERIAL_PBR;
    const cJSON *pbr = cJSON_GetObjectItemCaseSensitive(mj, "pbrMetallicRoughness");
    const cJSON *bcf = cJSON_GetObjectItemCaseSensitive(pbr, "baseColorFactor");
    float bc[4] = {1, 1, 1, 1};
    for (int k = 0; k < 4; k++)
        if (cJSON_IsArray(bcf) && cJSON_IsNumber(cJSON_GetArrayItem(bcf, k)))
            bc[k] = (float)fmin(fmax(cJSON_GetArrayItem(bcf, k)->valuedouble, 0), 1);
    m->base_color = vec3_make(bc[0], bc[1], bc[2]);
    m->base_alpha = bc[3];
    m->metallic = (float)fmin(fmax(num_or(pbr, "metallicFactor", 1), 0), 1);
    m->roughness = (float)fmin(fmax(num_or(pbr, "roughnessFactor", 1), 0), 1);
    char f2[128];
    snprintf(f2, sizeof f2, "%s.pbrMetallicRoughness.baseColorTexture", field);
    const cJSON *bct = cJSON_GetObjectItemCaseSensitive(pbr, "baseColorTexture");
    long t = texinfo(im, bct, 1, f2);
    if (t < 0) return -1;
    m->tex_base = (uint32_t)t;
    texture_transform(bct, m);
    snprintf(f2, sizeof f2, "%s.pbrMetallicRoughness.metallicRoughnessTexture", field);
    if ((t = texinfo(im, cJSON_GetObjectItemCaseSensitive(pbr, "metallicRoughnessTexture"), 0, f2)) < 0) return -1;
    m->tex_mr = (uint32_t)t;
    const cJSON *nt = cJSON_GetObjectItemCaseSensitive(mj, "normalTexture");
    snprintf(f2, sizeof f2, "%s.normalTexture", field);
    if ((t = texinfo(im, nt, 0, f2)) < 0) return -1;
    m->tex_normal = (uint32_t)t;
    m->normal_scale = (float)num_or(nt, "scale", 1);
    const cJSON *am = cJSON_GetObjectItemCaseSensitive(mj, "alphaMode");
    if (cJSON_IsString(am) && strcmp(am->valuestring, "MASK") == 0)
        m->alpha_cutoff = (float)fmax(num_or(mj, "alphaCutoff", 0.5), 1e-6);
    else if (cJSON_IsString(am) && strcmp(am->valuestring, "BLEND") == 0)
        fprintf(stderr, "warning: %s: %s: alphaMode BLEND is rendered opaque\n", im->name, field);
    out->double_sided = cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(mj, "doubleSided"));
    /* Emission: factor x KHR_materials_emissive_strength; an emissive texture
     * scales it by its mean colour (lights have one radiance per triangle). */
    const cJSON *ef = cJSON_GetObjectItemCaseSensitive(mj, "emissiveFactor");
    double e[3] = {0, 0, 0}, strength = num_or(ext_of(mj, "KHR_materials_emissive_strength"), "emissiveStrength", 1);
    for (int k = 0; k < 3 && cJSON_IsArray(ef); k++)
        if (cJSON_IsNumber(cJSON_GetArrayItem(ef, k))) e[k] = fmax(0, cJSON_GetArrayItem(ef, k)->valuedouble);
    out->emission = vec3_scale(vec3_make((float)e[0], (float)e[1], (float)e[2]), (float)fmax(strength, 0));
    const cJSON *et = cJSON_GetObjectItemCaseSensitive(mj, "emissiveTexture");
    if (et && !vec3_is_zero(out->emission)) {
        snprintf(f2, sizeof f2, "%s.emissiveTexture", field);
        if ((t = texinfo(im, et, 1, f2)) < 0) return -1;
        out->emission = vec3_mul(out->emission, texture_mean(&im->m->textures[t - 1]));
    }
    /* Transmission onto the smooth dielectric, where it dominates. */
    double tr = num_or(ext_of(mj, "KHR_materials_transmission"), "transmissionFactor", 0);
    double ior = num_or(ext_of(mj, "KHR_materials_ior"), "ior", 1.5);
    if (tr >= 0.5 && m->metallic < 0.5) {
        m->kind = MATERIAL_GLASS;
        m->ior = (float)fmin(fmax(ior, 1.0001), 10);
        m->kt = m->base_color;
    }
    return 0;
}

/* ---- node transforms (glTF JSON, for cameras and lights) ----------------- */

/* Column-major 4x4 as glTF stores it. */
static void mat_mul(const double a[16], const double b[16], double o[16]) {
    double r[16];
    for (int c = 0; c < 4; c++)
        for (int rr = 0; rr < 4; rr++) {
            double s = 0;
            for (int k = 0; k < 4; k++) s += a[k * 4 + rr] * b[c * 4 + k];
            r[c * 4 + rr] = s;
        }
    memcpy(o, r, sizeof r);
}

static void node_local(const cJSON *node, double m[16]) {
    const cJSON *mat = cJSON_GetObjectItemCaseSensitive(node, "matrix");
    static const double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    memcpy(m, id, sizeof id);
    if (cJSON_IsArray(mat) && cJSON_GetArraySize(mat) == 16) {
        int k = 0;
        const cJSON *v;
        cJSON_ArrayForEach(v, mat) m[k++] = cJSON_IsNumber(v) ? v->valuedouble : 0;
        return;
    }
    double t[3] = {0, 0, 0}, q[4] = {0, 0, 0, 1}, s[3] = {1, 1, 1};
    const cJSON *a;
    if (cJSON_IsArray(a = cJSON_GetObjectItemCaseSensitive(node, "translation")) && cJSON_GetArraySize(a) == 3)
        for (int k = 0; k < 3; k++) t[k] = cJSON_GetArrayItem(a, k)->valuedouble;
    if (cJSON_IsArray(a = cJSON_GetObjectItemCaseSensitive(node, "rotation")) && cJSON_GetArraySize(a) == 4)
        for (int k = 0; k < 4; k++) q[k] = cJSON_GetArrayItem(a, k)->valuedouble;
    if (cJSON_IsArray(a = cJSON_GetObjectItemCaseSensitive(node, "scale")) && cJSON_GetArraySize(a) == 3)
        for (int k = 0; k < 3; k++) s[k] = cJSON_GetArrayItem(a, k)->valuedouble;
    double x = q[0], y = q[1], z = q[2], w = q[3];
    double R[9] = {1 - 2 * (y * y + z * z), 2 * (x * y + z * w),     2 * (x * z - y * w),
                   2 * (x * y - z * w),     1 - 2 * (x * x + z * z), 2 * (y * z + x * w),
                   2 * (x * z + y * w),     2 * (y * z - x * w),     1 - 2 * (x * x + y * y)}; /* columns */
    for (int c = 0; c < 3; c++)
        for (int r = 0; r < 3; r++) m[c * 4 + r] = R[c * 3 + r] * s[c];
    for (int r = 0; r < 3; r++) m[12 + r] = t[r];
}

static void xform_point(const double m[16], const double p[3], double o[3]) {
    for (int r = 0; r < 3; r++) o[r] = m[r] * p[0] + m[4 + r] * p[1] + m[8 + r] * p[2] + m[12 + r];
}
static void xform_dir(const double m[16], const double d[3], double o[3]) {
    for (int r = 0; r < 3; r++) o[r] = m[r] * d[0] + m[4 + r] * d[1] + m[8 + r] * d[2];
    double l = sqrt(o[0] * o[0] + o[1] * o[1] + o[2] * o[2]);
    for (int r = 0; r < 3 && l > 0; r++) o[r] /= l;
}

/* The caller's rotation of a direction (normals, light and camera axes). */
static void user_dir(const import_options *opt, double d[3]) {
    if (!opt->has_rotate) return;
    const double *R = opt->rotate;
    double o[3];
    for (int r = 0; r < 3; r++) o[r] = R[3 * r] * d[0] + R[3 * r + 1] * d[1] + R[3 * r + 2] * d[2];
    memcpy(d, o, sizeof o);
}

static void user_point(const import_options *opt, double p[3]) {
    user_dir(opt, p);
    for (int k = 0; k < 3; k++) p[k] = p[k] * opt->scale + opt->translate[k];
}

static int push_light(importer *im, const cJSON *lj, const double M[16]) {
    import_light *nl = realloc(im->m->lights, (im->m->light_count + 1) * sizeof *nl);
    if (!nl) return fail(im, "out of memory");
    im->m->lights = nl;
    import_light *l = &nl[im->m->light_count];
    memset(l, 0, sizeof *l);
    const cJSON *type = cJSON_GetObjectItemCaseSensitive(lj, "type"), *col = cJSON_GetObjectItemCaseSensitive(lj, "color");
    double c[3] = {1, 1, 1}, I = fmax(0, num_or(lj, "intensity", 1));
    for (int k = 0; k < 3 && cJSON_IsArray(col); k++)
        if (cJSON_IsNumber(cJSON_GetArrayItem(col, k))) c[k] = fmax(0, cJSON_GetArrayItem(col, k)->valuedouble);
    static const double o[3] = {0, 0, 0}, down[3] = {0, 0, -1};
    xform_point(M, o, l->position);
    user_point(im->opt, l->position);
    xform_dir(M, down, l->direction);
    user_dir(im->opt, l->direction);
    l->intensity = vec3_make((float)(c[0] * I), (float)(c[1] * I), (float)(c[2] * I));
    const char *t = cJSON_IsString(type) ? type->valuestring : "";
    if (strcmp(t, "point") == 0) {
        l->kind = LIGHT_POINT;
    } else if (strcmp(t, "spot") == 0) {
        const cJSON *sp = cJSON_GetObjectItemCaseSensitive(lj, "spot");
        l->kind = LIGHT_SPOT;
        l->cos_inner = (float)cos(num_or(sp, "innerConeAngle", 0));
        l->cos_outer = (float)cos(num_or(sp, "outerConeAngle", M_PI / 4));
    } else if (strcmp(t, "directional") == 0) {
        l->kind = LIGHT_DIRECTIONAL;
    } else {
        return fail(im, "KHR_lights_punctual: unknown light type \"%s\"", t);
    }
    /* Photometric (cd, lux) to radiometric (W/sr, W/m^2) at 683 lm/W, the
     * factor Blender's exporter multiplies by; and a model scaled by s keeps
     * its picture when point and spot intensities scale by s^2. */
    double scale2 = l->kind == LIGHT_DIRECTIONAL ? 1 : im->opt->scale * im->opt->scale;
    l->intensity = vec3_scale(l->intensity, (float)(scale2 / IMPORT_LUMENS_PER_WATT));
    if (!vec3_is_zero(l->intensity)) im->m->light_count++;
    return 0;
}

static int camera_matches(const cJSON *node, const cJSON *cam, const char *want) {
    if (!want) return 1;
    const cJSON *a = cJSON_GetObjectItemCaseSensitive(node, "name"), *b = cJSON_GetObjectItemCaseSensitive(cam, "name");
    return (cJSON_IsString(a) && strcmp(a->valuestring, want) == 0) ||
           (cJSON_IsString(b) && strcmp(b->valuestring, want) == 0);
}

static int walk_node(importer *im, int ni, const double parent[16], int depth) {
    const cJSON *nodes = cJSON_GetObjectItemCaseSensitive(im->gltf, "nodes");
    const cJSON *node = cJSON_GetArrayItem(nodes, ni);
    if (!cJSON_IsObject(node)) return fail(im, "nodes[%d]: no such node", ni);
    if (depth > 256 || ++im->visits > MAX_NODE_VISITS) return fail(im, "nodes: the hierarchy has a cycle or is too deep");
    double local[16], M[16];
    node_local(node, local);
    mat_mul(parent, local, M);
    const cJSON *cam = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(im->gltf, "cameras"),
                                          int_or(node, "camera", -1));
    import_camera *c = &im->m->camera;
    if (cam && !c->present && camera_matches(node, cam, im->opt->camera)) {
        const cJSON *type = cJSON_GetObjectItemCaseSensitive(cam, "type");
        const cJSON *nm = cJSON_GetObjectItemCaseSensitive(node, "name");
        if (!cJSON_IsString(type) || strcmp(type->valuestring, "perspective") != 0)
            return fail(im, "cameras[%g]: only perspective cameras are supported", num_or(node, "camera", -1));
        const cJSON *p = cJSON_GetObjectItemCaseSensitive(cam, "perspective");
        static const double o[3] = {0, 0, 0}, fwd[3] = {0, 0, -1}, up[3] = {0, 1, 0};
        c->present = 1;
        snprintf(c->name, sizeof c->name, "%s", cJSON_IsString(nm) ? nm->valuestring : "");
        xform_point(M, o, c->position);
        user_point(im->opt, c->position);
        xform_dir(M, fwd, c->forward);
        xform_dir(M, up, c->up);
        user_dir(im->opt, c->forward);
        user_dir(im->opt, c->up);
        c->yfov = num_or(p, "yfov", 0.8);
        c->aspect = num_or(p, "aspectRatio", 0);
    }
    const cJSON *lr = ext_of(node, "KHR_lights_punctual");
    if (lr) {
        const cJSON *lights = cJSON_GetObjectItemCaseSensitive(ext_of(im->gltf, "KHR_lights_punctual"), "lights");
        const cJSON *lj = cJSON_GetArrayItem(lights, int_or(lr, "light", -1));
        if (!cJSON_IsObject(lj)) return fail(im, "nodes[%d]: KHR_lights_punctual.light: no such light", ni);
        if (push_light(im, lj, M)) return -1;
    }
    const cJSON *ch;
    cJSON_ArrayForEach(ch, cJSON_GetObjectItemCaseSensitive(node, "children")) {
        if (!cJSON_IsNumber(ch)) return fail(im, "nodes[%d].children: expected node indices", ni);
        if (walk_node(im, ch->valueint, M, depth + 1)) return -1;
    }
    return 0;
}

static int gltf_nodes(importer *im) {
    static const double id[16] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1};
    const cJSON *scenes = cJSON_GetObjectItemCaseSensitive(im->gltf, "scenes");
    const cJSON *sc = cJSON_GetArrayItem(scenes, int_or(im->gltf, "scene", 0)), *n;
    cJSON_ArrayForEach(n, cJSON_GetObjectItemCaseSensitive(sc, "nodes")) {
        if (!cJSON_IsNumber(n)) return fail(im, "scenes: expected node indices");
        if (walk_node(im, n->valueint, id, 0)) return -1;
    }
    if (im->opt->camera && !im->m->camera.present) return fail(im, "no camera named \"%s\"", im->opt->camera);
    return 0;
}

/* ---- OBJ materials through Assimp ---------------------------------------- */

static vec3 ai_color(const struct aiMaterial *am, const char *key, vec3 dflt) {
    struct aiColor4D c;
    if (aiGetMaterialColor(am, key, 0, 0, &c) != AI_SUCCESS) return dflt;
    return vec3_make(fmaxf(0, c.r), fmaxf(0, c.g), fmaxf(0, c.b));
}

static float ai_float(const struct aiMaterial *am, const char *key, float dflt) {
    ai_real v;
    unsigned int n = 1;
    if (aiGetMaterialFloatArray(am, key, 0, 0, &v, &n) != AI_SUCCESS || n < 1 || !isfinite(v)) return dflt;
    return (float)v;
}

static int obj_material(importer *im, const struct aiMaterial *am, int index, import_material *out) {
    memset(out, 0, sizeof *out);
    material *m = &out->mat;
    vec3 kd = ai_color(am, "$clr.diffuse", vec3_splat(0.8f)), ks = ai_color(am, "$clr.specular", vec3_splat(0));
    float ns = ai_float(am, "$mat.shininess", 0), d = ai_float(am, "$mat.opacity", 1), ni = ai_float(am, "$mat.refracti", 1.5f);
    out->emission = ai_color(am, "$clr.emissive", vec3_splat(0));
    if (d < 0.5f) { /* mostly transparent (d, or Tr = 1 - d): the smooth dielectric */
        m->kind = MATERIAL_GLASS;
        m->ior = ni > 1.0001f ? fminf(ni, 10) : 1.5f;
        m->kt = vec3_splat(1);
        return 0;
    }
    kd = vec3_min(kd, vec3_splat(1));
    ks = vec3_min(ks, vec3_splat(1));
    if (!vec3_is_zero(ks) && ns > 0) { /* keep kd + ks <= 1, as the JSON format requires */
        m->kind = MATERIAL_GLOSSY;
        float worst = vec3_max_comp(vec3_add(kd, ks));
        if (worst > 1) {
            kd = vec3_scale(kd, 1 / worst);
            ks = vec3_scale(ks, 1 / worst);
        }
        m->exponent = fminf(ns, 1e6f);
        float sd = vec3_luminance(kd), ss = vec3_luminance(ks);
        m->p_specular = sd + ss > 0 ? ss / (sd + ss) : 0;
    } else {
        m->kind = MATERIAL_DIFFUSE;
    }
    m->kd = kd;
    m->ks = ks;
    struct aiString path;
    if (aiGetMaterialTexture(am, aiTextureType_DIFFUSE, 0, &path, NULL, NULL, NULL, NULL, NULL, NULL) == AI_SUCCESS &&
        path.length > 0) {
        char field[64];
        size_t len;
        snprintf(field, sizeof field, "material %d map_Kd", index);
        const char *data = referenced_file(im, path.data, 0, &len, field);
        if (!data) return -1;
        texture *nt = realloc(im->m->textures, (im->m->texture_count + 1) * sizeof *nt);
        if (!nt) return fail(im, "out of memory");
        im->m->textures = nt;
        char e2[512];
        if (texture_decode((const uint8_t *)data, len, path.data, &nt[im->m->texture_count], e2, sizeof e2))
            return fail(im, "%s", e2);
        nt[im->m->texture_count].srgb = 1;
        m->tex_base = ++im->m->texture_count;
    }
    return 0;
}

/* ---- geometry from Assimp ----------------------------------------------- */

static int grow_tris(importer *im, size_t more) {
    import_model *m = im->m;
    if (m->tri_count + more <= im->tri_cap) return 0;
    size_t cap = im->tri_cap ? im->tri_cap : 1024;
    while (cap < m->tri_count + more) cap *= 2;
    double *p = realloc(m->positions, cap * 9 * sizeof *p);
    if (p) m->positions = p;
    uint32_t *n = realloc(m->normal_indices, cap * 3 * sizeof *n);
    if (n) m->normal_indices = n;
    float *uv = realloc(m->uvs, cap * 6 * sizeof *uv);
    if (uv) m->uvs = uv;
    uint8_t *f = realloc(m->flags, cap);
    if (f) m->flags = f;
    uint32_t *mt = realloc(m->material, cap * sizeof *mt);
    if (mt) m->material = mt;
    if (!p || !n || !uv || !f || !mt) return fail(im, "out of memory for %zu triangles", cap);
    im->tri_cap = cap;
    return 0;
}

/* Hash of a normal's bits (for normal_index's set). */
static uint64_t normal_hash(const float n[3]) {
    uint32_t b[3];
    memcpy(b, n, sizeof b);
    return rng_mix64((((uint64_t)b[0] << 32) | b[1]) ^ (uint64_t)b[2] * 0x9E3779B97F4A7C15ull);
}

/* Make room for one more normal in m->normals and its hash set (rehashed
 * when half full). Returns 0, or -1 (with the error set) out of memory. */
static int grow_normals(importer *im) {
    import_model *m = im->m;
    if (m->normal_count == im->normal_cap) {
        size_t cap = im->normal_cap ? 2 * im->normal_cap : 1024;
        float *p = cap < UINT32_MAX ? realloc(m->normals, cap * 3 * sizeof *p) : NULL;
        if (!p) return fail(im, "out of memory for %zu normals", cap);
        m->normals = p;
        im->normal_cap = cap;
    }
    if (2 * (m->normal_count + 1) <= im->slot_cap) return 0;
    size_t cap = im->slot_cap ? 2 * im->slot_cap : 2048;
    uint32_t *slots = calloc(cap, sizeof *slots);
    if (!slots) return fail(im, "out of memory for %zu normals", m->normal_count);
    for (size_t i = 0; i < m->normal_count; i++) {
        size_t k = normal_hash(&m->normals[3 * i]) & (cap - 1);
        while (slots[k]) k = (k + 1) & (cap - 1);
        slots[k] = (uint32_t)i + 1;
    }
    free(im->normal_slots);
    im->normal_slots = slots;
    im->slot_cap = cap;
    return 0;
}

/* Index of normal n in m->normals, appended when no equal one (bit for bit)
 * is there yet: corners share their normals as the mesh's vertices do, also
 * where the file repeats a vertex per face (OBJ through Assimp, flat glTF)
 * and across meshes and instances. Returns 0 with *idx set, or -1 (error
 * set) out of memory. */
static int normal_index(importer *im, const float n[3], uint32_t *idx) {
    if (grow_normals(im)) return -1;
    import_model *m = im->m;
    size_t k = normal_hash(n) & (im->slot_cap - 1);
    for (; im->normal_slots[k]; k = (k + 1) & (im->slot_cap - 1))
        if (memcmp(&m->normals[3 * (size_t)(im->normal_slots[k] - 1)], n, 3 * sizeof *n) == 0) {
            *idx = im->normal_slots[k] - 1;
            return 0;
        }
    *idx = (uint32_t)m->normal_count;
    memcpy(&m->normals[3 * m->normal_count++], n, 3 * sizeof *n);
    im->normal_slots[k] = *idx + 1;
    return 0;
}

#define NORMAL_UNSET UINT32_MAX    /* add_faces' vertex cache: not computed yet */
#define NORMAL_BAD (UINT32_MAX - 1) /* the vertex's normal has no direction */

/* Vertex vi's normal, transformed by N (the cofactor matrix of the node
 * transform, whose determinant is det) and the caller's rotation, made
 * unit: its index into m->normals, computed on first use and kept in
 * vn[vi] (NORMAL_BAD when it has no direction). Returns 0, or -1 (error
 * set) out of memory. */
static int vertex_normal(importer *im, const struct aiMesh *mesh, unsigned vi, const double N[9], double det,
                         uint32_t *vn) {
    if (vn[vi] != NORMAL_UNSET) return 0;
    const struct aiVector3D *n = &mesh->mNormals[vi];
    double w[3];
    for (int r = 0; r < 3; r++) w[r] = N[3 * r] * n->x + N[3 * r + 1] * n->y + N[3 * r + 2] * n->z;
    user_dir(im->opt, w);
    double l = sqrt(w[0] * w[0] + w[1] * w[1] + w[2] * w[2]);
    if (!(l > 0) || !isfinite(l)) {
        vn[vi] = NORMAL_BAD;
        return 0;
    }
    float u[3];
    for (int r = 0; r < 3; r++) u[r] = (float)(w[r] / l * (det < 0 ? -1 : 1));
    return normal_index(im, u, &vn[vi]);
}

/* The triangles of mesh under node transform M (normals by N, det as in
 * vertex_normal; vn: its cache, NULL when the mesh has no normals). A
 * triangle keeps normals only when all three corners have one. Returns 0 or
 * -1 with the error set. */
static int add_faces(importer *im, const struct aiMesh *mesh, const double M[12], const double N[9], double det,
                     uint32_t *vn) {
    import_model *m = im->m;
    for (unsigned fi = 0; fi < mesh->mNumFaces; fi++) {
        const struct aiFace *face = &mesh->mFaces[fi];
        if (face->mNumIndices != 3) {
            if (face->mNumIndices < 3 && m->skipped_primitives++ == 0)
                fprintf(stderr, "warning: %s: mesh \"%s\" has points or lines (not triangles): skipped\n", im->name,
                        mesh->mName.data);
            continue;
        }
        size_t t = m->tri_count;
        int order[3] = {0, det < 0 ? 2 : 1, det < 0 ? 1 : 2};
        m->flags[t] = (vn ? 1 : 0) | (mesh->mTextureCoords[0] ? 2 : 0);
        for (int k = 0; k < 3; k++) {
            unsigned vi = face->mIndices[order[k]];
            if (vi >= mesh->mNumVertices)
                return fail(im, "mesh \"%s\": vertex index %u out of range (%u vertices)", mesh->mName.data, vi,
                            mesh->mNumVertices);
            const struct aiVector3D *v = &mesh->mVertices[vi];
            double p[3] = {v->x, v->y, v->z};
            double *o = &m->positions[9 * t + 3 * k];
            for (int r = 0; r < 3; r++) o[r] = M[4 * r] * p[0] + M[4 * r + 1] * p[1] + M[4 * r + 2] * p[2] + M[4 * r + 3];
            user_point(im->opt, o);
            for (int r = 0; r < 3; r++) {
                if (!isfinite(o[r])) return fail(im, "mesh \"%s\": a vertex is not finite", mesh->mName.data);
                if (fabs(o[r]) > SCENE_COORD_MAX)
                    return fail(im, "mesh \"%s\": a face's vertex lies at %c = %g, beyond +-%g (after the file's "
                                "transforms)", mesh->mName.data, "xyz"[r], o[r], SCENE_COORD_MAX);
            }
            if (vn) {
                if (vertex_normal(im, mesh, vi, N, det, vn)) return -1;
                if (vn[vi] == NORMAL_BAD) m->flags[t] &= (uint8_t)~1u;
                m->normal_indices[3 * t + k] = vn[vi];
            }
            if (mesh->mTextureCoords[0]) {
                const struct aiVector3D *uv = &mesh->mTextureCoords[0][vi];
                /* Assimp flips v for glTF and keeps OBJ's v (up); both are
                 * 1 - v in glTF's orientation. */
                m->uvs[6 * t + 2 * k] = uv->x;
                m->uvs[6 * t + 2 * k + 1] = 1.0f - uv->y;
            }
        }
        m->material[t] = mesh->mMaterialIndex;
        m->tri_count++;
    }
    return 0;
}

static int add_mesh(importer *im, const struct aiScene *sc, const struct aiMesh *mesh, const double M[12]) {
    if (mesh->mPrimitiveTypes & ~(unsigned)(aiPrimitiveType_TRIANGLE | aiPrimitiveType_POLYGON)) {
        if (!(mesh->mPrimitiveTypes & (aiPrimitiveType_TRIANGLE | aiPrimitiveType_POLYGON))) {
            if (im->m->skipped_primitives++ == 0)
                fprintf(stderr, "warning: %s: mesh \"%s\" has points or lines (not triangles): skipped\n", im->name,
                        mesh->mName.data);
            return 0;
        }
    }
    /* Normals transform by the inverse transpose; a mirroring transform
     * reverses the winding (glTF spec, "Transformations"). */
    double a = M[0], b = M[1], c = M[2], d = M[4], e = M[5], f = M[6], g = M[8], h = M[9], i = M[10];
    double det = a * (e * i - f * h) - b * (d * i - f * g) + c * (d * h - e * g);
    double N[9] = {e * i - f * h, f * g - d * i, d * h - e * g, c * h - b * i, a * i - c * g,
                   b * g - a * h, b * f - c * e, c * d - a * f, a * e - b * d}; /* cofactor matrix */
    if (mesh->mMaterialIndex >= sc->mNumMaterials) return fail(im, "mesh \"%s\": bad material index", mesh->mName.data);
    if (grow_tris(im, mesh->mNumFaces)) return -1;
    uint32_t *vn = NULL; /* each vertex's normal is transformed and looked up once */
    if (mesh->mNormals) {
        vn = malloc(((size_t)mesh->mNumVertices + 1) * sizeof *vn);
        if (!vn) return fail(im, "mesh \"%s\": out of memory for %u normals", mesh->mName.data, mesh->mNumVertices);
        memset(vn, 0xff, ((size_t)mesh->mNumVertices + 1) * sizeof *vn); /* NORMAL_UNSET */
    }
    int rc = add_faces(im, mesh, M, N, det, vn);
    free(vn);
    return rc;
}

static int walk_ai(importer *im, const struct aiScene *sc, const struct aiNode *node, const double parent[12], int depth) {
    if (depth > 256 || ++im->visits > MAX_NODE_VISITS) return fail(im, "nodes: the hierarchy is too deep");
    const struct aiMatrix4x4 *t = &node->mTransformation;
    double L[12] = {t->a1, t->a2, t->a3, t->a4, t->b1, t->b2, t->b3, t->b4, t->c1, t->c2, t->c3, t->c4}, M[12];
    for (int r = 0; r < 3; r++)
        for (int c = 0; c < 4; c++)
            M[4 * r + c] = parent[4 * r] * L[c] + parent[4 * r + 1] * L[4 + c] + parent[4 * r + 2] * L[8 + c] +
                           (c == 3 ? parent[4 * r + 3] : 0);
    for (unsigned k = 0; k < node->mNumMeshes; k++) {
        if (node->mMeshes[k] >= sc->mNumMeshes) return fail(im, "node \"%s\": bad mesh index", node->mName.data);
        if (add_mesh(im, sc, sc->mMeshes[node->mMeshes[k]], M)) return -1;
    }
    for (unsigned k = 0; k < node->mNumChildren; k++)
        if (walk_ai(im, sc, node->mChildren[k], M, depth + 1)) return -1;
    return 0;
}

static int materials_from(importer *im, const struct aiScene *sc) {
    import_model *m = im->m;
    m->materials = calloc(sc->mNumMaterials + 1, sizeof *m->materials);
    if (!m->materials) return fail(im, "out of memory");
    const cJSON *mats = im->gltf ? cJSON_GetObjectItemCaseSensitive(im->gltf, "materials") : NULL;
    int n = cJSON_GetArraySize(mats);
    for (unsigned i = 0; i < sc->mNumMaterials; i++) {
        import_material *out = &m->materials[i];
        if (im->gltf) {
            /* Assimp keeps glTF's order and appends its default material. */
            const cJSON *mj = (int)i < n ? cJSON_GetArrayItem(mats, (int)i) : NULL;
            struct aiString an;
            const cJSON *jn = cJSON_GetObjectItemCaseSensitive(mj, "name");
            if (mj && cJSON_IsString(jn) && aiGetMaterialString(sc->mMaterials[i], "?mat.name", 0, 0, &an) == AI_SUCCESS &&
                strcmp(an.data, jn->valuestring) != 0)
                return fail(im, "materials[%u]: importer order differs (\"%s\" vs \"%s\")", i, an.data, jn->valuestring);
            if (mj) {
                if (gltf_material(im, mj, (int)i, out)) return -1;
            } else { /* the glTF default material */
                memset(out, 0, sizeof *out);
                out->mat.kind = MATERIAL_PBR;
                out->mat.base_color = vec3_splat(1);
                out->mat.base_alpha = 1;
                out->mat.metallic = 1;
                out->mat.roughness = 1;
            }
        } else if (obj_material(im, sc->mMaterials[i], (int)i, out)) {
            return -1;
        }
    }
    m->material_count = sc->mNumMaterials;
    return 0;
}

static pthread_mutex_t assimp_lock = PTHREAD_MUTEX_INITIALIZER; /* aiGetErrorString is global */

static int import_run(importer *im) {
    model_kind kind = model_kind_of(im->name);
    if (kind != MODEL_GLTF && kind != MODEL_GLB && kind != MODEL_OBJ)
        return fail(im, "not a model file (expected .gltf, .glb or .obj)");
    if (kind == MODEL_GLB || kind == MODEL_GLTF) {
        const char *json = im->data;
        size_t jl = im->len;
        if (kind == MODEL_GLB &&
            model_glb_chunks(im->name, im->data, im->len, &json, &jl, &im->bin, &im->bin_len, im->err, im->err_len))
            return -1;
        im->gltf = cJSON_ParseWithLength(json, jl);
        if (!cJSON_IsObject(im->gltf)) return fail(im, "the glTF JSON does not parse");
        const cJSON *ver = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(im->gltf, "asset"), "version");
        if (!cJSON_IsString(ver) || strncmp(ver->valuestring, "2.", 2) != 0)
            return fail(im, "asset.version: expected \"2.0\" (only glTF 2 is supported)");
        if (check_extensions(im) || check_data_uris(im) || check_buffers_and_accessors(im) || check_primitives(im))
            return -1;
    }
    struct aiFileIO io = {io_open, io_close, (aiUserData)im};
    pthread_mutex_lock(&assimp_lock);
    const struct aiScene *sc = aiImportFileEx(im->name,
                                              aiProcess_Triangulate | aiProcess_SortByPType |
                                                  aiProcess_ValidateDataStructure,
                                              &io);
    if (!sc) {
        fail(im, "%s", aiGetErrorString());
        pthread_mutex_unlock(&assimp_lock);
        return -1;
    }
    pthread_mutex_unlock(&assimp_lock);
    static const double id[12] = {1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1, 0};
    int rc = materials_from(im, sc);
    if (!rc && sc->mRootNode) rc = walk_ai(im, sc, sc->mRootNode, id, 0);
    im->visits = 0;
    if (!rc && im->gltf) rc = gltf_nodes(im);
    aiReleaseImport(sc);
    if (!rc && im->m->tri_count == 0) rc = fail(im, "no triangles");
    return rc;
}

static int import_common(importer *im, import_model *out) {
    memset(out, 0, sizeof *out);
    im->m = out;
    int rc = import_run(im);
    cJSON_Delete(im->gltf);
    for (int i = 0; i < im->buffer_count; i++) free(im->buffers[i]);
    free(im->buffers);
    free(im->buffer_lens);
    free(im->tex_slot);
    free(im->normal_slots);
    if (rc) import_model_free(out);
    return rc;
}

int import_model_load(const scene_bundle *b, const char *name, const import_options *opt, import_model *out,
                      char *err, size_t err_len) {
    importer im;
    memset(&im, 0, sizeof im);
    im.b = b;
    im.name = name;
    im.err = err;
    im.err_len = err_len;
    im.opt = opt;
    const scene_bundle_file *f = scene_bundle_find(b, name);
    if (!f) {
        snprintf(err, err_len, "%s: not in the scene bundle", name);
        return -1;
    }
    if (!f->data) {
        snprintf(err, err_len, "%s", f->error);
        return -1;
    }
    im.data = f->data;
    im.len = f->len;
    return import_common(&im, out);
}

int import_model_from_memory(const char *name, const uint8_t *data, size_t len, import_model *out, char *err,
                             size_t err_len) {
    static const import_options opt = {.scale = 1};
    importer im;
    memset(&im, 0, sizeof im);
    im.name = name;
    im.data = (const char *)data;
    im.len = len;
    im.err = err;
    im.err_len = err_len;
    im.opt = &opt;
    return import_common(&im, out);
}

void import_model_free(import_model *m) {
    if (!m) return;
    free(m->positions);
    free(m->normals);
    free(m->normal_indices);
    free(m->uvs);
    free(m->flags);
    free(m->material);
    free(m->materials);
    for (uint32_t i = 0; m->textures && i < m->texture_count; i++) texture_free(&m->textures[i]);
    free(m->textures);
    free(m->lights);
    memset(m, 0, sizeof *m);
}
