/* import_time.c - how long the model importer takes on a file, against the
 * whole scene load (import + internal units + BVH) and the built-in OBJ
 * reader. Build and run from the repository root after `make`:
 *   cc -O2 -std=c11 -D_DEFAULT_SOURCE -I. -Icommon bench/gltf/import_time.c \
 *      build/release/lib/libtessera_render.a build/release/lib/libtessera_base.a \
 *      -lassimp -lcjson -lpng16 -ljpeg -lsodium -lpthread -lm -o build/import_time
 *   build/import_time MODEL.glb [MESH.obj]   (prints seconds, median of 3) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "render/import.h"
#include "render/obj.h"
#include "render/scene.h"

static double now(void) {
    struct timespec t;
    clock_gettime(CLOCK_MONOTONIC, &t);
    return t.tv_sec + t.tv_nsec * 1e-9;
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

int main(int argc, char **argv) {
    if (argc < 2) return 2;
    char err[1024];
    double t_imp[3], t_scene[3], t_obj[3] = {0, 0, 0};
    size_t tris = 0;
    for (int r = 0; r < 3; r++) {
        scene_bundle b;
        if (scene_bundle_read(argv[1], &b, err, sizeof err)) return fprintf(stderr, "%s\n", err), 1;
        import_options opt = {.scale = 1};
        import_model m;
        const char *slash = strrchr(argv[1], '/');
        double t0 = now();
        if (import_model_load(&b, slash ? slash + 1 : argv[1], &opt, &m, err, sizeof err))
            return fprintf(stderr, "%s\n", err), 1;
        t_imp[r] = now() - t0;
        tris = m.tri_count;
        import_model_free(&m);
        t0 = now();
        scene *s = scene_load_bundle(&b, NULL, err, sizeof err);
        t_scene[r] = now() - t0;
        if (!s) return fprintf(stderr, "%s\n", err), 1;
        scene_free(s);
        scene_bundle_free(&b);
        if (argc > 2) {
            obj_mesh om;
            t0 = now();
            if (obj_load(argv[2], &om, err, sizeof err)) return fprintf(stderr, "%s\n", err), 1;
            t_obj[r] = now() - t0;
            obj_mesh_free(&om);
        }
    }
    qsort(t_imp, 3, sizeof(double), cmp);
    qsort(t_scene, 3, sizeof(double), cmp);
    qsort(t_obj, 3, sizeof(double), cmp);
    printf("%s: %zu triangles; import (Assimp + glTF JSON) %.2f s; whole scene load (import, units, BVH) %.2f s",
           argv[1], tris, t_imp[1], t_scene[1]);
    if (argc > 2) printf("; built-in OBJ reader on %s %.2f s", argv[2], t_obj[1]);
    printf(" (medians of 3)\n");
    return 0;
}
