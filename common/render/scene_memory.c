/* scene_memory.c - the memory estimate of scene_memory.h: faces counted in
 * the OBJ text, triangles counted in a glTF's JSON, texels read from a
 * texture's header, instances counted in the scene text; available memory
 * from /proc/meminfo and the cgroup (v2) limit. */
#include "scene_memory.h"

#include <cjson/cJSON.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "model_files.h"
#include "par.h"
#include "texture.h"

/* Triangles the `f` lines of an OBJ text make (corners - 2 each). */
static uint64_t count_obj_triangles(const char *s, size_t len) {
    uint64_t tris = 0;
    const char *end = s + len;
    while (s < end) {
        while (s < end && (*s == ' ' || *s == '\t')) s++;
        if (end - s > 1 && s[0] == 'f' && (s[1] == ' ' || s[1] == '\t')) {
            int corners = 0, in_token = 0;
            for (s += 1; s < end && *s != '\n' && *s != '#'; s++) {
                int blank = *s == ' ' || *s == '\t' || *s == '\r';
                if (!blank && !in_token) corners++;
                in_token = !blank;
            }
            if (corners > 2) tris += (uint64_t)corners - 2;
        }
        const char *nl = memchr(s, '\n', (size_t)(end - s));
        s = nl ? nl + 1 : end;
    }
    return tris;
}

/* count_obj_triangles over a text in ranges (par.h): each range counts the
 * lines that start in it, so the sum is the whole text's count. */
typedef struct {
    const char *s;
    size_t len;
    uint64_t tris[PAR_MAX_PARTS];
} obj_count;

/* The first line start at or after offset at of the text (len if none). */
static size_t line_start(const char *s, size_t len, size_t at) {
    if (at == 0 || at >= len) return at >= len ? len : 0;
    const char *nl = memchr(s + at - 1, '\n', len - (at - 1));
    return nl ? (size_t)(nl - s) + 1 : len;
}

static void count_range(void *ctx, size_t begin, size_t end, int part) {
    obj_count *C = ctx;
    size_t b = line_start(C->s, C->len, begin), e = line_start(C->s, C->len, end);
    C->tris[part] = b < e ? count_obj_triangles(C->s + b, e - b) : 0;
}

/* count_obj_triangles on every core, in ranges of at least 1 MiB: a
 * worker checks a scene before it loads it, and at 10.5M triangles the
 * whole estimate took 0.143 s on one thread, 0.098 s on two (ico9.json's
 * bundle, 3 runs each). */
static uint64_t count_obj_triangles_par(const char *s, size_t len) {
    obj_count C = {s, len, {0}};
    int parts = par_parts(len, (size_t)1 << 20);
    par_run(len, parts, count_range, &C);
    uint64_t tris = 0;
    for (int k = 0; k < parts; k++) tris += C.tris[k];
    return tris;
}

/* 4 bytes per texel of a w x h texture, or 0 when texture_decode refuses
 * that size before decoding. */
static uint64_t texels_bytes(uint32_t w, uint32_t h) {
    return w <= TEXTURE_MAX_SIDE && h <= TEXTURE_MAX_SIDE && (uint64_t)w * h <= TEXTURE_MAX_TEXELS ? (uint64_t)w * h * 4
                                                                                                   : 0;
}

/* The bytes a PNG or JPEG decodes to as a texture (render/texture.h: 4 per
 * texel), from the width and height in its header; 0 for any other file
 * or a header that does not hold them. */
