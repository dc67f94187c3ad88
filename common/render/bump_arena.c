/* bump_arena.c - chunks of anonymous memory with an atomic bump pointer
 * (bump_arena.h). A chunk is mapped 2 MiB larger than asked and its blocks
 * start at the first 2 MiB boundary, so that all of it can be a huge page. */
#include "bump_arena.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <sys/mman.h>

#define HUGE_PAGE ((size_t)2 << 20)

typedef struct chunk {
    struct chunk *next; /* the one filled before */
    void *map;          /* what mmap returned, map_bytes long */
    size_t map_bytes;
    char *base;         /* the first block: map rounded up to HUGE_PAGE */
    atomic_size_t used; /* may pass the chunk size: a block that did not fit */
} chunk;

struct bump_arena {
    size_t chunk_bytes;
    bump_arena_hint_fn hint;
    int all_huge; /* every chunk's hint said huge pages (under lock) */
    _Atomic(chunk *) cur; /* the chunk blocks come from, NULL before the first */
    pthread_mutex_t lock; /* taken to replace cur */
};

static size_t round_up(size_t x, size_t to) { return (x + to - 1) / to * to; }

bump_arena *bump_arena_new(size_t chunk_bytes, bump_arena_hint_fn hint) {
    bump_arena *a = calloc(1, sizeof *a);
    if (!a) return NULL;
    a->chunk_bytes = round_up(chunk_bytes ? chunk_bytes : 1, HUGE_PAGE);
    a->hint = hint;
    a->all_huge = hint != NULL;
    atomic_init(&a->cur, NULL);
    pthread_mutex_init(&a->lock, NULL);
    return a;
}

/* A mapped chunk after `prev`, its hint given, or NULL when mmap refuses.
 * Under a's lock. */
static chunk *chunk_new(bump_arena *a, chunk *prev) {
    chunk *c = malloc(sizeof *c);
    if (!c) return NULL;
    c->map_bytes = a->chunk_bytes + HUGE_PAGE;
    c->map = mmap(NULL, c->map_bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
    if (c->map == MAP_FAILED) {
        free(c);
        return NULL;
    }
    c->base = (char *)round_up((uintptr_t)c->map, HUGE_PAGE);
    if (a->hint && !a->hint(c->base, a->chunk_bytes)) a->all_huge = 0;
    atomic_init(&c->used, 0);
    c->next = prev;
    return c;
}

void *bump_arena_alloc(bump_arena *a, size_t bytes) {
    size_t step = round_up(bytes ? bytes : 1, BUMP_ARENA_ALIGN);
    if (step > a->chunk_bytes) return NULL;
    for (;;) {
        chunk *c = atomic_load_explicit(&a->cur, memory_order_acquire);
        if (c) {
            size_t at = atomic_fetch_add_explicit(&c->used, step, memory_order_relaxed);
            if (at + step <= a->chunk_bytes) return c->base + at;
        }
        /* Full (or none yet): one thread maps the next chunk, the others
         * find it published when they get the lock. */
        pthread_mutex_lock(&a->lock);
        int ok = 1;
        if (atomic_load_explicit(&a->cur, memory_order_relaxed) == c) {
            chunk *n = chunk_new(a, c);
            if (n) atomic_store_explicit(&a->cur, n, memory_order_release);
            else ok = 0;
        }
        pthread_mutex_unlock(&a->lock);
        if (!ok) return NULL;
    }
}

size_t bump_arena_bytes(const bump_arena *a) {
    size_t sum = 0;
    for (chunk *c = atomic_load(&((bump_arena *)a)->cur); c; c = c->next) {
        size_t u = atomic_load(&c->used);
        sum += u < a->chunk_bytes ? u : a->chunk_bytes;
    }
    return sum;
}

int bump_arena_on_huge_pages(const bump_arena *a) { return a->all_huge; }

void bump_arena_free(bump_arena *a) {
    if (!a) return;
    chunk *c = atomic_load(&a->cur);
    while (c) {
        chunk *next = c->next;
        munmap(c->map, c->map_bytes);
        free(c);
        c = next;
    }
    pthread_mutex_destroy(&a->lock);
    free(a);
}
