/* service_web.c - the job service seen by watchers: the farm's events into
 * each job's log (joblog.h) and on to the dashboard (dashboard.h), and the
 * dashboard's view of the service: its jobs as JSON, a running job's frame
 * or a finished job's image, its log, cancel and priority. The service
 * calls service_web_start once its farm listens. */
#include "service_internal.h"

#include <unistd.h>
#include "dashboard.h"
#include "net/address.h"

static void web_jobs(void *ctx, cJSON *arr) {
    service *s = ctx;
    sjob *j;
    double now = svc_wall_now();
    TAILQ_FOREACH(j, &s->jobs, link) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddNumberToObject(o, "id", j->desc.id);
        cJSON_AddStringToObject(o, "name", j->name);
        int queued = j->state == SJOB_RUNNING && j->first_tile == 0; /* as `tessera status` says */
        cJSON_AddStringToObject(o, "state", queued ? "queued" : state_names[j->state]);
        cJSON_AddNumberToObject(o, "tiles_done", j->state == SJOB_DONE ? j->tile_count : j->tiles_done);
        cJSON_AddNumberToObject(o, "tiles_total", j->tile_count);
        cJSON_AddNumberToObject(o, "samples", (double)j->stats.samples);
        cJSON_AddNumberToObject(o, "priority", j->priority);
        cJSON_AddNumberToObject(o, "width", j->desc.width);
        cJSON_AddNumberToObject(o, "height", j->desc.height);
        cJSON_AddNumberToObject(o, "spp", j->desc.spp);
        cJSON_AddNumberToObject(o, "submitted", j->submitted);
        cJSON_AddStringToObject(o, "submitter", j->submitter);
        if (j->owner[0]) cJSON_AddStringToObject(o, "owner", j->owner);
        cJSON_AddNumberToObject(o, "started", j->started);
        cJSON_AddNumberToObject(o, "finished", j->state == SJOB_RUNNING ? 0 : j->finished);
        cJSON_AddNumberToObject(o, "now", now);
        if (j->error[0]) cJSON_AddStringToObject(o, "error", j->error);
        cJSON_AddItemToArray(arr, o);
    }
}

/* The path of the job's saved image, jobs/ID.pfm, when it is there (and,
 * with done_only, the job done): the dashboard reads it off the loop. */
static int web_image_file(void *ctx, uint32_t id, int done_only, char *path, size_t len) {
    service *s = ctx;
    sjob *j = store_find_job(s, id);
    if (!j || (done_only && j->state != SJOB_DONE)) return -1;
    store_job_path(s, id, "pfm", path, len);
    return access(path, R_OK) == 0 ? 0 : -1;
}

static int web_frame(void *ctx, uint32_t id, float **rgb, int *w, int *h) {
    service *s = ctx;
    sjob *j = store_find_job(s, id);
    if (!j || !j->rgb || j->desc.adaptive) return -1; /* then the saved image, if any */
    *w = j->desc.width;
    *h = j->desc.height;
    *rgb = j->rgb;
    return 0;
}

static int web_cancel(void *ctx, uint32_t id, char *err, size_t err_len) {
    service *s = ctx;
    sjob *j = store_find_job(s, id);
    if (!j) {
        snprintf(err, err_len, "no job %u\n", id);
        return -1;
    }
    char why[200];
    if (svc_cancel_refused(j, why, sizeof why)) {
        snprintf(err, err_len, "%s\n", why);
        return -1;
    }
    svc_log("job %u cancelled from the dashboard", id);
    joblog_add(j->log, svc_wall_now(), "cancel asked from the dashboard");
    svc_cancel_job(s, j);
    return 0;
}

static int web_priority(void *ctx, uint32_t id, int priority, char *err, size_t err_len) {
    return store_set_priority(ctx, id, priority, "the dashboard", err, err_len);
}

static int web_owner(void *ctx, uint32_t id, char *owner, size_t len) {
    sjob *j = store_find_job(ctx, id);
    if (!j) return -1;
    snprintf(owner, len, "%s", j->owner);
    return 0;
}

static int web_log(void *ctx, uint32_t id, int last, cJSON *out) {
    sjob *j = store_find_job(ctx, id);
    return j ? joblog_to_json(j->log, out, last) : -1;
}

void service_on_farm_event(void *ctx, const farm_event *e) {
    service *s = ctx;
    double now = svc_wall_now();
    if (e->kind == FARM_EV_JOIN || e->kind == FARM_EV_LEAVE) {
        sjob *j;
        TAILQ_FOREACH(j, &s->jobs, link)
            if (j->state == SJOB_RUNNING) joblog_add_event(j->log, now, e);
    } else {
        sjob *j = store_find_farm_job(s, e->job); /* an adaptive job's round has a farm id of its own */
        if (j) {
            joblog_add_event(j->log, now, e);
            farm_event named = *e; /* the dashboard knows the job by its service id, not the round's */
            named.job = j->desc.id;
            if (s->web) dashboard_farm_event(s->web, &named);
            return;
        }
    }
    if (s->web) dashboard_farm_event(s->web, e);
}

int service_web_start(service *s, char *err, size_t err_len) {
    if (!s->o.http) return 0;
    dashboard_options o = *s->o.http;
    o.auth = &s->o.farm.auth;
    dashboard_source src = {.jobs = web_jobs, .frame = web_frame, .image_file = web_image_file, .cancel = web_cancel,
                            .priority = web_priority, .log = web_log, .owner = web_owner, .forwards_events = 1,
                            .ctx = s};
    s->web = dashboard_new(&s->loop, s->f, &o, &src, err, err_len);
    if (!s->web) return -1;
    char where[300];
    address_format(o.host ? o.host : "127.0.0.1", dashboard_port(s->web), where, sizeof where);
    svc_log("dashboard on %s://%s/%s", dashboard_scheme(s->web), where, o.read_only ? " (read-only)" : "");
    char what[400];
    if (dashboard_tls_describe(s->web, what, sizeof what)) svc_log("dashboard certificate: %s", what);
    else if (o.host && !address_is_loopback(o.host))
        svc_log("warning: the dashboard on %s is plain HTTP beyond loopback: its token and pixels cross the network "
                "in clear; give --http-cert and --http-key, or keep it on loopback behind a TLS proxy", o.host);
    return 0;
}

void service_web_stop(service *s) {
    if (s->web) dashboard_close(s->web, NULL, NULL);
    s->web = NULL;
}
