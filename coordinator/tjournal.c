/* tjournal.c - the tile journal's writer off the loop thread, with group
 * commit (tjournal.h). The loop thread owns everything but the batch being
 * written, which only the pool thread touches until after_batch runs. */
#define _GNU_SOURCE
#include "tjournal.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct {
    uint8_t *data;
    size_t len, cap;
    uint32_t *tiles;
    int n, tiles_cap;
} batch;

struct tjournal {
    uv_loop_t *loop;
    uv_work_t work;
    int fd;
    off_t durable;           /* file length of whole, synced records */
    batch queued, writing;   /* writing: the pool thread's while busy */
    int busy, in_cb, closing;
    int error;               /* errno of the batch just written */
    uint64_t batches;
    int largest;
    tjournal_cb cb;
    void *ctx;
};

static void batch_free(batch *b) {
    free(b->data);
    free(b->tiles);
    memset(b, 0, sizeof *b);
}

tjournal *tjournal_open(uv_loop_t *loop, const char *path, tjournal_cb cb, void *ctx, char *err, size_t err_len) {
    tjournal *jr = calloc(1, sizeof *jr);
    if (!jr) {
        snprintf(err, err_len, "%.400s: out of memory for the tile journal", path);
        return NULL;
    }
    jr->fd = open(path, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    struct stat st;
    if (jr->fd < 0 || fstat(jr->fd, &st) != 0) {
        snprintf(err, err_len, "%.400s: cannot open the tile journal: %s", path, strerror(errno));
        if (jr->fd >= 0) close(jr->fd);
        free(jr);
        return NULL;
    }
    jr->durable = st.st_size;
    jr->loop = loop;
    jr->cb = cb;
    jr->ctx = ctx;
    jr->work.data = jr;
    return jr;
}

/* On the pool thread: write the batch whole and sync it; on failure cut
 * the file back to its last durable length. */
static void write_batch(uv_work_t *w) {
    tjournal *jr = w->data;
    const batch *b = &jr->writing;
    size_t done = 0;
    int e = 0;
    while (!e && done < b->len) { /* a short write (disk full, file limit) is followed by the error */
        ssize_t n = write(jr->fd, b->data + done, b->len - done);
        if (n > 0) done += (size_t)n;
        else e = n < 0 ? errno : EIO;
    }
    if (!e && fdatasync(jr->fd) != 0) e = errno;
    if (e && ftruncate(jr->fd, jr->durable) != 0) {
        /* a torn record left behind is cut off at the next start */
    }
    jr->error = e;
}

static void after_batch(uv_work_t *w, int status);

static void start_batch(tjournal *jr) {
    batch t = jr->writing;
    jr->writing = jr->queued;
    jr->queued = t; /* reuse the old buffers */
    jr->queued.len = 0;
    jr->queued.n = 0;
    jr->busy = 1;
    jr->batches++;
    if (jr->writing.n > jr->largest) jr->largest = jr->writing.n;
    if (uv_queue_work(jr->loop, &jr->work, write_batch, after_batch) != 0) {
        write_batch(&jr->work); /* cannot happen with a live loop; stay correct anyway */
        after_batch(&jr->work, 0);
    }
}

static void tjournal_free(tjournal *jr) {
    close(jr->fd);
    batch_free(&jr->queued);
    batch_free(&jr->writing);
    free(jr);
}

static void after_batch(uv_work_t *w, int status) {
    (void)status;
    tjournal *jr = w->data;
    jr->busy = 0;
    if (!jr->closing) {
        if (!jr->error) jr->durable += (off_t)jr->writing.len;
        jr->in_cb = 1;
        jr->cb(jr->ctx, jr->writing.tiles, jr->writing.n, jr->error);
        jr->in_cb = 0;
    }
    if (jr->closing) {
        if (!jr->busy) tjournal_free(jr);
        return;
    }
    if (!jr->busy && jr->queued.n > 0) start_batch(jr);
}

int tjournal_append(tjournal *jr, uint32_t tile, const uint8_t *rec, size_t len) {
    batch *b = &jr->queued;
    if (b->len + len > b->cap) {
        size_t cap = b->cap ? b->cap : 65536;
        while (cap < b->len + len) cap *= 2;
        uint8_t *d = realloc(b->data, cap);
        if (!d) return -1;
        b->data = d;
        b->cap = cap;
    }
    if (b->n == b->tiles_cap) {
        int cap = b->tiles_cap ? 2 * b->tiles_cap : 64;
        uint32_t *t = realloc(b->tiles, (size_t)cap * sizeof *t);
        if (!t) return -1;
        b->tiles = t;
        b->tiles_cap = cap;
    }
    memcpy(b->data + b->len, rec, len);
    b->len += len;
    b->tiles[b->n++] = tile;
    if (!jr->busy) start_batch(jr);
    return 0;
}

void tjournal_stats(const tjournal *jr, uint64_t *batches, int *largest) {
    *batches = jr->batches;
    *largest = jr->largest;
}

void tjournal_close(tjournal *jr) {
    if (!jr || jr->closing) return;
    jr->closing = 1;
    if (!jr->busy && !jr->in_cb) tjournal_free(jr);
}
