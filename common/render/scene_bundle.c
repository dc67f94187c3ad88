/* scene_bundle.c - gather a scene and its meshes into memory, serialise,
 * parse and hash them (see scene_bundle.h for the byte layout). */
#include "scene_bundle.h"

#include <errno.h>
#include <cjson/cJSON.h>
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "fileio.h"
#include "model_files.h"

#define BUNDLE_SCENE_MAX (64u << 20)
#define BUNDLE_MESH_MAX (SCENE_BUNDLE_MAX_BYTES / 2)

/* Append an entry; returns it, or NULL when out of memory. */
static scene_bundle_file *bundle_add(scene_bundle *b, const char *name) {
    scene_bundle_file *f = realloc(b->files, (b->count + 1) * sizeof *f);
    if (!f) return NULL;
    b->files = f;
    f = &b->files[b->count];
    memset(f, 0, sizeof *f);
    f->name = strdup(name);
    if (!f->name) return NULL;
    b->count++;
    return f;
}

const scene_bundle_file *scene_bundle_find(const scene_bundle *b, const char *name) {
    for (size_t i = 1; i < b->count; i++)
        if (strcmp(b->files[i].name, name) == 0) return &b->files[i];
    return NULL;
}

static int bundle_read_mesh(scene_bundle *b, const char *dir, const char *name);

typedef struct {
    scene_bundle *b;
    const char *dir;
} ref_ctx;

static int bundle_read_ref(void *ctx, const char *name) {
    ref_ctx *c = ctx;
    if (c->b->count >= SCENE_BUNDLE_MAX_FILES) return 0;
    return bundle_read_mesh(c->b, c->dir, name);
}

/* Models (model_files.h): read the files entry i references, recursively
 * (a glTF's buffers and images, an OBJ's MTL files and their textures). */
static int bundle_read_references(scene_bundle *b, const char *dir, size_t i) {
    if (!b->files[i].data || model_kind_of(b->files[i].name) == MODEL_NONE) return 0;
    ref_ctx c = {b, dir};
    char *name = strdup(b->files[i].name); /* b->files moves as entries are added */
    if (!name) return -1;
    int rc = model_references(name, b->files[i].data, b->files[i].len, bundle_read_ref, &c);
    free(name);
    return rc;
}

/* Read one mesh named in the scene into a new entry. Returns -1 only when
 * out of memory; an unreadable file is recorded in the entry. */
static int bundle_read_mesh(scene_bundle *b, const char *dir, const char *name) {
    if (scene_bundle_find(b, name)) return 0;
    scene_bundle_file *f = bundle_add(b, name);
    if (!f) return -1;
    char path[8192], err[1024];
    if (name[0] == '/')
        snprintf(path, sizeof path, "%s", name);
    else
        snprintf(path, sizeof path, "%s/%s", dir, name);
    f->data = file_read_all(path, BUNDLE_MESH_MAX, &f->len, err, sizeof err);
    if (!f->data) {
        f->error = strdup(err);
        if (!f->error) return -1;
    }
    return bundle_read_references(b, dir, b->count - 1);
}

/* Names of mesh files: shapes[i].file where shapes[i].type is "mesh". The
 * scene loader validates everything else; here a malformed scene simply
 * names no files. */
static int bundle_read_meshes(scene_bundle *b, const char *dir) {
    cJSON *root = cJSON_ParseWithLength(b->files[0].data, b->files[0].len);
    const cJSON *shapes = cJSON_GetObjectItemCaseSensitive(root, "shapes"), *sh;
    int rc = 0;
    cJSON_ArrayForEach(sh, shapes) {
        const cJSON *type = cJSON_GetObjectItemCaseSensitive(sh, "type");
        const cJSON *file = cJSON_GetObjectItemCaseSensitive(sh, "file");
        if (!cJSON_IsString(type) || !cJSON_IsString(file) ||
            (strcmp(type->valuestring, "mesh") != 0 && strcmp(type->valuestring, "model") != 0))
            continue;
        if (b->count >= SCENE_BUNDLE_MAX_FILES || (rc = bundle_read_mesh(b, dir, file->valuestring))) break;
    }
    const cJSON *imp = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(root, "import"), "file");
    if (!rc && cJSON_IsString(imp) && b->count < SCENE_BUNDLE_MAX_FILES) rc = bundle_read_mesh(b, dir, imp->valuestring);
    cJSON_Delete(root);
    return rc;
}

/* Read all of f (a pipe or a file) up to max bytes into a malloc'd,
 * NUL-terminated buffer; NULL with "NAME: reason" in err. */
static char *read_stream(FILE *f, const char *name, size_t max, size_t *len, char *err, size_t err_len) {
    size_t n = 0, cap = 65536;
    char *buf = malloc(cap + 1);
    while (buf) {
        size_t got = fread(buf + n, 1, cap - n, f);
        n += got;
        if (got == 0) break;
        if (n == cap) {
            char *bigger = cap < max ? realloc(buf, 2 * cap + 1) : NULL;
            if (!bigger) {
                if (cap < max) snprintf(err, err_len, "%s: out of memory", name);
                else snprintf(err, err_len, "%s: more than the limit of %zu MiB", name, max >> 20);
                free(buf);
                return NULL;
            }
            buf = bigger;
            cap *= 2;
        }
    }
    if (!buf || ferror(f)) {
        snprintf(err, err_len, "%s: %s", name, buf ? "read error" : "out of memory");
        free(buf);
        return NULL;
    }
    buf[n] = '\0';
    *len = n;
    return buf;
}

