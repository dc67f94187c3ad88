/* fuzz_obj.c - libFuzzer target: the OBJ reader on any bytes (v, vn, vt,
 * faces in every corner form): errors are reported, indices stay in range. */
#include <math.h>
#include <stdint.h>
#include <stdlib.h>

#include "render/obj.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    obj_mesh m;
    char err[512];
    if (obj_parse((const char *)data, size, "fuzz.obj", &m, err, sizeof err) == 0) {
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
        obj_mesh_free(&m);
    } else if (!err[0]) {
        abort();
    }
    return 0;
}
