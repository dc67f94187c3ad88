/* par.h - a loop over [0, n) split into contiguous ranges, one thread each.
 *
 * For the loader's per-vertex and per-triangle loops, fileio.c's reads of
 * big files and sah_build.c's binning and subtrees: every range writes only
 * its own elements (and its own slot of a per-range result the caller
 * merges in range order), so the result is the same bytes whatever the
 * number of ranges. */
#ifndef TESSERA_PAR_H
#define TESSERA_PAR_H

#include <stddef.h>

#define PAR_MAX_PARTS 8

/* fn(ctx, begin, end, part): the work on [begin, end), range number part. */
typedef void (*par_fn)(void *ctx, size_t begin, size_t end, int part);

/* How many ranges a loop of n elements is split into: one per core (at
 * most PAR_MAX_PARTS; TESSERA_LOAD_THREADS overrides the core count), but
 * no range shorter than min_per_part elements, and at least 1. */
int par_parts(size_t n, size_t min_per_part);

/* par_parts for a loop that writes memory touched for the first time (the
 * loader's parse and records, the builders' boxes): up to
 * PAR_TOUCH_PER_CORE ranges per core, so that while one range's thread
 * waits for fresh pages another runs. On a VM whose host takes freed pages
 * back, a first touch can stall a thread for milliseconds: a one-pixel
 * 10.5M-triangle run took 2.33-2.52 s with these loops in 8 ranges on 2
 * cores against 2.51-4.19 s in 2 (5 alternations; docs/meshes.md). */
#define PAR_TOUCH_PER_CORE 4
int par_parts_touch(size_t n, size_t min_per_part);

/* Range `part` of `parts` over [0, n): [n part / parts, n (part + 1) / parts). */
void par_range(size_t n, int parts, int part, size_t *begin, size_t *end);

/* Run fn over [0, n) in `parts` ranges (1 <= parts <= PAR_MAX_PARTS), range
 * 0 on the calling thread, the others on threads of their own; on the
 * caller too, in order, when a thread cannot be started or only one core is
 * to be used (TESSERA_LOAD_THREADS=1). Returns when all are done. */
void par_run(size_t n, int parts, par_fn fn, void *ctx);

#endif
