/* meshload_time.c - where loading a big mesh scene goes, stage by stage:
 * reading the bundle, serialising and parsing it again (what the farm path
 * does to hand it to a worker), the OBJ parse alone, the whole scene load
 * without an intersector, and the intersector build. Each stage reports
 * this thread's CPU seconds (user + system, so page clearing counts), wall
 * seconds and minor page faults; the medians of N rounds are printed.
 * Build and run from the repository root after `make`:
 *   cc -O2 -std=c11 -D_DEFAULT_SOURCE -I. -Icommon bench/meshload_time.c \
 *      build/release/lib/libtessera_render.a build/release/lib/libtessera_base.a \
 *      -lassimp -lcjson -lpng16 -ljpeg -lsodium -lembree3 -lpthread -lm -o build/meshload_time
 *   build/meshload_time SCENE.json [ROUNDS]   (default 3 rounds) */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <time.h>

#include "render/accel.h"
#include "render/obj.h"
#include "render/scene.h"

enum { ST_READ, ST_COPY, ST_OBJ, ST_SCENE, ST_BUILD, ST_COUNT };
static const char *const stage_names[ST_COUNT] = {"bundle read", "bundle serialise+parse", "OBJ parse (first mesh)",
                                                  "scene load, no intersector", "intersector build"};

typedef struct {
    double cpu, wall, faults;
} sample;

static double clock_s(clockid_t c) {
    struct timespec t;
    clock_gettime(c, &t);
    return (double)t.tv_sec + (double)t.tv_nsec * 1e-9;
}

static double minor_faults(void) {
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_minflt;
}

static sample mark(void) { return (sample){clock_s(CLOCK_THREAD_CPUTIME_ID), clock_s(CLOCK_MONOTONIC), minor_faults()}; }

static sample since(sample a) {
    sample b = mark();
    return (sample){b.cpu - a.cpu, b.wall - a.wall, b.faults - a.faults};
}

static int cmp(const void *a, const void *b) {
    double x = *(const double *)a, y = *(const double *)b;
    return x < y ? -1 : x > y;
}

static double median(double *v, int n) {
    qsort(v, (size_t)n, sizeof *v, cmp);
    return v[n / 2];
}

/* One round of every stage into s[]; returns 0 or 1 (printed). */
static int one_round(const char *path, sample s[ST_COUNT], unsigned *tris) {
    char err[1024];
    scene_bundle b, b2;
    sample t = mark();
    if (scene_bundle_read(path, &b, err, sizeof err)) return fprintf(stderr, "%s\n", err), 1;
    s[ST_READ] = since(t);
    t = mark();
    size_t len;
    uint8_t *bytes = scene_bundle_serialise(&b, &len);
    if (!bytes || scene_bundle_parse(bytes, len, &b2, err, sizeof err)) return fprintf(stderr, "serialise/parse\n"), 1;
    free(bytes);
    s[ST_COPY] = since(t);
    scene_bundle_free(&b2);
    s[ST_OBJ] = (sample){0, 0, 0};
    if (b.count > 1 && b.files[1].data) {
        obj_mesh m;
        t = mark();
        if (obj_parse(b.files[1].data, b.files[1].len, b.files[1].name, &m, err, sizeof err) == 0) obj_mesh_free(&m);
        s[ST_OBJ] = since(t);
    }
    scene_overrides ov = {.width = -1, .height = -1, .spp = -1, .max_depth = -1, .no_accel = 1};
    t = mark();
    scene *sc = scene_load_bundle(&b, &ov, err, sizeof err);
    s[ST_SCENE] = since(t);
    if (!sc) return fprintf(stderr, "%s\n", err), 1;
    *tris = sc->triangle_count;
    t = mark();
    sc->accel = accel_build_err(sc, sc->settings.accel, err, sizeof err);
    s[ST_BUILD] = since(t); /* thread CPU: the calling thread only when the build is parallel */
    if (!sc->accel) return fprintf(stderr, "%s\n", err), 1;
    scene_free(sc);
    scene_bundle_free(&b);
    return 0;
}

int main(int argc, char **argv) {
    if (argc < 2) return fprintf(stderr, "usage: meshload_time SCENE.json [ROUNDS]\n"), 2;
    int rounds = argc > 2 ? atoi(argv[2]) : 3;
    if (rounds < 1 || rounds > 99) return 2;
    double v[3][ST_COUNT][99];
    unsigned tris = 0;
    for (int r = 0; r < rounds; r++) {
        sample s[ST_COUNT];
        if (one_round(argv[1], s, &tris)) return 1;
        for (int k = 0; k < ST_COUNT; k++) {
            v[0][k][r] = s[k].cpu;
            v[1][k][r] = s[k].wall;
            v[2][k][r] = s[k].faults;
        }
    }
    printf("%s: %u triangles, medians of %d rounds\n", argv[1], tris, rounds);
    printf("%-30s %9s %9s %12s\n", "stage", "cpu s", "wall s", "minor faults");
    for (int k = 0; k < ST_COUNT; k++)
        printf("%-30s %9.3f %9.3f %12.0f\n", stage_names[k], median(v[0][k], rounds), median(v[1][k], rounds),
               median(v[2][k], rounds));
    return 0;
}
