/* fetch.c - a finished image streamed to a client in chunks (fetch.h): each
 * chunk is read with pread and hashed on libuv's thread pool, sent from the
 * loop, and the next one read when the write queue has drained. */
#define _GNU_SOURCE
#include "fetch.h"

#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <sodium.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

#include "journal.h"
#include "net/protocol.h"
#include "net/wire.h"

struct fetch_stream {
    uv_work_t work;
    uv_loop_t *loop;
    conn *c;             /* NULL once detached */
    fetch_stream **slot; /* the owner's pointer to us, cleared at the end */
    uint32_t job;
    char path[4096];
    int fd;              /* -1 until the first chunk's work opens it */
    /* fetch_start_partial: the PFM at path is first made from the journal
     * (then opened and unlinked: the stream holds the only reference) */
    fetch_partial_spec partial;
    int is_partial;
    char journal[4096], state[32];
    uint8_t *done;       /* the tiles found, then the "partial" message's ranges */
    int tiles_found;
    char build_err[600];
    struct fetch_stream *next_waiting; /* on the builds' queue (below) */
    uint64_t size, sent; /* file size; bytes read so far */
    size_t chunk;
    int busy;            /* a read is on the pool */
    /* the pool's, read on the loop after the work */
    uint8_t *frame; /* a D frame holding the chunk just read */
    size_t frame_len;
    int err_no;
    crypto_generichash_state hash;
};

/* Partial images are made one at a time: a build holds a thread of the
 * loop's pool for a whole journal, and the journals' own writes, uploads
 * and reads share that pool. The others wait here, in order. (One loop per
 * process: these are touched on its thread only.) */
static fetch_stream *build_running, *build_first, *build_last;

size_t fetch_chunk_size(void) {
    const char *e = getenv("TESSERA_FETCH_CHUNK");
    char *end;
    long long v = e && *e ? strtoll(e, &end, 10) : 0;
    return e && *e && *end == 0 && v >= 16 && v <= (64ll << 20) ? (size_t)v : FETCH_CHUNK_DEFAULT;
}

/* On the pool, before the first chunk of a partial fetch: the PFM made
 * from the journal. Returns 0, or -1 with build_err set. */
static int build_partial(fetch_stream *f) {
    const fetch_partial_spec *p = &f->partial;
    f->tiles_found = journal_write_partial_pfm(f->journal, f->path, p->width, p->height, p->tile_size, p->tile_count,
                                               f->done, f->build_err, sizeof f->build_err);
    return f->tiles_found < 0 ? -1 : 0;
}

/* On the pool: open the file (first time; for a partial fetch made first,
 * and unlinked once open), then read and hash the next chunk. */
static void read_chunk(uv_work_t *w) {
    fetch_stream *f = w->data;
    if (f->fd < 0) {
        struct stat st;
        if (f->is_partial && build_partial(f)) {
            f->err_no = EIO; /* send_error says build_err */
            return;
        }
        f->fd = open(f->path, O_RDONLY | O_CLOEXEC);
        int saved = errno;
        if (f->is_partial) unlink(f->path);
        if (f->fd < 0 || fstat(f->fd, &st) != 0) {
            f->err_no = f->fd < 0 ? saved : errno;
            return;
        }
        f->size = (uint64_t)st.st_size;
    }
    uint64_t left = f->size - f->sent;
    size_t n = left < f->chunk ? (size_t)left : f->chunk, got = 0;
    f->frame = wire_frame_new(WIRE_KIND_DATA, n, &f->frame_len);
    if (!f->frame) {
        f->err_no = ENOMEM;
        return;
    }
    while (got < n) {
        ssize_t r = pread(f->fd, f->frame + WIRE_HEADER_BYTES + got, n - got, (off_t)(f->sent + got));
        if (r < 0 && errno == EINTR) continue;
        if (r <= 0) {
            f->err_no = r < 0 ? errno : EIO; /* shorter than at the start: changed under us */
            return;
        }
        got += (size_t)r;
    }
    crypto_generichash_update(&f->hash, f->frame + WIRE_HEADER_BYTES, n);
}

