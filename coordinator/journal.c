/* journal.c - reading a job's tile journal back (journal.h). */
#include "journal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

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

/* What to do with each good record: its tile's floats (3 per pixel, row
 * by row). Returns 0, or -1 to stop the scan. */
typedef int (*record_fn)(void *ctx, const tile_rect *r, const float *px);

/* Walk the records of data[0..len) up to the first torn or corrupt one (or
 * fn's refusal), marking done[tile] and counting in *found the tiles not
 * yet done. Returns the length of the good prefix. */
static size_t scan_records(const uint8_t *data, size_t len, const tile_rect *rects, int tile_count, uint8_t *done,
                           int *found, record_fn fn, void *ctx) {
    size_t off = 0, rec_len;
    uint32_t tile;
    float *px;
    *found = 0;
    while (off < len && record_read(data + off, len - off, rects, tile_count, &tile, &px, &rec_len) == 0) {
        int rc = fn(ctx, &rects[tile], px);
        free(px);
        if (rc) break;
        *found += !done[tile];
        done[tile] = 1;
        off += rec_len;
    }
    return off;
}

static int put_film(void *ctx, const tile_rect *r, const float *px) {
    film_put_tile(ctx, r, px);
    return 0;
}

size_t journal_replay(const uint8_t *data, size_t len, const tile_rect *rects, int tile_count, film *f,
                      uint8_t *done, int *found) {
    return scan_records(data, len, rects, tile_count, done, found, put_film, f);
}

/* The PFM being written by journal_write_partial_pfm. */
typedef struct {
    int fd, width, height;
    size_t header;
    uint8_t *row; /* one tile row, encoded */
    int err_no;
} pfm_out;

/* A tile's rows into the PFM at their places (bottom row first). */
static int put_pfm(void *ctx, const tile_rect *r, const float *px) {
    pfm_out *o = ctx;
    size_t w = (size_t)tile_width(r);
    for (int y = r->y0; y < r->y1; y++, px += 3 * w) {
        for (size_t i = 0; i < 3 * w; i++) wire_put_f32(o->row + 4 * i, px[i]);
        off_t at = (off_t)(o->header + 12 * ((size_t)(o->height - 1 - y) * (size_t)o->width + (size_t)r->x0));
        errno = 0;
        if (pwrite(o->fd, o->row, 12 * w, at) != (ssize_t)(12 * w)) {
            o->err_no = errno ? errno : ENOSPC; /* a short write: the disk is full */
            return -1;
        }
    }
    return 0;
}

/* Read the journal at fd record by record with pread (not mapped: the
 * coordinator may cut a live journal short meanwhile, after a failed write
 * or a torn tail, and a mapped page past the new end would kill it with
 * SIGBUS), handing each good record to scan_records; stops at the end, a
 * short read or the first torn or corrupt record (or one longer than
 * max_len, the largest tile's). *found counts the tiles found. Returns 0,
 * or -1 when out of memory. */
static int scan_file(int fd, const tile_rect *rects, int tile_count, size_t max_len, uint8_t *done, int *found,
                     record_fn fn, void *ctx) {
    uint8_t head[12], *rec = NULL;
    size_t cap = 0;
    off_t off = 0;
    *found = 0;
    for (;;) {
        if (pread(fd, head, sizeof head, off) != (ssize_t)sizeof head) break;
        size_t len = JOURNAL_RECORD_OVERHEAD + 4 * (size_t)wire_get_u32(head + 8);
        if (wire_get_u32(head) != JOURNAL_MAGIC || len > max_len) break; /* no record of this job's */
        if (len > cap) {
            uint8_t *grown = realloc(rec, len);
            if (!grown) {
                free(rec);
                return -1;
            }
            rec = grown, cap = len;
        }
        int one = 0;
        if (pread(fd, rec, len, off) != (ssize_t)len ||
            scan_records(rec, len, rects, tile_count, done, &one, fn, ctx) != len)
            break;
        *found += one;
        off += (off_t)len;
    }
    free(rec);
    return 0;
}

int journal_write_partial_pfm(const char *path, const char *out, int width, int height, int tile_size,
                              int tile_count, uint8_t *done, char *err, size_t err_len) {
    char header[64];
    int hl = snprintf(header, sizeof header, "PF\n%d %d\n-1.0\n", width, height); /* image.c's PFM */
    pfm_out o = {.fd = -1, .width = width, .height = height, .header = (size_t)hl};
    tile_rect *rects = calloc((size_t)tile_count, sizeof *rects);
    o.row = malloc(12 * (size_t)(tile_size < width ? tile_size : width));
    int in = open(path, O_RDONLY | O_CLOEXEC), found = -1;
    memset(done, 0, (size_t)tile_count);
    if (!rects || !o.row) {
        snprintf(err, err_len, "%.400s: out of memory", path);
    } else if (in < 0 && errno != ENOENT) { /* a missing journal is an empty one */
        snprintf(err, err_len, "%.400s: %s", path, strerror(errno));
    } else if ((o.fd = open(out, O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0600)) < 0 ||
               write(o.fd, header, (size_t)hl) != hl ||
               ftruncate(o.fd, (off_t)(o.header + 12 * (size_t)width * (size_t)height)) != 0) {
        /* (the tiles never written stay black: zeros, a sparse file's holes) */
        snprintf(err, err_len, "%.400s: cannot write: %s", out, strerror(errno));
    } else {
        render_split_tiles(width, height, tile_size, rects, tile_count);
        found = 0;
        size_t max_len = JOURNAL_RECORD_OVERHEAD + 12 * (size_t)tile_size * (size_t)tile_size;
        if (in >= 0 && scan_file(in, rects, tile_count, max_len, done, &found, put_pfm, &o)) {
            snprintf(err, err_len, "%.400s: out of memory", path);
            found = -1;
        } else if (o.err_no) {
            snprintf(err, err_len, "%.400s: cannot write: %s", out, strerror(o.err_no));
            found = -1;
        }
    }
    if (in >= 0) close(in);
    if (o.fd >= 0) close(o.fd);
    if (found < 0 && o.fd >= 0) unlink(out);
    free(rects);
    free(o.row);
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
