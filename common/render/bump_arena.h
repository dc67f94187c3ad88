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

/* A block of `bytes` (at most the chunk size), BUMP_ARENA_ALIGN-aligned and
 * zero-filled as fresh pages are, owned by the arena. Any thread, at once.
 * Returns NULL when no chunk can be mapped. */
void *bump_arena_alloc(bump_arena *a, size_t bytes);

/* The bytes handed out so far, the rounding to BUMP_ARENA_ALIGN included
 * (a full chunk counts whole, its tail too small for the next block
 * included). Call when no thread allocates. */
size_t bump_arena_bytes(const bump_arena *a);

/* Unmap every chunk and free the arena; NULL is allowed. */
void bump_arena_free(bump_arena *a);

#endif
