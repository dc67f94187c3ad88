/* joblog.c - a job's bounded event log (see joblog.h): a ring of fixed
 * lines that grows by doubling up to JOBLOG_MAX, then overwrites the
 * oldest. */
#include "joblog.h"

#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    double t;
    char text[JOBLOG_LINE];
} joblog_line;

struct joblog {
    joblog_line *lines;
    int cap, head, count; /* head: index of the oldest line */
    uint64_t dropped;
};

joblog *joblog_new(void) { return calloc(1, sizeof(joblog)); }

void joblog_free(joblog *l) {
    if (!l) return;
    free(l->lines);
    free(l);
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

int joblog_to_json(const joblog *l, cJSON *o, int max) {
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
