/* sah_build.h - a wide BVH built top-down by the binned surface area
 * heuristic, over boxes the caller supplies, into nodes and leaves the
 * caller's callbacks make (the wide BVH of accel_wide.h uses it below
 * ACCEL_WIDE_MORTON_MIN_PRIMITIVES).
 *
 * The procedure is Embree's generic builder's (rtcBuildBVH at
 * RTC_BUILD_QUALITY_MEDIUM, which built Tessera's wide BVH until
 * 2026-11-27): at each node the set is split in two by the best of up to
 * 32 bins per axis of the boxes' centres, then the child with the largest
 * box that is still splittable is split again, until the node has `width`
 * children; a set of `leaf_min` primitives or fewer is a leaf, and so is one
 * of `leaf_max` or fewer whose leaf cost is no more than its best split's.
 * Costs count primitives in blocks of `block` (a leaf test handles a block
 * at once). Why Tessera's own: it builds a tree as fast to render (at 2.6M
 * triangles the node and leaf counts within 1 of Embree's) in less time on
 * 2 cores (2.6M triangles: 0.83-1.08 s against 1.08-1.48 s, before the
 * AVX2 binning), without
 * Embree's buffers (a 2.6M-triangle run's system time 0.3 s instead of
 * 1.2 s), the same tree on any number of threads, and it stops within
 * 0.03 s when cancelled instead of 0.2-0.9 s (docs/meshes.md).
 *
 * The tree depends on the boxes only, never on the number of threads: the
 * top of the tree is built on the calling thread, the subtrees below it
 * (each a separate range of the primitive array) on par.h's threads. */
#ifndef TESSERA_SAH_BUILD_H
#define TESSERA_SAH_BUILD_H

#include <stddef.h>
#include <stdint.h>

#define SAH_MAX_WIDTH 16 /* sah_args.width at most */

/* One primitive's box and id: 32 bytes, the lower corner then the upper
 * (the builder loads each row as one SSE register, or the whole as one AVX
 * register): an array of them must be 32-byte aligned. */
typedef struct {
    float lo[3];
    uint32_t id;
    float hi[3];
    uint32_t pad;
} sah_prim;

typedef struct {
    unsigned width;     /* children per inner node at most, 2 to SAH_MAX_WIDTH */
    unsigned leaf_min;  /* a set this small is always a leaf (>= 1) */
    unsigned leaf_max;  /* a leaf holds this many at most (>= leaf_min) */
    unsigned block;     /* the SAH counts primitives in blocks of this many (>= 1) */
    unsigned max_depth; /* inner nodes on a path from the root, at most (>= 12) */
    float trav_cost, isect_cost;
    /* A new inner node for `count` children (2 to width), none set yet;
     * NULL when out of memory (the build then fails). Any thread, at once. */
    void *(*create_node)(unsigned count, void *user);
    /* Child k of node: its reference (as create_node or create_leaf returned
     * it) and its box. Called once per child, from any thread. */
    void (*set_child)(void *node, unsigned k, void *child, const float lo[3], const float hi[3], void *user);
    /* A leaf of prims[0 .. count) (1 <= count <= leaf_max, in order of id);
     * NULL when out of memory. Any thread, at once. */
    void *(*create_leaf)(const sah_prim *prims, size_t count, void *user);
    /* Nonzero stops the build (asked now and then; NULL: never). */
    int (*cancelled)(void *user);
    void *user;
} sah_args;

/* The threads a build over n primitives uses: par.h's cores
 * (TESSERA_LOAD_THREADS), fewer for small builds. */
int sah_build_threads(size_t n);

/* Build over prims[0 .. n) (n >= 1; 32-byte aligned; every box finite,
 * lo <= hi), which the build reorders. Returns the root's reference (a node, or a leaf when n is
 * small), or NULL when a callback returned NULL, the build was cancelled or
 * a->width is outside 2 .. SAH_MAX_WIDTH;
 * what the callbacks made belongs to the caller either way. */
void *sah_build(const sah_args *a, sah_prim *prims, size_t n);

#endif
