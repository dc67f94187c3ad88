/* accel_embree.h - Embree 3's BVH as the traversal of large scenes, with
 * Tessera's own primitive tests deciding every hit.
 *
 * Embree builds (in parallel, on all cores) and walks a wide BVH over
 * bounding boxes that Tessera supplies; at each leaf it calls back into
 * Tessera, which runs the watertight triangle test and the sphere test of
 * intersect.h. The answer is defined without reference to any tree:
 *
 *   closest hit = the primitive with the smallest (t, index), t and the
 *   barycentrics as intersect.h computes them for the caller's ray and tmax;
 *   occluded  = some primitive has such a hit.
 *
 * Embree's choices (ISA, build order, thread count, node layout) only decide
 * in which order candidates are tried, never which one wins, because the
 * boxes are padded and the culling distance widened (accel_embree.c) so that
 * no box of a candidate that could still win is ever skipped. So the bytes
 * are the same with SSE2, AVX2 or AVX-512 kernels, any number of build
 * threads, and equal to the BVH's (bvh.c applies the same rule).
 *
 * TESSERA_EMBREE_CONFIG, if set, is passed to rtcNewDevice (e.g. "isa=sse2"
 * to force a kernel in tests); TESSERA_EMBREE_QUALITY = "medium" or "high"
 * asks for a slower SAH build instead of the default Morton build. Built once per scene, then read-only. */
#ifndef TESSERA_ACCEL_EMBREE_H
#define TESSERA_ACCEL_EMBREE_H

#include <embree3/rtcore.h>
#include <stdatomic.h>
#include <stddef.h>

#include "intersect.h"
#include "scene.h"

typedef struct accel_embree accel_embree;

typedef struct {
    double build_seconds;
    size_t memory_bytes; /* peak bytes Embree held during the build */
    size_t final_bytes;  /* bytes Embree holds after it */
    const char *config;  /* the device configuration used ("" for Embree's defaults) */
} accel_embree_stats;

/* An Embree device with Tessera's configuration (TESSERA_EMBREE_CONFIG), its
 * first error and the bytes it holds (now and at the peak), shared by this
 * intersector and accel_wide.c's builder. */
typedef struct {
    RTCDevice device;
    atomic_llong bytes, peak;
    char config[128];
    char error[256];
} accel_embree_device;

/* Open d (which must stay at this address until closed). Returns 0, or -1
 * with why in err (Embree refusing the configuration). */
int accel_embree_device_open(accel_embree_device *d, char *err, size_t err_len);

/* Release d's device; a device that failed to open is allowed. */
void accel_embree_device_close(accel_embree_device *d);

/* Primitive id's box (triangles, then spheres), padded by 2^-16 of its
 * largest coordinate plus 2^-16, far more than any slab test's rounding
 * (accel_embree.c). Can't fail. */
void accel_padded_box(const scene *s, uint32_t id, float lo[3], float hi[3]);

/* Build over s's triangles and spheres. Returns NULL on failure (out of
 * memory, or Embree refusing the device configuration) and writes why to
 * err. */
accel_embree *accel_embree_build(const scene *s, char *err, size_t err_len);

/* Free; NULL is allowed. */
void accel_embree_free(accel_embree *e);

void accel_embree_get_stats(const accel_embree *e, accel_embree_stats *out);

/* Closest hit with 0 < t < tmax. Returns 1 and fills *h, or 0 for a miss. */
int accel_embree_intersect(const accel_embree *e, const scene *s, const ray *r, float tmax, hit *h);

/* Any hit with 0 < t < tmax (shadow rays). Returns 1 if occluded. */
int accel_embree_occluded(const accel_embree *e, const scene *s, const ray *r, float tmax);

#endif
