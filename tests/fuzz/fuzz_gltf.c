/* fuzz_gltf.c - libFuzzer target: the model importer (glTF JSON or binary
 * glTF, told apart by the "glTF" magic) on any bytes, with no other files;
 * and first, as a worker does, the memory estimate of a scene importing
 * them (a glTF's triangles, its images' headers: scene_memory.c). */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/import.h"
#include "render/scene_memory.h"

/* scene_memory_estimate of {"import": {"file": name}} with the bytes as name. */
static void estimate(const char *name, const uint8_t *data, size_t size) {
    char *copy = malloc(size + 1), scene_text[64];
    if (!copy) return;
    memcpy(copy, data, size);
    copy[size] = '\0'; /* bundle entries are NUL-terminated */
    int n = snprintf(scene_text, sizeof scene_text, "{\"import\": {\"file\": \"%s\"}}", name);
    scene_bundle_file files[2] = {{(char *)"scene.json", scene_text, (size_t)n, NULL, 0},
                                  {(char *)name, copy, size, NULL, 0}};
    scene_bundle b = {files, 2};
    uint64_t tris;
    if (scene_memory_estimate(&b, &tris) < size) abort(); /* the file's own bytes count */
    free(copy);
}

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    import_model m;
    char err[1024];
    const char *name = size >= 4 && memcmp(data, "glTF", 4) == 0 ? "fuzz.glb" : "fuzz.gltf";
    estimate(name, data, size);
    err[0] = '\0';
    if (import_model_from_memory(name, data, size, &m, err, sizeof err) == 0) {
        for (size_t i = 0; i < 9 * m.tri_count; i++)
            if (!isfinite(m.positions[i])) abort();
        for (size_t t = 0; t < m.tri_count; t++) {
            if (m.material[t] >= m.material_count) abort();
            for (int k = 0; k < 3 && (m.flags[t] & 1); k++) /* shading normals: shared, in range */
                if (m.normal_indices[3 * t + k] >= m.normal_count) abort();
        }
        for (size_t i = 0; i < 3 * m.normal_count; i++)
            if (!isfinite(m.normals[i]) || fabsf(m.normals[i]) > 1.0f + 1e-6f) abort();
        import_model_free(&m);
    } else if (!err[0]) {
        abort();
    }
    return 0;
}
