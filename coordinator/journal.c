/* journal.c - reading a job's tile journal back (journal.h). */
#include "journal.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"
#include "net/wire.h"
#include "render/render.h"

uint32_t journal_record_check(uint32_t tile, const float *px, size_t n) {
    uint32_t h = 2166136261u ^ tile; /* FNV-1a over the bytes: catches torn writes */
    const uint8_t *b = (const uint8_t *)px;
    for (size_t i = 0; i < 4 * n; i++) h = (h ^ b[i]) * 16777619u;
    return h;
}

/* Decode and check the record at p (len bytes left) of a job cut into
 * rects[tile_count]: its tile and floats into *tile and a new buffer *px
 * (the caller frees), its length into *rec_len. Returns 0, or -1 for a
 * torn or corrupt record (or no memory). */
static int record_read(const uint8_t *p, size_t len, const tile_rect *rects, int tile_count, uint32_t *tile,
                       float **px, size_t *rec_len) {
    if (len < JOURNAL_RECORD_OVERHEAD) return -1;
    uint32_t t = wire_get_u32(p + 4), n = wire_get_u32(p + 8);
    if (wire_get_u32(p) != JOURNAL_MAGIC || t >= (uint32_t)tile_count) return -1;
    const tile_rect *r = &rects[t];
    if (n != 3 * (size_t)tile_width(r) * (size_t)tile_height(r) || JOURNAL_RECORD_OVERHEAD + 4 * (size_t)n > len)
        return -1;
    float *v = malloc(4 * (size_t)n);
    if (!v) return -1;
    for (uint32_t i = 0; i < n; i++) v[i] = wire_get_f32(p + 12 + 4 * i);
    if (journal_record_check(t, v, n) != wire_get_u32(p + 12 + 4 * (size_t)n)) {
        free(v);
        return -1;
    }
    *tile = t;
    *px = v;
    *rec_len = JOURNAL_RECORD_OVERHEAD + 4 * (size_t)n;
    return 0;
}

size_t journal_replay(const uint8_t *data, size_t len, const tile_rect *rects, int tile_count, film *f,
                      uint8_t *done, int *found) {
    size_t off = 0, rec_len;
    uint32_t tile;
    float *px;
    *found = 0;
    while (off < len && record_read(data + off, len - off, rects, tile_count, &tile, &px, &rec_len) == 0) {
        film_put_tile(f, &rects[tile], px);
        free(px);
        *found += !done[tile];
        done[tile] = 1;
        off += rec_len;
    }
    return off;
}

int journal_read_partial(const char *path, int width, int height, int tile_size, int tile_count, image *img,
                         uint8_t *done, char *err, size_t err_len) {
    tile_rect *rects = calloc((size_t)tile_count, sizeof *rects);
    if (!rects || image_alloc(img, width, height)) {
        free(rects);
        snprintf(err, err_len, "%.400s: out of memory for a %dx%d image", path, width, height);
        return -1;
    }
    render_split_tiles(width, height, tile_size, rects, tile_count);
    memset(done, 0, (size_t)tile_count);
    size_t len = 0;
    char why[512];
    uint8_t *data = (uint8_t *)file_read_all(path, (size_t)1 << 40, &len, why, sizeof why);
    film f = {img->rgb, width, height, 3};
    int found = 0;
    if (data) journal_replay(data, len, rects, tile_count, &f, done, &found);
    free(data);
    free(rects);
    return found;
}

void journal_missing_ranges(const uint8_t *done, int tile_count, char *out, size_t out_len) {
    size_t used = 0;
    out[0] = '\0';
    for (int t = 0; t < tile_count; t++) {
        if (done[t]) continue;
        int end = t;
        while (end + 1 < tile_count && !done[end + 1]) end++;
        char part[32];
        int n = end > t ? snprintf(part, sizeof part, "%s%d-%d", used ? ", " : "", t, end)
                        : snprintf(part, sizeof part, "%s%d", used ? ", " : "", t);
        if (used + (size_t)n + 4 >= out_len) {
            snprintf(out + used, out_len - used, "%s", out_len - used > 4 ? "..." : "");
            return;
        }
        memcpy(out + used, part, (size_t)n + 1);
        used += (size_t)n;
        t = end;
    }
}