/* A partial fetch's file has no name left: its last close frees all its
 * blocks (seen: 1 s of the loop for a 2.35 GB image), so it closes on the
 * pool. */
typedef struct {
    uv_work_t work;
    int fd;
} pool_close;

static void pool_close_work(uv_work_t *w) { close(((pool_close *)w->data)->fd); }
static void pool_close_done(uv_work_t *w, int status) {
    (void)status;
    free(w->data);
}

static void close_file(fetch_stream *f) {
    pool_close *pc = f->is_partial ? malloc(sizeof *pc) : NULL;
    if (pc) {
        pc->fd = f->fd;
        pc->work.data = pc;
        if (uv_queue_work(f->loop, &pc->work, pool_close_work, pool_close_done) == 0) return;
        free(pc);
    }
    close(f->fd);
}

static void stream_free(fetch_stream *f) {
    if (f->slot) *f->slot = NULL;
    if (f->fd >= 0) close_file(f);
    free(f->frame);
    free(f->done);
    free(f);
}

static void send_message(fetch_stream *f, cJSON *m) {
    size_t len;
    uint8_t *fr = wire_frame_json(m, &len);
    cJSON_Delete(m);
    if (fr) conn_send(f->c, fr, len);
}

static void send_error(fetch_stream *f) {
    char reason[4200];
    if (f->build_err[0])
        snprintf(reason, sizeof reason, "job %u: cannot make its partial image: %s", f->job, f->build_err);
    else
        snprintf(reason, sizeof reason, "job %u: cannot read its image %s: %s", f->job, f->path, strerror(f->err_no));
    size_t len;
    uint8_t *fr = proto_frame_reason("error", reason, &len);
    if (fr) conn_send(f->c, fr, len);
}

static void send_end(fetch_stream *f) {
    unsigned char h[32];
    char hex[65];
    crypto_generichash_final(&f->hash, h, sizeof h);
    sodium_bin2hex(hex, sizeof hex, h, sizeof h);
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", "image_end");
    cJSON_AddNumberToObject(m, "job", f->job);
    cJSON_AddNumberToObject(m, "bytes", (double)f->sent);
    cJSON_AddStringToObject(m, "blake2b", hex);
    send_message(f, m);
}

/* A partial fetch's first message: what the image holds and what not. */
static void send_partial(fetch_stream *f) {
    char missing[1024];
    journal_missing_ranges(f->done, f->partial.tile_count, missing, sizeof missing);
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", "partial");
    cJSON_AddNumberToObject(m, "job", f->job);
    cJSON_AddStringToObject(m, "state", f->state);
    cJSON_AddNumberToObject(m, "tiles_done", f->tiles_found);
    cJSON_AddNumberToObject(m, "tiles_total", f->partial.tile_count);
    cJSON_AddNumberToObject(m, "tile_size", f->partial.tile_size);
    cJSON_AddStringToObject(m, "missing", missing);
    send_message(f, m);
}

static void after_read(uv_work_t *w, int status);

static void next_chunk(fetch_stream *f) {
    f->busy = 1;
    uv_queue_work(f->loop, &f->work, read_chunk, after_read);
}

static void on_drained(conn *c, void *arg) {
    (void)c;
    next_chunk(arg);
}

/* On the loop: send what was read; then read on at once while the queue
 * holds under a chunk, else when it has drained to that. */
/* The partial build that held the slot is over: start the next one. */
static void build_done(fetch_stream *f) {
    if (f != build_running) return;
    build_running = build_first;
    if (!build_first) return;
    build_first = build_first->next_waiting;
    if (!build_first) build_last = NULL;
    next_chunk(build_running);
}

