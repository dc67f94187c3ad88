/* accel_wide.h - Tessera's own wide BVH for large scenes: built in
 * parallel by Tessera's binned SAH builder (sah_build.h; nodes of up to 16
 * children) or, from ACCEL_WIDE_MORTON_MIN_PRIMITIVES, by Embree's
 * Morton-code builder (rtcBuildBVH, up to 8), over boxes Tessera supplies;
 * walked by Tessera with one SIMD slab test for every eight children of a
 * node, leaves of up to eight triangles (four without AVX2)
 * tested at once by the flat kernel's watertight test (accel_flat.h),
 * spheres by the scalar test.
 *
 * The answer is the one accel_embree.h defines, without reference to any
 * tree:
 *
 *   closest hit = the primitive with the smallest (t, index), t and the
 *   barycentrics as intersect.h computes them for the caller's ray and tmax;
 *   occluded  = some primitive has such a hit.
 *
 * The tree (whose shape depends on the Morton build's threads; the SAH
 * build's does not) only decides the
 * order in which candidates are tried: boxes are padded
 * (accel_padded_box), the slab test's far distance is widened by
 * 1 + 3 * 2^-23 (more than its rounding, pbrt's bound) and the culling
 * distance by accel_cull_distance, so no box holding a candidate that could
 * still win is skipped. Every lane of every test is the same IEEE operation
 * on every x86-64 (no FMA), whatever walk the CPU runs (SSE, AVX2 or
 * AVX-512; TESSERA_NO_AVX512 / TESSERA_NO_AVX2 stop it lower): the tree and
 * the walk only decide the order in which candidates are tried.
 *
 * TESSERA_EMBREE_CONFIG, if set, configures the Morton builder's Embree
 * device (e.g. "threads=1"); TESSERA_LOAD_THREADS the SAH builder's
 * threads. Built once per scene, then read-only: any number of
 * threads may trace through it at once. */
#ifndef TESSERA_ACCEL_WIDE_H
#define TESSERA_ACCEL_WIDE_H

#include <stddef.h>

#include "intersect.h"
#include "scene.h"

typedef struct accel_wide accel_wide;

typedef struct {
    double build_seconds;  /* wall time of the whole build, boxes included */
    size_t node_count;     /* inner nodes */
    size_t wide_node_count; /* of them, those of 16 slots (more than 8 children) */
    int node_width;        /* children per inner node at most (16 from the SAH, 8 from the Morton build) */
    const char *walk_isa;  /* the walk this CPU runs: "sse2", "avx2" or "avx512" */
    size_t leaf_count;     /* leaves (8 primitives each at most; 4 for the SSE walk) */
    size_t primitive_count;
    size_t memory_bytes;   /* bytes held after the build (nodes and leaves) */
    size_t peak_bytes;     /* bytes held at the build's peak, boxes included */
    const char *config;    /* the Morton builder's Embree device configuration ("" for Embree's defaults, or the SAH) */
    const char *builder;   /* "binned SAH" (Tessera's) or "Morton" (Embree's; ACCEL_WIDE_MORTON_MIN_PRIMITIVES) */
    int build_threads;     /* the SAH build's threads (0 for the Morton build: Embree's device decides) */
    int huge_pages;        /* 1 when every chunk of the tree asked for transparent huge pages (accel_wide.c) */
    size_t spare_bytes;    /* the loader's freed buffers offered to the tree's arena (scene.spare; short renders) */
} accel_wide_stats;

/* From this many primitives the tree is built by Embree's Morton-code
 * builder (RTC_BUILD_QUALITY_LOW) instead of the binned SAH: at 10.5M
 * triangles it builds in 1.7-2.5 s instead of 3.5-3.8 s (Tessera's SAH;
 * Embree's generic SAH took 5.0 s, Embree's own scene, which auto picked
 * there before, 3.5 s) and renders as fast as Embree's, for about 1.6x
 * Embree's peak memory (docs/meshes.md). Below,
 * its trees cost 19-25% more render CPU than the SAH's, more than the
 * build saves. TESSERA_WIDE_BUILDER=sah or =morton overrides the choice
 * (for tests and benchmarks); the bytes rendered never depend on it. */
#define ACCEL_WIDE_MORTON_MIN_PRIMITIVES 4194304

/* Build over s's triangles and spheres. Returns NULL on failure (out of
 * memory, Embree refusing the device configuration or failing the build)
 * and writes why to err. */
accel_wide *accel_wide_build(const scene *s, char *err, size_t err_len);

/* Free; NULL is allowed. */
void accel_wide_free(accel_wide *w);

void accel_wide_get_stats(const accel_wide *w, accel_wide_stats *out);

/* Closest hit with 0 < t < tmax. Returns 1 and fills *h, or 0 for a miss. */
int accel_wide_intersect(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h);

/* Any hit with 0 < t < tmax (shadow rays). Returns 1 if occluded. */
int accel_wide_occluded(const accel_wide *w, const scene *s, const ray *r, float tmax);

/* accel_wide_intersect of r and accel_wide_occluded of sh (*occluded set
 * to its answer) in one call, the two walks interleaved: the same answers. */
int accel_wide_intersect_occluded(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h,
                                  const ray *sh, float sh_tmax, int *occluded);

#ifdef TESSERA_WALK_COUNT
/* Only in a build with -DTESSERA_WALK_COUNT (build/release/bin/walk-count,
 * never the library): the walks started, node tests and leaf tests of the
 * calling thread's walks since it started. Counts depend on the tree and
 * the rays alone, so two trees compare without timing noise. */
typedef struct {
    unsigned long long walks, nodes, leaves;
} accel_wide_walk_counts;
void accel_wide_get_walk_counts(accel_wide_walk_counts *out);
#endif

#endif
