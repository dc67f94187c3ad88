/* journal_partial.c - a job's finished tiles read back from its journal
 * (see journal_partial.h). The record layout and check are service.c's:
 * u32 magic "TILE", u32 tile, u32 float count, the floats (little-endian),
 * u32 FNV-1a of the tile number and the floats' bytes. */
#include "journal_partial.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"
#include "render/render.h"
#include "net/wire.h"

#define JOURNAL_MAGIC 0x454c4954u /* "TILE" */

/* service.c's record_check: FNV-1a over the floats' bytes, seeded by the tile. */
static uint32_t journal_check(uint32_t tile, const float *px, size_t n) {
    uint32_t h = 2166136261u ^ tile;
    const uint8_t *b = (const uint8_t *)px;
    for (size_t i = 0; i < 4 * n; i++) h = (h ^ b[i]) * 16777619u;
    return h;
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
    int found = 0;
    for (size_t off = 0; data && off + 16 <= len;) {
        const uint8_t *p = data + off;
        uint32_t tile = wire_get_u32(p + 4), n = wire_get_u32(p + 8);
        if (wire_get_u32(p) != JOURNAL_MAGIC || tile >= (uint32_t)tile_count) break;
        const tile_rect *r = &rects[tile];
        size_t w = (size_t)tile_width(r);
        if (n != 3 * w * (size_t)tile_height(r) || off + 16 + 4 * (size_t)n > len) break;
        float *px = malloc(4 * (size_t)n);
        if (!px) break;
        for (uint32_t i = 0; i < n; i++) px[i] = wire_get_f32(p + 12 + 4 * i);
        int ok = journal_check(tile, px, n) == wire_get_u32(p + 12 + 4 * (size_t)n);
        for (int y = r->y0; ok && y < r->y1; y++)
            memcpy(img->rgb + 3 * ((size_t)y * (size_t)width + (size_t)r->x0), px + 3 * w * (size_t)(y - r->y0), 12 * w);
        free(px);
        if (!ok) break;
        found += !done[tile];
        done[tile] = 1;
        off += 16 + 4 * (size_t)n;
    }
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
