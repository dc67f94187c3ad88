/* accel_speed.c - render CPU time of a scene through each intersector,
 * in one process, the kinds interleaved round by round, so that a loaded
 * machine's noise falls on all of them alike.
 *
 *   accel-speed SCENE.json [--width W --height H --spp N] [--rounds R] [--pair-both] [KIND...]
 *
 * KIND: bvh, embree, wide (default: embree wide). Each intersector is built
 * once; each round renders the whole image as one tile on the calling
 * thread and reports that thread's CPU time (CLOCK_THREAD_CPUTIME_ID: the
 * builders' threads and the loading are not counted), rays per CPU second,
 * and whether the picture equals the first one's bit for bit (every other
 * round runs the kinds in reverse order); for the wide
 * BVH also its walk (the widest this CPU runs, or as TESSERA_NO_AVX512 /
 * TESSERA_NO_AVX2 say), its nodes and leaves and bytes per primitive.
 * --pair-both runs each kind twice a round: shadow rays traced alongside
 * the next ray (the default) and each at once (integrator_options.no_pair).
 *
 * Built with -DTESSERA_WALK_COUNT over a copy of accel_wide.c compiled
 * likewise (`make walk-count`: build/release/bin/walk-count), it also
 * prints each round's walks, node tests and leaf tests through the wide
 * BVH: a tree's quality measured without timing noise. */
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "render/accel.h"
#include "render/render.h"
#include "render/scene.h"

static double thread_cpu(void) {
    struct timespec t;
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return (double)t.tv_sec + 1e-9 * (double)t.tv_nsec;
}

static int parse_kind(const char *name, accel_kind *out) {
    static const char *const names[] = {"auto", "bvh", "flat", "embree", "wide"}; /* accel_kind order */
    for (int k = 0; k < 5; k++)
        if (strcmp(name, names[k]) == 0) return *out = (accel_kind)k, 0;
    return -1;
}

int main(int argc, char **argv) {
    const char *path = NULL, *names[8];
    accel_kind kinds[8];
    int nk = 0, rounds = 3, pair_both = 0;
    /* no intersector: built below, one per kind */
    scene_overrides ov = {.width = -1, .height = -1, .spp = -1, .max_depth = -1, .no_accel = 1};
    for (int i = 1; i < argc; i++) {
        if (i + 1 < argc && strcmp(argv[i], "--width") == 0) ov.width = atoi(argv[++i]);
        else if (i + 1 < argc && strcmp(argv[i], "--height") == 0) ov.height = atoi(argv[++i]);
        else if (i + 1 < argc && strcmp(argv[i], "--spp") == 0) ov.spp = atoi(argv[++i]);
        else if (i + 1 < argc && strcmp(argv[i], "--rounds") == 0) rounds = atoi(argv[++i]);
        else if (strcmp(argv[i], "--pair-both") == 0) pair_both = 1;
        else if (!path) path = argv[i];
        else if (nk < 8 && parse_kind(argv[i], &kinds[nk]) == 0) names[nk++] = argv[i];
        else return fprintf(stderr, "accel-speed: unknown argument \"%s\"\n", argv[i]), 2;
    }
    if (!path || rounds < 1) return fprintf(stderr, "usage: accel-speed SCENE.json [--width W --height H --spp N] [--rounds R] [--pair-both] [KIND...]\n"), 2;
    if (nk == 0) {
        kinds[0] = ACCEL_EMBREE, names[0] = "embree";
        kinds[1] = ACCEL_WIDE, names[1] = "wide";
        nk = 2;
    }
    char err[512];
    scene *s = scene_load(path, &ov, err, sizeof err);
    if (!s) return fprintf(stderr, "accel-speed: %s\n", err), 1;
    accel *built[8];
    for (int k = 0; k < nk; k++) {
        built[k] = accel_build_err(s, kinds[k], err, sizeof err);
        if (!built[k]) return fprintf(stderr, "accel-speed: building %s: %s\n", names[k], err), 1;
        accel_wide_stats ws;
        if (accel_get_wide_stats(built[k], &ws) == 0)
            printf("wide: %s walk, %zu nodes, %zu leaves, %.1f bytes per primitive\n", ws.walk_isa, ws.node_count,
                   ws.leaf_count, (double)ws.memory_bytes / (double)(ws.primitive_count ? ws.primitive_count : 1));
    }
    tile_rect all = {0, 0, s->settings.width, s->settings.height};
    size_t px = (size_t)s->settings.width * (size_t)s->settings.height;
    float *first = malloc(px * 3 * sizeof(float)), *rgb = malloc(px * 3 * sizeof(float));
    double *accum = malloc(px * 3 * sizeof(double));
    if (!first || !rgb || !accum) return fprintf(stderr, "accel-speed: out of memory\n"), 1;
    integrator_options opt = {0};
    printf("scene %s: %u triangles, %u spheres, %dx%d, %d spp, 1 thread\n", path, s->triangle_count, s->sphere_count,
           s->settings.width, s->settings.height, s->settings.spp);
    int pairings = pair_both ? 2 : 1; /* with --pair-both, each kind also with integrator_options.no_pair */
    for (int r = 0; r < rounds; r++)
        for (int i = 0; i < nk * pairings; i++) {
            int v = r % 2 ? nk * pairings - 1 - i : i; /* every other round backwards: no kind always goes first */
            int k = v / pairings;
            s->accel = built[k];
            opt.no_pair = v % pairings;
            trace_stats st = {0};
            memset(accum, 0, px * 3 * sizeof(double));
#ifdef TESSERA_WALK_COUNT
            accel_wide_walk_counts c0, c1;
            accel_wide_get_walk_counts(&c0);
#endif
            double t0 = thread_cpu();
            int ref = r == 0 && i == 0; /* the first picture: the others are compared with it */
            render_tile_means(s, &opt, &all, s->settings.spp, 1, accum, ref ? first : rgb, &st, NULL);
            double cpu = thread_cpu() - t0;
            int same = ref || memcmp(first, rgb, px * 3 * sizeof(float)) == 0;
            printf("round %d %-7s%s render CPU %.3f s, %.3f Mrays per CPU s, %s\n", r + 1, names[k],
                   opt.no_pair ? " (shadow rays unpaired)" : "", cpu,
                   (double)(st.rays + st.shadow_rays) / cpu * 1e-6, same ? "same picture" : "PICTURE DIFFERS");
#ifdef TESSERA_WALK_COUNT
            accel_wide_get_walk_counts(&c1);
            unsigned long long walks = c1.walks - c0.walks, nodes = c1.nodes - c0.nodes, leaves = c1.leaves - c0.leaves;
            if (walks)
                printf("round %d %-7s walks %llu, node tests %llu (%.3f per walk), leaf tests %llu (%.3f per walk)\n",
                       r + 1, names[k], walks, nodes, (double)nodes / (double)walks, leaves,
                       (double)leaves / (double)walks);
#endif
            fflush(stdout);
        }
    s->accel = NULL;
    for (int k = 0; k < nk; k++) accel_free(built[k]);
    free(first);
    free(rgb);
    free(accum);
    scene_free(s);
    return 0;
}
