/* film.c - putting tiles into a frame and checking their values (film.h). */
#include "film.h"

#include <math.h>
#include <string.h>

void film_put_tile(film *f, const tile_rect *r, const float *tile) {
    size_t row_floats = (size_t)tile_width(r) * (size_t)f->channels;
    for (int y = r->y0; y < r->y1; y++) {
        float *dst = f->px + (size_t)f->channels * ((size_t)y * (size_t)f->width + (size_t)r->x0);
        memcpy(dst, tile + row_floats * (size_t)(y - r->y0), row_floats * sizeof *dst);
    }
}

long film_first_bad(const float *v, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (!isfinite(v[i]) || v[i] < 0) return (long)i;
    return -1;
}
