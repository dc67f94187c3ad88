/* admission.c - jobs admitted within the memory budget (--max-memory,
 * membudget.h): a job holds its frame and scene only once admitted; until
 * its need fits beside the jobs already admitted it waits, queued, with the
 * reason as its note; a job that could never fit is refused at submit time
 * (and fails at a restart) naming the figures. Part of the job service
 * (service_internal.h). */
#define _GNU_SOURCE
#include "service_internal.h"

uint64_t svc_memory_in_use(const service *s, int *jobs) {
    uint64_t sum = 0;
    int n = 0;
    const sjob *j;
    TAILQ_FOREACH(j, &s->jobs, link)
        if (j->rgb || j->admitting) { /* admitted: holding its frame (rendering, or waiting for disk space) or about to */
            sum += j->need;
            n++;
        }
    if (jobs) *jobs = n;
    return sum;
}

int svc_admit_check(const service *s, const sjob *j, char *why, size_t why_len) {
    char need[32], budget[32], used[32];
    membudget_format(j->need, need, sizeof need);
    membudget_format(s->o.max_memory, budget, sizeof budget);
    if (j->need > s->o.max_memory) {
        snprintf(why, why_len, "job needs %s for a %dx%d frame (with the saved image's copy) and its scene, --max-memory is %s", need,
                 j->desc.width, j->desc.height, budget);
        return -1;
    }
    int n;
    uint64_t in_use = svc_memory_in_use(s, &n);
    if (in_use + j->need <= s->o.max_memory) return 0;
    membudget_format(in_use, used, sizeof used);
    snprintf(why, why_len, "waiting for memory: needs %s for a %dx%d frame; %s of --max-memory %s is held by %d "
             "running job%s", need, j->desc.width, j->desc.height, used, budget, n, n == 1 ? "" : "s");
    return 1;
}

/* An admitted job's scene, read and framed on the loop's thread pool: a
 * scene of up to --max-upload bytes is no stall of the loop. */
typedef struct {
    uv_work_t work;
    service *s;
    sjob *j;
    char path[4096];
    size_t max_len;
    conn_blob *framed; /* the scene as a frame, or NULL with err */
    char err[600];
    int width, height, tile_size, tile_count;
    char journal[4096];
    store_resume resume; /* the journal replayed when prepared is 0 (-1: out of memory) */
    int prepared;
} admit_read;

/* file_read_with's room for the scene: the body of a frame (*ctx, a
 * conn_blob pointer), so that the scene is read straight into the frame
 * the workers are sent. */
static void *alloc_frame(size_t len, void *ctx) {
    conn_blob **b = ctx;
    *b = len < UINT32_MAX ? conn_blob_new(WIRE_HEADER_BYTES + len) : NULL;
    return *b ? (*b)->data + WIRE_HEADER_BYTES : NULL;
}

/* On the pool: read the scene into its frame (held once: before, the read
 * buffer and a copy of it as the frame were held together for a moment,
 * up to twice --max-upload) and replay the job's journal, however long,
 * off the loop. */
static void admit_read_work(uv_work_t *w) {
    admit_read *a = w->data;
    if (file_read_with(a->path, a->max_len, alloc_frame, &a->framed, a->err, sizeof a->err) < 0) {
        conn_blob_unref(a->framed);
        a->framed = NULL;
        return;
    }
    conn_blob_set_frame_header(a->framed, WIRE_KIND_SCENE);
    a->prepared = store_resume_prepare(a->journal, a->width, a->height, a->tile_size, a->tile_count, &a->resume);
}

/* Back on the loop: start the job unless it was cancelled (or the service
 * began to stop) while its scene was read. */