/* A scene file that is a pipe: a FIFO, or the shell's <(...) (/dev/fd/N).
 * Read like stdin: waits for its writer, as cat would. */
static int is_pipe(const char *path) {
    struct stat st;
    return stat(path, &st) == 0 && S_ISFIFO(st.st_mode);
}

/* The scene text at path (a file, or with stream set "-" or a pipe) into
 * *len bytes, malloc'd and NUL-terminated; NULL with "PATH: reason" in
 * err. What comes through stdin or a pipe may be a model
 * (streamed_model_name), so it may be as long as a mesh file; the caller
 * holds a scene to BUNDLE_SCENE_MAX. */
static char *read_scene_text(const char *path, int stream, size_t *len, char *err, size_t err_len) {
    if (strcmp(path, "-") == 0) return read_stream(stdin, "<stdin>", BUNDLE_MESH_MAX, len, err, err_len);
    if (!stream) return file_read_all(path, BUNDLE_SCENE_MAX, len, err, err_len);
    FILE *f = fopen(path, "rb");
    if (!f) {
        snprintf(err, err_len, "%s: cannot open: %s", path, strerror(errno));
        return NULL;
    }
    char *text = read_stream(f, path, BUNDLE_MESH_MAX, len, err, err_len);
    fclose(f);
    return text;
}

void scene_bundle_folder(const char *path, char *out, size_t n) {
    const char *slash = strrchr(path, '/');
    if (strncmp(path, "/dev/fd/", 8) == 0 || strncmp(path, "/proc/self/fd/", 14) == 0) slash = NULL;
    if (slash == path) snprintf(out, n, "/");
    else if (slash) snprintf(out, n, "%.*s", (int)(slash - path), path);
    else snprintf(out, n, ".");
}

/* An OBJ's material library that cannot be read is not an error to the
 * importer (Assimp goes on with grey materials): say so here, once per
 * command, where the files are read (workers get the bundle, not the
 * files). Can't fail. */
static void warn_missing_materials(const scene_bundle *b) {
    for (size_t i = 1; i < b->count; i++)
        if (!b->files[i].data && model_kind_of(b->files[i].name) == MODEL_MTL)
            fprintf(stderr, "warning: material library %s; its materials are rendered grey\n", b->files[i].error);
}

/* A model that came through stdin or a pipe, which has no name to tell its
 * kind by: binary glTF by its magic, glTF JSON by its "asset" object (a
 * scene file has none). Returns the entry name it gets ("stdin.glb",
 * "pipe.gltf", ...), or NULL for anything else (a scene). */
static const char *streamed_model_name(const char *data, size_t len, int from_stdin) {
    if (len >= 12 && memcmp(data, "glTF", 4) == 0) return from_stdin ? "stdin.glb" : "pipe.glb";
    if (len == 0 || memchr(data, '{', len < 64 ? len : 64) == NULL) return NULL;
    cJSON *root = cJSON_ParseWithLength(data, len);
    int gltf = cJSON_IsObject(cJSON_GetObjectItemCaseSensitive(root, "asset"));
    cJSON_Delete(root);
    return !gltf ? NULL : from_stdin ? "stdin.gltf" : "pipe.gltf";
}

/* b->files[0] holds a streamed model's bytes: move them to an entry of
 * their own named `name`, read what it references against dir, and make
 * files[0] the scene that imports it (as for a model file given by name).
 * Returns 0, or -1 when out of memory. */
static int bundle_stream_model(scene_bundle *b, const char *name, const char *dir) {
    scene_bundle_file *m = bundle_add(b, name);
    if (!m) return -1;
    m->data = b->files[0].data;
    m->len = b->files[0].len;
    m->streamed = 1;
    b->files[0].data = model_scene_json(name, NULL, &b->files[0].len);
    if (!b->files[0].data) return -1;
    return bundle_read_references(b, dir, b->count - 1);
}