static uint64_t texture_bytes(const uint8_t *d, size_t len) {
#define BE16(o) ((uint32_t)d[o] << 8 | d[(o) + 1])
#define BE32(o) (BE16(o) << 16 | BE16((o) + 2))
    static const uint8_t png[8] = {0x89, 'P', 'N', 'G', '\r', '\n', 0x1a, '\n'};
    if (len >= 24 && memcmp(d, png, 8) == 0 && memcmp(d + 12, "IHDR", 4) == 0)
        return texels_bytes(BE32(16), BE32(20));
    if (len < 4 || d[0] != 0xff || d[1] != 0xd8) return 0;
    /* JPEG: the segments up to the first start-of-frame (SOF0-15 but DHT,
     * JPG and DAC), which holds the height, then the width. */
    for (size_t i = 2; i + 4 <= len && d[i] == 0xff;) {
        uint8_t mk = d[i + 1];
        if (mk == 0xff) { i++; continue; } /* fill byte */
        if (mk >= 0xc0 && mk <= 0xcf && mk != 0xc4 && mk != 0xc8 && mk != 0xcc)
            return i + 9 <= len ? texels_bytes(BE16(i + 7), BE16(i + 5)) : 0;
        if (mk == 0xd9 || mk == 0xda) return 0; /* the image ended or its data began: no frame */
        i += 2 + BE16(i + 2);
    }
    return 0;
#undef BE16
#undef BE32
}

/* A glTF accessor's count (0 when index i names none, or its count is not
 * a number in [0, 2^32)). */
static uint64_t accessor_count(const cJSON *accessors, const cJSON *index) {
    if (!cJSON_IsNumber(index)) return 0;
    const cJSON *c = cJSON_GetObjectItemCaseSensitive(cJSON_GetArrayItem(accessors, index->valueint), "count");
    return cJSON_IsNumber(c) && c->valuedouble >= 0 && c->valuedouble < 4294967296.0 ? (uint64_t)c->valuedouble : 0;
}

/* Triangles mesh m of a glTF makes: per primitive, of mode 4 (triangles,
 * the default) its index count / 3 (its POSITION count when unindexed), of
 * mode 5 or 6 (strip, fan) that count - 2, of the other modes (points,
 * lines) none. */
static uint64_t gltf_mesh_triangles(const cJSON *m, const cJSON *accessors) {
    uint64_t tris = 0;
    const cJSON *prim;
    cJSON_ArrayForEach(prim, cJSON_GetObjectItemCaseSensitive(m, "primitives")) {
        const cJSON *mode = cJSON_GetObjectItemCaseSensitive(prim, "mode");
        int md = cJSON_IsNumber(mode) ? mode->valueint : 4;
        const cJSON *idx = cJSON_GetObjectItemCaseSensitive(prim, "indices");
        uint64_t n = idx ? accessor_count(accessors, idx)
                         : accessor_count(accessors, cJSON_GetObjectItemCaseSensitive(
                                                         cJSON_GetObjectItemCaseSensitive(prim, "attributes"), "POSITION"));
        tris += md == 4 ? n / 3 : (md == 5 || md == 6) && n >= 3 ? n - 2 : 0;
    }
    return tris;
}

/* The bytes a glTF image decodes to when it is stored in the binary glTF's
 * BIN chunk (bin, bin_len; NULL for none) through a bufferView; 0 for an
 * image elsewhere (a bundle file, counted as one) or one that cannot be
 * located. */
static uint64_t gltf_image_bytes(const cJSON *root, const cJSON *image, const char *bin, size_t bin_len) {
    const cJSON *bv = cJSON_GetObjectItemCaseSensitive(image, "bufferView");
    if (!bin || !cJSON_IsNumber(bv)) return 0;
    const cJSON *view = cJSON_GetArrayItem(cJSON_GetObjectItemCaseSensitive(root, "bufferViews"), bv->valueint);
    const cJSON *off = cJSON_GetObjectItemCaseSensitive(view, "byteOffset"),
                *n = cJSON_GetObjectItemCaseSensitive(view, "byteLength"),
                *buf = cJSON_GetObjectItemCaseSensitive(view, "buffer");
    if (!cJSON_IsNumber(buf) || buf->valuedouble != 0) return 0; /* the BIN chunk is buffer 0 */
    double o = cJSON_IsNumber(off) ? off->valuedouble : 0, l = cJSON_IsNumber(n) ? n->valuedouble : -1;
    if (!view || !(o >= 0 && l >= 0 && o + l <= (double)bin_len)) return 0;
    return texture_bytes((const uint8_t *)bin + (size_t)o, (size_t)l);
}

