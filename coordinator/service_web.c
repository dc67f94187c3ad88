/* service_web.c - the job service seen by the dashboard (dashboard.h):
 * its jobs as JSON, a running job's frame or a finished job's image, and
 * cancel. The service calls service_web_start once its farm listens. */
#include "service_internal.h"
#include "dashboard.h"

static void web_jobs(void *ctx, cJSON *arr) {
    service *s = ctx;
    sjob *j;
    double now = svc_wall_now();
    TAILQ_FOREACH(j, &s->jobs, link) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddNumberToObject(o, "id", j->desc.id);
        cJSON_AddStringToObject(o, "name", j->name);
        cJSON_AddStringToObject(o, "state", state_names[j->state]);
        cJSON_AddNumberToObject(o, "tiles_done", j->state == SJOB_DONE ? j->tile_count : j->tiles_done);
        cJSON_AddNumberToObject(o, "tiles_total", j->tile_count);
        cJSON_AddNumberToObject(o, "samples", (double)j->stats.samples);
        cJSON_AddNumberToObject(o, "priority", j->priority);
        cJSON_AddNumberToObject(o, "width", j->desc.width);
        cJSON_AddNumberToObject(o, "height", j->desc.height);
        cJSON_AddNumberToObject(o, "spp", j->desc.spp);
        cJSON_AddNumberToObject(o, "submitted", j->submitted);
        cJSON_AddNumberToObject(o, "started", j->started);
        cJSON_AddNumberToObject(o, "finished", j->state == SJOB_RUNNING ? 0 : j->finished);
        cJSON_AddNumberToObject(o, "now", now);
        if (j->error[0]) cJSON_AddStringToObject(o, "error", j->error);
        cJSON_AddItemToArray(arr, o);
    }
}

static int web_frame(void *ctx, uint32_t id, float **rgb, int *w, int *h, int *owned) {
    service *s = ctx;
    sjob *j = store_find_job(s, id);
    if (!j) return -1;
    *w = j->desc.width;
    *h = j->desc.height;
    if (j->rgb && !j->desc.adaptive) {
        *rgb = j->rgb;
        *owned = 0;
        return 0;
    }
    if (j->state != SJOB_DONE) return -1;
    char path[4096], err[300];
    store_job_path(s, id, "pfm", path, sizeof path);
    image img;
    if (image_read(path, &img, err, sizeof err)) return -1;
    *rgb = img.rgb;
    *w = img.width;
    *h = img.height;
    *owned = 1;
    return 0;
}

static int web_cancel(void *ctx, uint32_t id, char *err, size_t err_len) {
    service *s = ctx;
    sjob *j = store_find_job(s, id);
    if (!j) {
        snprintf(err, err_len, "no job %u\n", id);
        return -1;
    }
    if (j->state != SJOB_RUNNING) {
        snprintf(err, err_len, "job %u is already %s\n", id, state_names[j->state]);
        return -1;
    }
    svc_log("job %u cancelled from the dashboard", id);
    svc_cancel_job(s, j);
    return 0;
}

int service_web_start(service *s, char *err, size_t err_len) {
    if (!s->o.http) return 0;
    dashboard_options o = *s->o.http;
    o.auth = &s->o.farm.auth;
    dashboard_source src = {web_jobs, web_frame, web_cancel, s};
    s->web = dashboard_new(&s->loop, s->f, &o, &src, err, err_len);
    if (!s->web) return -1;
    svc_log("dashboard on http://%s:%d/%s", o.host ? o.host : "127.0.0.1", dashboard_port(s->web),
            o.read_only ? " (read-only)" : "");
    return 0;
}

void service_web_stop(service *s) {
    if (s->web) dashboard_close(s->web, NULL, NULL);
    s->web = NULL;
}
