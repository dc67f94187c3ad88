/* accel.h - the scene's ray intersector, chosen to fit the scene.
 *
 * Four structures answer the same two questions (closest hit, any hit):
 *  - ACCEL_BVH: a binary bounding volume hierarchy (bvh.h), for scenes of
 *    hundreds of primitives;
 *  - ACCEL_WIDE: a wide BVH (8 or 16 children a node) with SIMD node and leaf tests (accel_wide.h),
 *    for scenes of thousands to hundreds of thousands of primitives;
 *  - ACCEL_EMBREE: Embree's BVH walk with Tessera's tests at the leaves
 *    (accel_embree.h), for the largest scenes;
 *  - ACCEL_FLAT: every triangle tested, 16 (AVX-512), 8 (AVX2) or 4 (SSE) at a time, from
 *    arrays laid out for SIMD, then every sphere; no tree to walk. On a scene as small as
 *    the Cornell box this is faster than any tree (see docs/performance.md).
 * ACCEL_AUTO picks FLAT for small scenes, then BVH, then WIDE as they
 * grow (EMBREE only when asked for by name). The choice is a function of the scene alone, never of the machine,
 * so every worker of a farm takes the same path. BVH, WIDE and EMBREE give
 * the same hits bit for bit (the smallest (t, index)); FLAT can differ from
 * them only in which of two hits at exactly the same distance wins.
 *
 * Built once per scene, then read-only: any number of threads may trace
 * through it at once. */
#ifndef TESSERA_ACCEL_H
#define TESSERA_ACCEL_H

#include "accel_embree.h"
#include "accel_wide.h"
#include "bvh.h"
#include "intersect.h"
#include "scene.h"

/* ACCEL_AUTO picks ACCEL_FLAT up to this many triangles and spheres. */
#define ACCEL_FLAT_MAX_TRIANGLES 96
#define ACCEL_FLAT_MAX_SPHERES 8
/* ... ACCEL_WIDE from this many primitives (ACCEL_BVH below), at every
 * size since 2026-11-27: up to 2.6M triangles it renders with about 30%
 * less render CPU than Embree, and at 10.5M, built by Morton codes
 * (accel_wide.h), it builds in about half Embree's time and renders as
 * fast, for 1.6x Embree's peak memory. ACCEL_EMBREE is had by name
 * (docs/meshes.md has the figures). */
#define ACCEL_WIDE_MIN_PRIMITIVES 1024

typedef struct accel accel;

/* Build the intersector of kind `kind` (ACCEL_AUTO to let the scene decide)
 * over s's triangles and spheres. Returns NULL only when out of memory. */
accel *accel_build(const scene *s, accel_kind kind);

/* accel_build, with the reason for a failure (out of memory, or Embree
 * refusing TESSERA_EMBREE_CONFIG) written to err. */
accel *accel_build_err(const scene *s, accel_kind kind, char *err, size_t err_len);

/* ACCEL_EMBREE's statistics; returns 0, or -1 (leaving *out alone) for the
 * other kinds. */
int accel_get_embree_stats(const accel *a, accel_embree_stats *out);

/* Free an intersector; NULL is allowed. */
void accel_free(accel *a);

/* The kind that was built: ACCEL_BVH, ACCEL_FLAT, ACCEL_EMBREE or ACCEL_WIDE, never ACCEL_AUTO. */
accel_kind accel_get_kind(const accel *a);

/* The kind's name as a scene file writes it ("auto", "bvh", "flat",
 * "embree", "wide"); "?" for a value out of range. Can't fail. */
const char *accel_kind_name(accel_kind k);

/* How many triangles the flat kernel this CPU runs tests at once: 16 with
 * AVX-512F, 8 with AVX2, else 4. Can't fail. */
int accel_flat_lanes(const accel *a);

/* ACCEL_WIDE's statistics; returns 0, or -1 (leaving *out alone) for the
 * other kinds. */
int accel_get_wide_stats(const accel *a, accel_wide_stats *out);

/* The BVH's statistics; returns 0, or -1 (leaving *out alone) for FLAT. */
int accel_get_bvh_stats(const accel *a, bvh_stats *out);

/* Closest hit with 0 < t < tmax. Returns 1 and fills *h, or 0 for a miss. */
int accel_intersect(const accel *a, const scene *s, const ray *r, float tmax, hit *h);

/* Any hit with 0 < t < tmax (shadow rays). Returns 1 if occluded. */
int accel_occluded(const accel *a, const scene *s, const ray *r, float tmax);

/* accel_intersect(a, s, r, tmax, h) and *occluded = accel_occluded(a, s,
 * sh, sh_tmax) in one call: the same answers, and where the intersector
 * can (ACCEL_WIDE) the two walks interleaved, so that one's waits on
 * memory overlap the other's work. Returns accel_intersect's result. */
int accel_intersect_occluded(const accel *a, const scene *s, const ray *r, float tmax, hit *h, const ray *sh,
                             float sh_tmax, int *occluded);

#endif
