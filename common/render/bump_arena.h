/* bump_arena.h - memory for a structure that several threads build at once
 * and that is freed all at once (the wide BVH's nodes and leaves): chunks
 * of address space, handed out by an atomic bump pointer in 64-byte steps,
 * a new chunk taken under a lock when the current one is full; on
 * transparent huge pages if asked (memhint.h). Nothing is freed alone. */
#ifndef TESSERA_BUMP_ARENA_H
#define TESSERA_BUMP_ARENA_H

#include <stddef.h>

#define BUMP_ARENA_ALIGN 64 /* every block starts on a cache line */

typedef struct bump_arena bump_arena;

/* The page hint a new chunk gets before its first block: called with the
 * chunk (2 MiB-aligned) and its size, under the arena's lock; returns 1 if
 * the chunk asked for huge pages (memhint_fresh_huge, say). */
typedef int (*bump_arena_hint_fn)(void *chunk, size_t bytes);

/* A new arena of chunks of chunk_bytes (rounded up to 2 MiB; no memory is
 * mapped until the first block), each given `hint` (NULL: none). Returns
 * NULL when out of memory. Free with bump_arena_free. */
bump_arena *bump_arena_new(size_t chunk_bytes, bump_arena_hint_fn hint);

/* Whether every chunk mapped so far asked for huge pages (1 for none yet
 * with a hint, 0 with no hint). Call when no thread allocates. */
int bump_arena_on_huge_pages(const bump_arena *a);

/* A block of `bytes` (at most the chunk size; a spare block smaller than
 * that is passed over when the block does not fit), BUMP_ARENA_ALIGN-aligned and
 * zero-filled as fresh pages are, owned by the arena. Any thread, at once.
 * Returns NULL when no chunk can be mapped. */
void *bump_arena_alloc(bump_arena *a, size_t bytes);

/* The bytes handed out so far, the rounding to BUMP_ARENA_ALIGN included
 * (a full chunk counts whole, its tail too small for the next block
 * included). Call when no thread allocates. */
size_t bump_arena_bytes(const bump_arena *a);

/* Unmap every chunk, free the blocks it took (bump_arena_take_spare) and
 * the arena; NULL is allowed. */
void bump_arena_free(bump_arena *a);

/* Spare memory: big buffers a loader is done with, already faulted in,
 * kept for an arena's chunks instead of being returned to the kernel. On
 * this VM the first touch of fresh memory costs 1-2 ms of kernel time per
 * MB, a memset of memory already touched about 0.07 ms (docs/meshes.md,
 * twenty-seventh and thirty-first sessions). */
typedef struct bump_spare bump_spare;

#define BUMP_SPARE_MAX 16 /* blocks one spare holds; more are freed at once */

/* Give *sp the block at `block` (from malloc, `bytes` of it usable),
 * making *sp first when it is NULL. *sp owns the block from here (freed by
 * bump_spare_free or by the arena that takes it); when *sp cannot be made
 * or is full, the block is freed at once. */
void bump_spare_add(bump_spare **sp, void *block, size_t bytes);

/* The bytes sp holds (0 for NULL). */
size_t bump_spare_bytes(const bump_spare *sp);

/* Free sp's blocks and sp; NULL is allowed. */
void bump_spare_free(bump_spare *sp);

/* Move sp's blocks into a, in order, until a holds max_bytes of them (the
 * last may pass it): each becomes one of its next chunks, whole (zeroed as
 * fresh memory is, no hint given), before any is mapped; a frees them with
 * itself. The blocks past max_bytes are freed now, so that memory the
 * arena will not use is not held through its build. sp is left empty;
 * NULL is allowed. Call before the first bump_arena_alloc. */
void bump_arena_take_spare(bump_arena *a, bump_spare *sp, size_t max_bytes);

#endif
