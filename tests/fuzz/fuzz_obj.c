/* fuzz_obj.c - libFuzzer target: the OBJ reader on any bytes (v, vn, vt,
 * faces in every corner form): errors are reported, indices stay in range;
 * and the text parsed in 2 and 3 spans (obj_parse_spans, what a big text
 * gets on several cores; here on one thread) is refused whenever the one
 * pass refuses it, and when accepted is the one pass's mesh, bit for bit.
 * The same bytes are also scanned for the files they reference, as an OBJ
 * (mtllib) and as an MTL (map_Kd): model_files.c's scan by letter. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "render/model_files.h"
#include "render/obj.h"

/* Whether n elements of `size` bytes at a and b are equal (NULL only equals NULL). */
static int same(const void *a, const void *b, size_t n, size_t size) {
    if (!a || !b) return a == b;
    return memcmp(a, b, n * size) == 0;
}

static int same_mesh(const obj_mesh *a, const obj_mesh *b) {
    return a->vertex_count == b->vertex_count && a->triangle_count == b->triangle_count &&
           a->normal_count == b->normal_count && a->uv_count == b->uv_count &&
           same(a->positions, b->positions, 3 * a->vertex_count, sizeof(double)) &&
           same(a->indices, b->indices, 3 * a->triangle_count, sizeof(uint32_t)) &&
           (!a->normal_count || same(a->normals, b->normals, 3 * a->normal_count, sizeof(float))) &&
           (!a->uv_count || same(a->uvs, b->uvs, 2 * a->uv_count, sizeof(float))) &&
           same(a->normal_indices, b->normal_indices, 3 * a->triangle_count, sizeof(uint32_t)) &&
           same(a->uv_indices, b->uv_indices, 3 * a->triangle_count, sizeof(uint32_t));
}

/* The spans run one after the other on the fuzzer's thread (par.h): the
 * same results, without starting threads for each input. */
int LLVMFuzzerInitialize(int *argc, char ***argv) {
    (void)argc;
    (void)argv;
    setenv("TESSERA_LOAD_THREADS", "1", 1);
    return 0;
}

/* model_references' callback: every name it reports is a joined path. */
static int check_ref(void *ctx, const char *name) {
    (void)ctx;
    if (!name[0]) abort();
    return 0;
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    model_references("dir/fuzz.obj", (const char *)data, size, check_ref, NULL);
    model_references("dir/fuzz.mtl", (const char *)data, size, check_ref, NULL);
    obj_mesh m, spans;
    char err[512];
    int one = obj_parse((const char *)data, size, "fuzz.obj", &m, err, sizeof err);
    if (one == 0) {
        for (size_t i = 0; i < 3 * m.triangle_count; i++) { /* every index must point at a vertex, normal, uv */
            if (m.indices[i] >= m.vertex_count) abort();
            if (m.normal_indices && m.normal_indices[i] != OBJ_NONE && m.normal_indices[i] >= m.normal_count) abort();
            if (m.uv_indices && m.uv_indices[i] != OBJ_NONE && m.uv_indices[i] >= m.uv_count) abort();
            if (m.normal_indices && (m.normal_indices[i] == OBJ_NONE) != (m.normal_indices[i / 3 * 3] == OBJ_NONE))
                abort(); /* a triangle has normals at all corners or at none */
        }
        for (size_t i = 0; i < 3 * m.normal_count; i++)
            if (!isfinite(m.normals[i])) abort();
        for (size_t i = 0; i < 2 * m.uv_count; i++)
            if (!isfinite(m.uvs[i])) abort();
    } else if (!err[0]) {
        abort();
    }
    for (int parts = 2; parts <= 3; parts++)
        if (obj_parse_spans((const char *)data, size, "fuzz.obj", parts, &spans) == 0) {
            if (one != 0 || !same_mesh(&m, &spans)) abort(); /* accepted what one pass refuses, or a different mesh */
            obj_mesh_free(&spans);
        }
    if (one == 0) obj_mesh_free(&m);
    return 0;
}
