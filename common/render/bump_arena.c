/* bump_arena.c - chunks of anonymous memory with an atomic bump pointer
 * (bump_arena.h). A chunk is mapped 2 MiB larger than asked and its blocks
 * start at the first 2 MiB boundary, so that all of it can be a huge page;
 * or it is a spare block whole (bump_arena_take_spare). */
#include "bump_arena.h"

#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <stdlib.h>
#include <string.h>
#include <sys/mman.h>

#define HUGE_PAGE ((size_t)2 << 20)

struct bump_spare {
    size_t count;
    void *block[BUMP_SPARE_MAX];
    size_t bytes[BUMP_SPARE_MAX];
};

typedef struct chunk {
    struct chunk *next; /* the one filled before */
    void *map;          /* what mmap returned, map_bytes long; NULL: a spare block */
    size_t map_bytes;
    char *base;         /* the first block: map rounded up to HUGE_PAGE */
    size_t bytes;       /* blocks fit in base .. base + bytes */
    atomic_size_t used; /* may pass bytes: a block that did not fit */
} chunk;

struct bump_arena {
    size_t chunk_bytes;
    bump_arena_hint_fn hint;
    int all_huge; /* every chunk's hint said huge pages (under lock) */
    _Atomic(chunk *) cur; /* the chunk blocks come from, NULL before the first */
    pthread_mutex_t lock; /* taken to replace cur */
    void *taken[BUMP_SPARE_MAX]; /* spare blocks (bump_arena_take_spare), freed with the arena */
    size_t taken_bytes[BUMP_SPARE_MAX];
    size_t taken_count, taken_used; /* the first taken_used have become chunks */
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

/* A chunk after `prev`: the next spare block whole (zeroed, as fresh
 * memory is), else a mapping given its hint; NULL when mmap refuses.
 * Under a's lock. */
static chunk *chunk_new(bump_arena *a, chunk *prev) {
    chunk *c = malloc(sizeof *c);
    if (!c) return NULL;
    if (a->taken_used < a->taken_count) {
        char *block = a->taken[a->taken_used];
        c->base = (char *)round_up((uintptr_t)block, BUMP_ARENA_ALIGN);
        c->bytes = a->taken_bytes[a->taken_used++] - (size_t)(c->base - block);
        c->map = NULL;
        c->map_bytes = 0;
        memset(c->base, 0, c->bytes);
        a->all_huge = 0; /* whatever pages the loader's buffer had */
    } else {
        c->map_bytes = a->chunk_bytes + HUGE_PAGE;
        c->map = mmap(NULL, c->map_bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS | MAP_NORESERVE, -1, 0);
        if (c->map == MAP_FAILED) {
            free(c);
            return NULL;
        }
        c->base = (char *)round_up((uintptr_t)c->map, HUGE_PAGE);
        c->bytes = a->chunk_bytes;
        if (a->hint && !a->hint(c->base, a->chunk_bytes)) a->all_huge = 0;
    }
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
            if (at + step <= c->bytes) return c->base + at;
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
        sum += u < c->bytes ? u : c->bytes;
    }
    return sum;
}

int bump_arena_on_huge_pages(const bump_arena *a) { return a->all_huge; }

void bump_arena_free(bump_arena *a) {
    if (!a) return;
    chunk *c = atomic_load(&a->cur);
    while (c) {
        chunk *next = c->next;
        if (c->map) munmap(c->map, c->map_bytes);
        free(c);
        c = next;
    }
    for (size_t k = 0; k < a->taken_count; k++) free(a->taken[k]);
    pthread_mutex_destroy(&a->lock);
    free(a);
}

void bump_spare_add(bump_spare **sp, void *block, size_t bytes) {
    if (!block) return;
    if (!*sp) *sp = calloc(1, sizeof **sp);
    if (!*sp || (*sp)->count == BUMP_SPARE_MAX) {
        free(block);
        return;
    }
    (*sp)->block[(*sp)->count] = block;
    (*sp)->bytes[(*sp)->count++] = bytes;
}

size_t bump_spare_bytes(const bump_spare *sp) {
    size_t sum = 0;
    for (size_t k = 0; sp && k < sp->count; k++) sum += sp->bytes[k];
    return sum;
}

void bump_spare_free(bump_spare *sp) {
    if (!sp) return;
    for (size_t k = 0; k < sp->count; k++) free(sp->block[k]);
    free(sp);
}

void bump_arena_take_spare(bump_arena *a, bump_spare *sp, size_t max_bytes) {
    if (!sp) return;
    size_t taken = 0;
    for (size_t i = 0; i < a->taken_count; i++) taken += a->taken_bytes[i];
    for (size_t k = 0; k < sp->count; k++) {
        if (taken >= max_bytes || a->taken_count == BUMP_SPARE_MAX) {
            free(sp->block[k]);
            continue;
        }
        taken += sp->bytes[k];
        a->taken[a->taken_count] = sp->block[k];
        a->taken_bytes[a->taken_count++] = sp->bytes[k];
    }
    sp->count = 0;
}