/* Triangles a glTF JSON text makes: each node's mesh once per node that
 * names it (as the importer flattens them); and into *tex the bytes its
 * images in the BIN chunk (bin, bin_len) decode to. Whatever does not
 * parse counts nothing: the importer refuses it with the reason. */
static uint64_t count_gltf(const char *json, size_t len, const char *bin, size_t bin_len, uint64_t *tex) {
    cJSON *root = cJSON_ParseWithLength(json, len);
    if (!root) return 0;
    const cJSON *meshes = cJSON_GetObjectItemCaseSensitive(root, "meshes"),
                *accessors = cJSON_GetObjectItemCaseSensitive(root, "accessors"), *node, *m, *image;
    int mesh_count = cJSON_IsArray(meshes) ? cJSON_GetArraySize(meshes) : 0, i = 0;
    uint64_t *per_mesh = calloc((size_t)mesh_count + 1, sizeof *per_mesh), tris = 0;
    if (!per_mesh) {
        cJSON_Delete(root);
        return 0;
    }
    const cJSON *mesh_array = mesh_count ? meshes : NULL; /* not an object's members: only an array's are counted */
    cJSON_ArrayForEach(m, mesh_array) {
        if (i < mesh_count) per_mesh[i++] = gltf_mesh_triangles(m, accessors);
    }
    cJSON_ArrayForEach(node, cJSON_GetObjectItemCaseSensitive(root, "nodes")) {
        const cJSON *mi = cJSON_GetObjectItemCaseSensitive(node, "mesh");
        if (cJSON_IsNumber(mi) && mi->valuedouble >= 0 && mi->valuedouble < mesh_count)
            tris += per_mesh[mi->valueint];
    }
    cJSON_ArrayForEach(image, cJSON_GetObjectItemCaseSensitive(root, "images")) *tex += gltf_image_bytes(root, image, bin, bin_len);
    free(per_mesh);
    cJSON_Delete(root);
    return tris;
}

/* The triangles of model file `name` (glTF, binary glTF; 0 for others),
 * and into *tex the bytes of the textures a binary glTF holds. */
static uint64_t count_model_triangles(const char *name, const char *data, size_t len, uint64_t *tex) {
    model_kind k = model_kind_of(name);
    if (k == MODEL_GLTF) return count_gltf(data, len, NULL, 0, tex);
    const char *json, *bin;
    size_t jl, bl;
    char err[160];
    if (k == MODEL_GLB && model_glb_chunks(name, data, len, &json, &jl, &bin, &bl, err, sizeof err) == 0)
        return count_gltf(json, jl, bin, bl, tex);
    return 0;
}

/* Whether the scene names `name` as a model (the top-level "import" or a
 * "model" shape: read by the importer) rather than as a mesh. */
static int named_as_model(const cJSON *root, const char *name) {
    const cJSON *f = cJSON_GetObjectItemCaseSensitive(cJSON_GetObjectItemCaseSensitive(root, "import"), "file"), *sh;
    if (cJSON_IsString(f) && strcmp(f->valuestring, name) == 0) return 1;
    cJSON_ArrayForEach(sh, cJSON_GetObjectItemCaseSensitive(root, "shapes")) {
        const cJSON *t = cJSON_GetObjectItemCaseSensitive(sh, "type");
        f = cJSON_GetObjectItemCaseSensitive(sh, "file");
        if (cJSON_IsString(t) && strcmp(t->valuestring, "model") == 0 && cJSON_IsString(f) &&
            strcmp(f->valuestring, name) == 0)
            return 1;
    }
    return 0;
}

/* How often the scene text names "name" (in quotes): the mesh's instances. */
static uint64_t count_uses(const char *scene_text, const char *name) {
    size_t n = strlen(name);
    uint64_t uses = 0;
    for (const char *p = scene_text; (p = strstr(p, name)) != NULL; p += n)
        if (p > scene_text && p[-1] == '"' && p[n] == '"') uses++;
    return uses ? uses : 1;
}

/* The estimate's parts: returns the bytes of b's files and textures, and
 * adds to *meshed and *imported the triangles of its meshes and models;
 * with scan_meshes 0 the meshes' OBJ texts are not read (*meshed stays). */
