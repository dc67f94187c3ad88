/* name_index.c - a string -> uint32 hash table (name_index.h). */
#include "name_index.h"

#include <stdlib.h>
#include <string.h>

static uint64_t hash(const char *s) {
    uint64_t h = 1469598103934665603ull;
    for (; *s; s++) h = (h ^ (uint8_t)*s) * 1099511628211ull;
    return h;
}

int name_index_init(name_index *ix, size_t n) {
    size_t cap = 16;
    while (cap < 2 * n + 2) cap *= 2;
    ix->keys = calloc(cap, sizeof *ix->keys);
    ix->values = calloc(cap, sizeof *ix->values);
    ix->cap = cap;
    if (!ix->keys || !ix->values) {
        name_index_free(ix);
        return -1;
    }
    return 0;
}

/* The slot of name, or of the empty slot where it would go; cap when the
 * table has no empty slot left. */
static size_t slot(const name_index *ix, const char *name) {
    size_t mask = ix->cap - 1, i = (size_t)hash(name) & mask;
    for (size_t probes = 0; probes < ix->cap; probes++, i = (i + 1) & mask)
        if (!ix->keys[i] || strcmp(ix->keys[i], name) == 0) return i;
    return ix->cap;
}

int name_index_add(name_index *ix, const char *name, uint32_t value) {
    size_t i = ix->cap ? slot(ix, name) : 0;
    if (i >= ix->cap) return -1;
    if (ix->keys[i]) return 1;
    ix->keys[i] = name;
    ix->values[i] = value;
    return 0;
}

int64_t name_index_find(const name_index *ix, const char *name) {
    size_t i = ix->cap ? slot(ix, name) : ix->cap;
    return i < ix->cap && ix->keys[i] ? (int64_t)ix->values[i] : -1;
}

void name_index_free(name_index *ix) {
    free(ix->keys);
    free(ix->values);
    memset(ix, 0, sizeof *ix);
}