static void admit_read_done(uv_work_t *w, int status) {
    admit_read *a = w->data;
    sjob *j = a->j;
    j->admitting = 0;
    if (status == 0 && !a->s->stopping && j->state == SJOB_RUNNING) {
        const uint8_t *bundle = a->framed ? a->framed->data + WIRE_HEADER_BYTES : NULL;
        size_t len = a->framed ? a->framed->len - WIRE_HEADER_BYTES : 0;
        store_resume *r = a->framed && a->prepared == 0 ? &a->resume : NULL;
        if (store_job_resume_with(a->s, j, bundle, len, a->framed, a->err, r)) /* the failure is recorded in the job */
            svc_memory_released(a->s); /* its need no longer counts, though it may never have held a frame */
    } else {
        svc_memory_released(a->s); /* its need no longer counts */
    }
    store_resume_free(&a->resume); /* what the job did not take (zeroed when nothing was prepared) */
    conn_blob_unref(a->framed);
    free(a);
}

void svc_admit_waiting(service *s) {
    sjob *j;
    char why[300];
    TAILQ_FOREACH(j, &s->jobs, link) {
        if (!j->waiting || j->state != SJOB_RUNNING) continue;
        if (svc_admit_check(s, j, why, sizeof why) != 0) {
            if (j->restarting) { /* fitted alone at load time, not beside the jobs resumed before it */
                j->restarting = 0;
                snprintf(j->error, sizeof j->error, "%.500s", why);
                svc_log("job %u: %s", j->desc.id, j->error);
            }
            continue;
        }
        admit_read *a = calloc(1, sizeof *a);
        if (!a) return; /* out of memory: the job keeps waiting, tried again when memory is next released */
        char need[32];
        membudget_format(j->need, need, sizeof need);
        j->waiting = 0;
        j->admitting = 1; /* its need counts from now on */
        j->error[0] = 0;
        if (j->restarting) svc_log("job %u resuming: its scene and journal are read off the loop", j->desc.id);
        else svc_log("job %u admitted: its %s fit within --max-memory now", j->desc.id, need);
        j->restarting = 0;
        a->s = s;
        a->j = j;
        a->max_len = s->o.max_upload;
        a->work.data = a;
        store_scene_path(s, j, a->path, sizeof a->path);
        store_job_path(s, j->desc.id, "tiles", a->journal, sizeof a->journal);
        a->width = j->desc.width, a->height = j->desc.height;
        a->tile_size = j->tile_size, a->tile_count = j->tile_count;
        if (uv_queue_work(&s->loop, &a->work, admit_read_work, admit_read_done)) {
            free(a);
            j->admitting = 0;
            store_job_resume(s, j); /* the pool refused: read here */
        }
    }
}

/* The admit timer (svc_memory_released): admit what fits now. */
static void on_admit_timer(uv_timer_t *t) { svc_admit_waiting(t->data); }

void svc_memory_released(service *s) {
    if (s->stopping || uv_is_closing((uv_handle_t *)&s->admit)) return;
    uv_timer_start(&s->admit, on_admit_timer, 0, 0);
}

int svc_cancel_refused(const sjob *j, char *why, size_t len) {
    if (j->state != SJOB_RUNNING) return snprintf(why, len, "job %u is already %s", j->desc.id, state_names[j->state]), -1;
    if (j->saving || j->save_timer)
        return snprintf(why, len, "job %u is rendered: its image is being saved%s", j->desc.id,
                        j->save_timer ? " (waiting for disk space)" : ""),
               -1;
    return 0;
}

void svc_cancel_job(service *s, sjob *j) {
    if (svc_cancel_refused(j, NULL, 0)) return;
    if (!j->waiting && !j->admitting) {
        store_job_cancel(s, j); /* store_on_job_event records the state */
        return;
    }
    char err[600];
    j->waiting = 0;
    j->state = SJOB_CANCELLED;
    j->error[0] = 0;
    j->finished = svc_wall_now();
    if (store_save_job(j, err, sizeof err)) svc_log("job %u: %s", j->desc.id, err);
    const char *when = j->admitting ? "while its scene was read" : "while waiting for memory";
    svc_log("job %u cancelled %s", j->desc.id, when);
    joblog_add(j->log, j->finished, "cancelled %s", when);
}
