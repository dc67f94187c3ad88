/* bvh.h - bounding volume hierarchy over all of a scene's primitives.
 *
 * Built once per scene (binned surface area heuristic), flattened into a
 * depth-first array of 32-byte nodes, then read-only: any number of threads
 * may trace through it at once. */
#ifndef TESSERA_BVH_H
#define TESSERA_BVH_H

#include <stddef.h>

#include "intersect.h"
#include "scene.h"

typedef struct bvh bvh;

typedef struct {
    size_t node_count;
    size_t leaf_count;
    size_t max_depth;
    size_t memory_bytes;
    double build_seconds;
} bvh_stats;

/* Build the BVH of s's triangles and spheres. Returns NULL only when out of
 * memory. A scene without primitives gets an empty BVH that nothing hits. */
bvh *bvh_build(const scene *s);

/* Free a BVH; NULL is allowed. */
void bvh_free(bvh *b);

void bvh_get_stats(const bvh *b, bvh_stats *out);

/* Closest hit with 0 < t < tmax. Returns 1 and fills *h, or 0 for a miss. */
int bvh_intersect(const bvh *b, const scene *s, const ray *r, float tmax, hit *h);

/* Any hit with 0 < t < tmax (shadow rays). Returns 1 if occluded. */
int bvh_occluded(const bvh *b, const scene *s, const ray *r, float tmax);

#endif
