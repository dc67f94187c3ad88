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
        if (j->rgb) { /* admitted and holding its frame (rendering, or waiting for disk space) */
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

void svc_admit_waiting(service *s) {
    sjob *j;
    char why[300];
    TAILQ_FOREACH(j, &s->jobs, link) {
        if (!j->waiting || j->state != SJOB_RUNNING || svc_admit_check(s, j, why, sizeof why) != 0) continue;
        char need[32];
        membudget_format(j->need, need, sizeof need);
        j->waiting = 0;
        j->error[0] = 0;
        svc_log("job %u admitted: its %s fit within --max-memory now", j->desc.id, need);
        store_job_resume(s, j); /* a failure is recorded in the job */
    }
}

static void on_admit_timer(uv_timer_t *t) { svc_admit_waiting(t->data); }

void svc_memory_released(service *s) {
    if (s->stopping || uv_is_closing((uv_handle_t *)&s->admit)) return;
    uv_timer_start(&s->admit, on_admit_timer, 0, 0);
}

void svc_cancel_job(service *s, sjob *j) {
    if (!j->waiting) {
        store_job_cancel(s, j); /* store_on_job_event records the state */
        return;
    }
    char err[600];
    j->waiting = 0;
    j->state = SJOB_CANCELLED;
    j->error[0] = 0;
    j->finished = svc_wall_now();
    if (store_save_job(j, err, sizeof err)) svc_log("job %u: %s", j->desc.id, err);
    svc_log("job %u cancelled while waiting for memory", j->desc.id);
    joblog_add(j->log, j->finished, "cancelled while waiting for memory");
}