int scene_bundle_read(const char *path, scene_bundle *out, char *err, size_t err_len) {
    memset(out, 0, sizeof *out);
    int from_stdin = strcmp(path, "-") == 0, stream = from_stdin || is_pipe(path);
    scene_bundle_file *f = bundle_add(out, from_stdin ? "<stdin>" : path);
    if (!f) goto oom;
    model_kind mk = model_kind_of(path);
    if (!from_stdin && (mk == MODEL_GLTF || mk == MODEL_GLB || mk == MODEL_OBJ)) { /* a model alone: import it whole */
        f->data = model_scene_json(path, NULL, &f->len);
        if (!f->data) goto oom;
    } else {
        f->data = read_scene_text(path, stream, &f->len, err, err_len);
    }
    if (!f->data) {
        scene_bundle_free(out);
        return -1;
    }
    char dir[4096];
    scene_bundle_folder(path, dir, sizeof dir);
    const char *streamed = stream ? streamed_model_name(f->data, f->len, from_stdin) : NULL;
    if (stream && !streamed && f->len > BUNDLE_SCENE_MAX) {
        snprintf(err, err_len, "%s: more than the limit of %u MiB", f->name, BUNDLE_SCENE_MAX >> 20);
        scene_bundle_free(out);
        return -1;
    }
    if (streamed && bundle_stream_model(out, streamed, dir)) goto oom;
    if (bundle_read_meshes(out, dir) == 0) {
        warn_missing_materials(out);
        return 0;
    }
oom:
    snprintf(err, err_len, "%s: out of memory", path);
    scene_bundle_free(out);
    return -1;
}

static void put_u32(uint8_t *p, uint32_t v) {
    for (int i = 0; i < 4; i++) p[i] = (uint8_t)(v >> (8 * i));
}

static uint32_t get_u32(const uint8_t *p) {
    return (uint32_t)p[0] | (uint32_t)p[1] << 8 | (uint32_t)p[2] << 16 | (uint32_t)p[3] << 24;
}

uint8_t *scene_bundle_serialise(const scene_bundle *b, size_t *len) {
    size_t n = 4, count = 0;
    for (size_t i = 0; i < b->count; i++) {
        if (!b->files[i].data) continue;
        n += 8 + strlen(b->files[i].name) + b->files[i].len;
        count++;
        if (n > SCENE_BUNDLE_MAX_BYTES) return NULL;
    }
    uint8_t *buf = malloc(n), *p = buf; /* ordinary pages, as file_read_all's (fileio.c) */
    if (!buf) return NULL;
    put_u32(p, (uint32_t)count);
    p += 4;
    for (size_t i = 0; i < b->count; i++) {
        const scene_bundle_file *f = &b->files[i];
        if (!f->data) continue;
        size_t nl = strlen(f->name);
        put_u32(p, (uint32_t)nl);
        memcpy(p + 4, f->name, nl);
        p += 4 + nl;
        put_u32(p, (uint32_t)f->len);
        memcpy(p + 4, f->data, f->len);
        p += 4 + f->len;
    }
    *len = n;
    return buf;
}

/* Copy len bytes at p into a new NUL-terminated string, or NULL. */
static char *dup_bytes(const uint8_t *p, size_t len) {
    char *s = malloc(len + 1); /* ordinary pages, as file_read_all's (fileio.c) */
    if (!s) return NULL;
    memcpy(s, p, len);
    s[len] = '\0';
    return s;
}

int scene_bundle_parse(const uint8_t *buf, size_t len, scene_bundle *out, char *err, size_t err_len) {
    memset(out, 0, sizeof *out);
    const uint8_t *p = buf, *end = buf + len;
    if (len < 4) goto truncated;
    uint32_t count = get_u32(p);
    p += 4;
    if (count < 1 || count > SCENE_BUNDLE_MAX_FILES) {
        snprintf(err, err_len, "scene bundle: %u entries (expected 1 to %d)", count, SCENE_BUNDLE_MAX_FILES);
        return -1;
    }
    out->files = calloc(count, sizeof *out->files);
    if (!out->files) goto oom;
    for (uint32_t i = 0; i < count; i++) {
        scene_bundle_file *f = &out->files[out->count++];
        if (end - p < 4) goto truncated;
        uint32_t nl = get_u32(p);
        if ((size_t)(end - p - 4) < nl || nl == 0) goto truncated;
        if (memchr(p + 4, '\0', nl)) {
            snprintf(err, err_len, "scene bundle: entry %u has a NUL in its name", i);
            scene_bundle_free(out);
            return -1;
        }
        if (!(f->name = dup_bytes(p + 4, nl))) goto oom;
        p += 4 + nl;
        if (end - p < 4) goto truncated;
        uint32_t dl = get_u32(p);
        if ((size_t)(end - p - 4) < dl) goto truncated;
        if (!(f->data = dup_bytes(p + 4, dl))) goto oom;
        f->len = dl;
        p += 4 + dl;
    }
    if (p != end) goto truncated;
    return 0;
truncated:
    snprintf(err, err_len, "scene bundle: truncated or inconsistent lengths");
    scene_bundle_free(out);
    return -1;
oom:
    snprintf(err, err_len, "scene bundle: out of memory");
    scene_bundle_free(out);
    return -1;
}

void scene_bundle_hash(const uint8_t *buf, size_t len, char hex[SCENE_BUNDLE_HASH_HEX]) {
    unsigned char h[32];
    crypto_generichash(h, sizeof h, buf, len, NULL, 0);
    sodium_bin2hex(hex, SCENE_BUNDLE_HASH_HEX, h, sizeof h);
}

void scene_bundle_free(scene_bundle *b) {
    for (size_t i = 0; i < b->count; i++) {
        free(b->files[i].name);
        free(b->files[i].data);
        free(b->files[i].error);
    }
    free(b->files);
    memset(b, 0, sizeof *b);
}
