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
    int paused;              /* out of space: records kept, retried by the timer */
    uv_timer_t retry;
    int error;               /* errno of the batch just written */
    uint64_t batches;
    int largest;
    tjournal_cb cb;
    tjournal_pause_cb on_pause;
    void *ctx;
};

/* Room for len more bytes and one more tile in b. Returns 0 or -1. */
static int batch_reserve(batch *b, size_t len, int tiles) {
    if (b->len + len > b->cap) {
        size_t cap = b->cap ? b->cap : 65536;
        while (cap < b->len + len) cap *= 2;
        uint8_t *d = realloc(b->data, cap);
        if (!d) return -1;
        b->data = d;
        b->cap = cap;
    }
    if (b->n + tiles > b->tiles_cap) {
        int cap = b->tiles_cap ? b->tiles_cap : 64;
        while (cap < b->n + tiles) cap *= 2;
        uint32_t *t = realloc(b->tiles, (size_t)cap * sizeof *t);
        if (!t) return -1;
        b->tiles = t;
        b->tiles_cap = cap;
    }
    return 0;
}

static void batch_free(batch *b) {
    free(b->data);
    free(b->tiles);
    memset(b, 0, sizeof *b);
}

tjournal *tjournal_open(uv_loop_t *loop, const char *path, tjournal_cb cb, tjournal_pause_cb on_pause, void *ctx,
                        char *err, size_t err_len) {
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
    jr->on_pause = on_pause;
    jr->ctx = ctx;
    jr->work.data = jr;
    uv_timer_init(loop, &jr->retry);
    uv_unref((uv_handle_t *)&jr->retry); /* waiting for space never keeps a stopping service alive */
    jr->retry.data = jr;
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
static void start_batch(tjournal *jr);

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

static void on_timer_closed(uv_handle_t *h) {
    tjournal *jr = h->data;
    batch_free(&jr->queued);
    batch_free(&jr->writing);
    free(jr);
}

static void tjournal_free(tjournal *jr) {
    close(jr->fd);
    uv_close((uv_handle_t *)&jr->retry, on_timer_closed);
}

/* Out of space: the batch goes back in front of the queue, whole, and is
 * tried again in TJOURNAL_RETRY_MS. Returns 0, or -1 when out of memory. */
static int requeue(tjournal *jr) {
    batch *w = &jr->writing, *q = &jr->queued;
    if (batch_reserve(w, q->len, q->n)) return -1;
    if (q->len) memcpy(w->data + w->len, q->data, q->len); /* an empty queue may have no buffers yet */
    if (q->n) memcpy(w->tiles + w->n, q->tiles, (size_t)q->n * sizeof *q->tiles);
    w->len += q->len;
    w->n += q->n;
    batch t = *q;
    *q = *w;
    *w = t;
    w->len = 0;
    w->n = 0;
    return 0;
}

static void on_retry(uv_timer_t *t) {
    tjournal *jr = t->data;
    if (!jr->closing && !jr->busy && jr->queued.n > 0) start_batch(jr);
}

static void after_batch(uv_work_t *w, int status) {
    (void)status;
    tjournal *jr = w->data;
    jr->busy = 0;
    int space = jr->error == ENOSPC || jr->error == EDQUOT;
    if (!jr->closing && space && requeue(jr) == 0) { /* nothing counted, nothing lost: wait for space */
        if (!jr->paused && jr->on_pause) jr->on_pause(jr->ctx, jr->error);
        jr->paused = 1;
        uv_timer_start(&jr->retry, on_retry, TJOURNAL_RETRY_MS, 0);
        return;
    }
    if (!jr->closing && !jr->error && jr->paused) {
        jr->paused = 0;
        if (jr->on_pause) jr->on_pause(jr->ctx, 0);
    }
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
    if (batch_reserve(b, len, 1)) return -1;
    memcpy(b->data + b->len, rec, len);
    b->len += len;
    b->tiles[b->n++] = tile;
    if (!jr->busy && !jr->paused) start_batch(jr);
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
