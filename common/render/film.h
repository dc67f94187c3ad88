/* film.h - the frame a render fills: width x height pixels of `channels`
 * floats (3 mean radiance values, or an adaptive round's sums), row 0 at the
 * top, into which tiles are put as they arrive, in any order.
 *
 * The farm stitches workers' tiles here; it knows nothing of radiance. The
 * film does not own its pixels: the caller allocates and frees them. */
#ifndef TESSERA_FILM_H
#define TESSERA_FILM_H

#include <stddef.h>

#include "render.h"

typedef struct {
    float *px; /* width * height * channels floats, the caller's */
    int width, height, channels;
} film;

/* Copy a tile's values (tile_width(r) * tile_height(r) * channels floats,
 * row-major, top row first) into the frame at r, which must lie inside it.
 * Can't fail. */
void film_put_tile(film *f, const tile_rect *r, const float *tile);

/* The index of the first of n values that is NaN, infinite or negative (a
 * radiance or a sum of radiances can be none of these), or -1. */
long film_first_bad(const float *v, size_t n);

#endif