static uint64_t estimate_parts(const scene_bundle *b, int scan_meshes, uint64_t *meshed, uint64_t *imported) {
    uint64_t bytes = 0;
    const char *scene_text = b->count ? b->files[0].data : NULL;
    cJSON *root = scene_text ? cJSON_ParseWithLength(scene_text, b->files[0].len) : NULL;
    for (size_t i = 0; i < b->count; i++) {
        const scene_bundle_file *f = &b->files[i];
        bytes += f->len;
        if (i == 0 || !f->data) continue;
        uint64_t uses = scene_text ? count_uses(scene_text, f->name) : 1;
        model_kind k = model_kind_of(f->name);
        uint64_t tex = texture_bytes((const uint8_t *)f->data, f->len);
        if (k == MODEL_GLTF || k == MODEL_GLB) {
            *imported += uses * count_model_triangles(f->name, f->data, f->len, &tex);
        } else if (!tex && k != MODEL_MTL) { /* an OBJ text, whatever its name */
            int as_model = named_as_model(root, f->name);
            uint64_t t = as_model || scan_meshes ? uses * count_obj_triangles_par(f->data, f->len) : 0;
            if (as_model) *imported += t;
            else *meshed += t;
        }
        bytes += tex;
    }
    cJSON_Delete(root);
    return bytes;
}

static uint64_t estimate_total(uint64_t bytes, uint64_t meshed, uint64_t imported) {
    return bytes + meshed * SCENE_MEMORY_BYTES_PER_TRIANGLE + imported * SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE;
}

uint64_t scene_memory_estimate(const scene_bundle *b, uint64_t *triangles) {
    uint64_t meshed = 0, imported = 0, bytes = estimate_parts(b, 1, &meshed, &imported);
    if (triangles) *triangles = meshed + imported;
    return estimate_total(bytes, meshed, imported);
}

uint64_t scene_memory_estimate_loaded(const scene_bundle *b, uint64_t loaded, uint64_t *triangles) {
    uint64_t meshed = 0, imported = 0, bytes = estimate_parts(b, 0, &meshed, &imported);
    meshed = loaded > imported ? loaded - imported : 0;
    if (triangles) *triangles = meshed + imported;
    return estimate_total(bytes, meshed, imported);
}

/* A number from a file holding one ("max" reads as UINT64_MAX). */
static uint64_t read_number_file(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) return UINT64_MAX;
    char buf[64] = "";
    uint64_t v = UINT64_MAX;
    if (fgets(buf, sizeof buf, f) && strncmp(buf, "max", 3) != 0) v = strtoull(buf, NULL, 10);
    fclose(f);
    return v;
}

uint64_t scene_memory_available(void) {
    const char *forced = getenv("TESSERA_MEMORY_AVAILABLE_MB");
    if (forced && *forced) return strtoull(forced, NULL, 10) << 20;
    uint64_t avail = UINT64_MAX;
    FILE *f = fopen("/proc/meminfo", "r");
    char line[256];
    while (f && fgets(line, sizeof line, f)) {
        unsigned long long kb;
        if (sscanf(line, "MemAvailable: %llu kB", &kb) == 1) avail = (uint64_t)kb << 10;
    }
    if (f) fclose(f);
    uint64_t max = read_number_file("/sys/fs/cgroup/memory.max"), cur = read_number_file("/sys/fs/cgroup/memory.current");
    if (max != UINT64_MAX && cur != UINT64_MAX) {
        uint64_t room = max > cur ? max - cur : 0;
        if (room < avail) avail = room;
    }
    return avail;
}

int scene_memory_check(const scene_bundle *b, char *err, size_t err_len) {
    uint64_t tris, need = scene_memory_estimate(b, &tris), have = scene_memory_available();
    if (have == UINT64_MAX || need <= have) return 0;
    snprintf(err, err_len,
             "%s: this worker cannot hold the scene: loading %llu triangles needs about %llu MiB, only %llu MiB "
             "available here",
             b->count ? b->files[0].name : "scene", (unsigned long long)tris, (unsigned long long)(need >> 20),
             (unsigned long long)(have >> 20));
    return -1;
}
