/* fuzz_obj.c - libFuzzer target: the OBJ reader on any bytes. */
#include <stdint.h>
#include <stdlib.h>

#include "render/obj.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    obj_mesh m;
    char err[512];
    if (obj_parse((const char *)data, size, "fuzz.obj", &m, err, sizeof err) == 0) {
        for (size_t i = 0; i < 3 * m.triangle_count; i++) /* every index must point at a vertex */
            if (m.indices[i] >= m.vertex_count) abort();
        obj_mesh_free(&m);
    } else if (!err[0]) {
        abort();
    }
    return 0;
}