static void after_read(uv_work_t *w, int status) {
    fetch_stream *f = w->data;
    f->busy = 0;
    build_done(f); /* its first chunk: the PFM is made (or failed) */
    if (!f->c) return stream_free(f); /* the client went away meanwhile */
    if (status != 0 && !f->err_no) f->err_no = ECANCELED;
    if (f->err_no) {
        send_error(f);
        return stream_free(f);
    }
    if (f->sent == 0 && f->is_partial) send_partial(f);
    if (f->sent == 0) { /* the header, now that the size is known */
        cJSON *m = cJSON_CreateObject();
        cJSON_AddStringToObject(m, "type", "image");
        cJSON_AddNumberToObject(m, "job", f->job);
        cJSON_AddStringToObject(m, "format", "pfm");
        cJSON_AddNumberToObject(m, "bytes", (double)f->size);
        send_message(f, m);
    }
    size_t n = f->frame_len - WIRE_HEADER_BYTES;
    f->sent += n;
    if (n > 0) conn_send(f->c, f->frame, f->frame_len);
    else free(f->frame);
    f->frame = NULL;
    if (f->sent >= f->size) {
        send_end(f);
        return stream_free(f);
    }
    if (conn_write_queue(f->c) < f->chunk) next_chunk(f);
    else conn_on_drain(f->c, f->chunk, on_drained, f);
}

/* Start f (allocated, partial fields set) on path. Returns 0. */
static int fetch_start_stream(fetch_stream *f, uv_loop_t *loop, conn *c, uint32_t job, const char *path, size_t chunk,
                              fetch_stream **slot) {
    f->loop = loop;
    f->c = c;
    f->slot = slot;
    f->job = job;
    f->fd = -1;
    f->chunk = chunk;
    f->work.data = f;
    snprintf(f->path, sizeof f->path, "%s", path);
    crypto_generichash_init(&f->hash, NULL, 0, 32);
    *slot = f;
    if (f->is_partial && build_running) { /* made after the one in hand */
        if (build_last) build_last->next_waiting = f;
        else build_first = f;
        build_last = f;
        return 0;
    }
    if (f->is_partial) build_running = f;
    next_chunk(f);
    return 0;
}

int fetch_start_partial(uv_loop_t *loop, conn *c, uint32_t job, const fetch_partial_spec *p, const char *tmp,
                        size_t chunk, fetch_stream **slot) {
    fetch_stream *f = calloc(1, sizeof *f);
    uint8_t *done = malloc((size_t)p->tile_count + 1);
    if (!f || !done) {
        free(f);
        free(done);
        return -1;
    }
    f->is_partial = 1;
    f->partial = *p;
    f->done = done;
    snprintf(f->journal, sizeof f->journal, "%s", p->journal);
    snprintf(f->state, sizeof f->state, "%s", p->state);
    f->partial.journal = f->partial.state = NULL; /* the copies above */
    return fetch_start_stream(f, loop, c, job, tmp, chunk, slot);
}

int fetch_start(uv_loop_t *loop, conn *c, uint32_t job, const char *path, size_t chunk, fetch_stream **slot) {
    fetch_stream *f = calloc(1, sizeof *f);
    return f ? fetch_start_stream(f, loop, c, job, path, chunk, slot) : -1;
}

/* Take f off the builds' queue if it waits there. Returns 1 if it did. */
static int unqueue(fetch_stream *f) {
    for (fetch_stream **p = &build_first, *prev = NULL; *p; prev = *p, p = &(*p)->next_waiting)
        if (*p == f) {
            *p = f->next_waiting;
            if (build_last == f) build_last = prev;
            return 1;
        }
    return 0;
}

void fetch_detach(fetch_stream **slot) {
    fetch_stream *f = *slot;
    if (!f) return;
    *slot = NULL;
    f->slot = NULL;
    if (unqueue(f)) {
        stream_free(f);
        return;
    }
    conn_on_drain(f->c, 0, NULL, NULL);
    f->c = NULL;
    if (!f->busy) stream_free(f);
}
