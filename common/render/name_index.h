/* name_index.h - names to small integers in linear time: an open-addressing
 * hash table (FNV-1a, linear probing) over strings the caller keeps alive.
 * The scene loader uses it so that checking n material names for
 * duplicates and resolving each shape's material cost O(n), not O(n^2). */
#ifndef TESSERA_NAME_INDEX_H
#define TESSERA_NAME_INDEX_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
    const char **keys; /* borrowed */
    uint32_t *values;
    size_t cap;        /* a power of two, at least twice the count */
} name_index;

/* A table for up to n names. Returns 0, or -1 when out of memory. */
int name_index_init(name_index *ix, size_t n);

/* Add name -> value. Returns 0; 1 when the name is already there (nothing
 * changes); -1 when the table is full (more than n names). */
int name_index_add(name_index *ix, const char *name, uint32_t value);

/* The value of name, or -1 when absent. */
int64_t name_index_find(const name_index *ix, const char *name);

void name_index_free(name_index *ix);

#endif
