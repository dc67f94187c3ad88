/* service.c - the long-running coordinator (service.h): client connections
 * and their requests (submit, status, workers, cancel, fetch), expiry of
 * old jobs, signals and start-up. The job store is jobstore.c. */
#define _GNU_SOURCE
#include "service_internal.h"
#include "net/address.h"

#include <sodium.h>
#include "paging.h"

void svc_log(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    log_vline(NULL, LOG_INFO, "tessera-coordinator", fmt, ap);
    va_end(ap);
}

double svc_longest_stall_ms(const service *s) { return loopstat_longest_ms(&s->stat); }

double svc_mono_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

double svc_wall_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

static void client_error(client *cl, const char *fmt, ...) __attribute__((format(printf, 2, 3)));

static void client_send_json(client *cl, cJSON *m) {
    size_t len;
    uint8_t *f = m ? wire_frame_json(m, &len) : NULL;
    cJSON_Delete(m);
    if (f) conn_send(cl->c, f, len);
    else client_error(cl, "the answer is larger than a frame (%u bytes) or memory ran out", WIRE_JSON_MAX);
}

static void client_error(client *cl, const char *fmt, ...) {
    char reason[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(reason, sizeof reason, fmt, ap);
    va_end(ap);
    size_t len;
    uint8_t *f = proto_frame_reason("error", reason, &len);
    if (f) conn_send(cl->c, f, len);
}

/* Read an optional integer field within [lo, hi]; -1 when absent. */
static int opt_int(const cJSON *m, const char *key, long lo, long hi, long *out) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(m, key);
    if (!v) return 0;
    if (!cJSON_IsNumber(v) || v->valuedouble != (double)(long)v->valuedouble || v->valuedouble < lo ||
        v->valuedouble > hi)
        return -1;
    *out = (long)v->valuedouble;
    return 0;
}

/* A submit's "seed": a string of 1 to 20 decimal digits within 64 bits
 * (no sign, no space). Returns 0, or -1. */
static int request_seed(const cJSON *v, uint64_t *out) {
    if (!cJSON_IsString(v)) return -1;
    const char *t = v->valuestring;
    size_t n = strlen(t);
    if (n < 1 || n > 20 || strspn(t, "0123456789") != n) return -1;
    errno = 0;
    unsigned long long x = strtoull(t, NULL, 10);
    if (errno == ERANGE) return -1;
    *out = (uint64_t)x;
    return 0;
}

/* The submit fields that are not numbers: name a string, nee/mis booleans.
 * Returns NULL or the fault. */
static const char *request_bad_field(const cJSON *m) {
    const cJSON *v = cJSON_GetObjectItemCaseSensitive(m, "name");
    if (v && (!cJSON_IsString(v) || strlen(v->valuestring) >= 256)) return "name must be a string under 256 bytes";
    v = cJSON_GetObjectItemCaseSensitive(m, "user");
    if (v && (!cJSON_IsString(v) || strlen(v->valuestring) >= 64)) return "user must be a string under 64 bytes";
    v = cJSON_GetObjectItemCaseSensitive(m, "nee");
    if (v && !cJSON_IsBool(v)) return "nee must be true or false";
    v = cJSON_GetObjectItemCaseSensitive(m, "mis");
    if (v && !cJSON_IsBool(v)) return "mis must be true or false";
    return NULL;
}

/* The scene of a submit was checked (upload.h): make the job, or say why
 * not. Frees u; frees cl when it went away meanwhile. */
static void submit_checked(upload *u) {
    client *cl = u->ctx;
    service *s = cl->svc;
    char err[1024], path[4096];
    cl->validating = 0;
    if (cl->closed) {
        free(cl->bundle_mem);
        free(cl);
        upload_free(u);
        return;
    }
    if (!cl->bundle) { /* give the bundle back for the next submit, unless a new one came */
        cl->bundle = u->bundle;
        cl->bundle_mem = u->bundle_mem;
        cl->bundle_len = u->len;
        u->bundle = u->bundle_mem = NULL;
    }
    if (u->rc) {
        client_error(cl, "%s", u->err); /* the scene's own message: file, line, field */
        upload_free(u);
        return;
    }
    const submit_req *q = &cl->req;
    sjob *j = store_job_new(s);
    if (!j) {
        upload_free(u);
        return client_error(cl, "out of memory");
    }
    const render_settings *st = &u->settings;
    j->desc = (proto_job){.id = s->next_id++, .width = st->width, .height = st->height, .spp = st->spp,
                          .max_depth = st->max_depth, .roulette_depth = st->roulette_depth, .seed = st->seed};
    j->desc.integrator.no_nee = q->no_nee;
    j->desc.integrator.no_mis = q->no_mis;
    j->desc.integrator.sampler = q->sampler;
    j->noise_threshold = q->noise_threshold;
    j->min_spp = (int)q->min_spp;
    memcpy(j->desc.scene_hash, u->hash, sizeof u->hash);
    snprintf(j->name, sizeof j->name, "%s", q->name);
    snprintf(j->owner, sizeof j->owner, "%s", cl->name);
    j->priority = (int)q->priority;
    j->tile_size = (int)q->tile_size;
    j->submitted = svc_wall_now();
    snprintf(j->submitter, sizeof j->submitter, "%s%s%s", q->user, q->user[0] ? " at " : "", cl->addr);
    j->tile_count = render_split_tiles(j->desc.width, j->desc.height, j->tile_size, NULL, 0);
    j->need = membudget_job_bytes(j->desc.width, j->desc.height, j->tile_count, u->len);
    int adm = svc_admit_check(s, j, err, sizeof err), rc = adm < 0 ? -1 : 0;
    if (adm == 0) {
        j->rgb = calloc((size_t)j->desc.width * (size_t)j->desc.height * 3, sizeof(float));
        rc = j->rgb ? 0 : -1;
        if (!j->rgb) snprintf(err, sizeof err, "out of memory for a %dx%d image", j->desc.width, j->desc.height);
    } else if (adm > 0) { /* queued: admitted by svc_admit_waiting once it fits; its scene is on disk */
        j->waiting = 1;
        snprintf(j->error, sizeof j->error, "%.500s", err);
    }
    if (rc == 0) rc = store_save_job(j, err, sizeof err);
    if (rc == 0 && adm == 0)
        rc = store_job_start(s, j, u->bundle ? u->bundle : cl->bundle, u->bundle ? u->len : cl->bundle_len, u->blob,
                             err, sizeof err);
    upload_free(u);
    if (rc) {
        svc_log("submit from %s refused: %s", cl->addr, err);
        store_job_path(s, j->desc.id, "json", path, sizeof path);
        unlink(path);
        store_job_unlink_free(s, j);
        return client_error(cl, "%s", err);
    }
    store_job_persist_log(s, j, 0);
    svc_log("job %u submitted from %s: %s, %dx%d, %d spp, priority %d%s%s", j->desc.id, j->submitter, j->name,
            j->desc.width, j->desc.height, j->desc.spp, j->priority, j->waiting ? "; " : "", j->waiting ? j->error : "");
    joblog_add(j->log, j->submitted, "job submitted by %.60s: %.40s, %dx%d, %d spp, %d tiles, priority %d",
               j->submitter, j->name, j->desc.width, j->desc.height, j->desc.spp, j->tile_count, j->priority);
    cJSON *r = cJSON_CreateObject();
    cJSON_AddStringToObject(r, "type", "submitted");
    cJSON_AddNumberToObject(r, "job", j->desc.id);
    cJSON_AddNumberToObject(r, "width", j->desc.width);
    cJSON_AddNumberToObject(r, "height", j->desc.height);
    if (j->waiting) cJSON_AddStringToObject(r, "note", j->error);
    client_send_json(cl, r);
}

/* A submit: every field checked here, on the loop (cheap); the scene is
 * hashed, parsed, validated and stored off the loop (upload.h), then
 * submit_checked makes the job. */
static void on_submit(client *cl, const cJSON *m) {
    service *s = cl->svc;
    const cJSON *h = cJSON_GetObjectItemCaseSensitive(m, "scene"), *name = cJSON_GetObjectItemCaseSensitive(m, "name");
    if (cl->validating) return client_error(cl, "submit: the previous submit's scene is still being checked");
    if (!cl->bundle) return client_error(cl, "submit: no scene was uploaded before it");
    if (!cJSON_IsString(h) || strlen(h->valuestring) != SCENE_BUNDLE_HASH_HEX - 1)
        return client_error(cl, "submit: \"scene\" must be the uploaded scene's hash (%d hex digits)",
                            SCENE_BUNDLE_HASH_HEX - 1);
    long w = -1, ht = -1, spp = -1, depth = -1, roulette = -1, pri = 0, tile = s->o.tile_size, min_spp = 16;
    const struct { const char *key; long lo, hi; long *out; } ints[] = {
        {"width", 1, LIMIT_SIDE, &w}, {"height", 1, LIMIT_SIDE, &ht}, {"spp", 1, LIMIT_SPP, &spp},
        {"max_depth", 1, LIMIT_DEPTH, &depth}, {"roulette_depth", 0, LIMIT_DEPTH, &roulette},
        {"priority", -LIMIT_PRIORITY, LIMIT_PRIORITY, &pri},
        {"tile_size", 1, s->o.farm.max_tile_side, &tile}, {"min_spp", 2, LIMIT_SPP, &min_spp}};
    for (size_t i = 0; i < sizeof ints / sizeof ints[0]; i++)
        if (opt_int(m, ints[i].key, ints[i].lo, ints[i].hi, ints[i].out))
            return client_error(cl, "submit: %s must be an integer from %ld to %ld", ints[i].key, ints[i].lo, ints[i].hi);
    const char *bad = request_bad_field(m);
    if (bad) return client_error(cl, "submit: %s", bad);
    const cJSON *nt = cJSON_GetObjectItemCaseSensitive(m, "noise_threshold");
    if (nt && (!cJSON_IsNumber(nt) || !(nt->valuedouble >= 1e-6 && nt->valuedouble <= 1e6)))
        return client_error(cl, "submit: noise_threshold must be a number from 1e-06 to 1e+06");
    const cJSON *sname = cJSON_GetObjectItemCaseSensitive(m, "sampler");
    sampler_kind sampler = SAMPLER_SOBOL_GLOBAL; /* the default, as tessera render's */
    if (sname && (!cJSON_IsString(sname) || sampler_parse(sname->valuestring, &sampler) != 0))
        return client_error(cl, "submit: sampler must be \"sobol-global\", \"sobol\" or \"random\"");
    /* no intersector: the workers build theirs */
    scene_overrides ov = {.width = (int)w, .height = (int)ht, .spp = (int)spp, .max_depth = (int)depth,
                          .has_roulette_depth = roulette >= 0, .roulette_depth = (int)roulette, .no_accel = 1};
    const cJSON *seed = cJSON_GetObjectItemCaseSensitive(m, "seed");
    if (seed) {
        if (request_seed(seed, &ov.seed))
            return client_error(cl, "submit: seed must be a decimal integer from 0 to 18446744073709551615 "
                                    "in a string, got %.40s%s", cJSON_IsString(seed) ? seed->valuestring : "a non-string",
                                cJSON_IsString(seed) && strlen(seed->valuestring) > 40 ? "..." : "");
        ov.has_seed = 1;
    }
    if (store_running_jobs(s) + upload_queue_length(&s->uploads) >= s->o.max_jobs)
        return client_error(cl, "the queue is full (%d jobs); try again later", s->o.max_jobs);
    upload *u = calloc(1, sizeof *u);
    if (!u) return client_error(cl, "out of memory");
    u->bundle = cl->bundle; /* the upload's now; given back when it ends */
    u->bundle_mem = cl->bundle_mem;
    u->len = cl->bundle_len;
    cl->bundle = cl->bundle_mem = NULL;
    snprintf(u->claimed_hash, sizeof u->claimed_hash, "%s", h->valuestring);
    u->ov = ov;
    snprintf(u->store_path_dir, sizeof u->store_path_dir, "%s/scenes", s->o.data_dir);
    u->done = submit_checked;
    u->ctx = cl;
    cl->req = (submit_req){.priority = pri, .tile_size = tile, .sampler = sampler, .min_spp = min_spp,
                           .noise_threshold = nt ? nt->valuedouble : 0,
                           .no_nee = cJSON_IsFalse(cJSON_GetObjectItemCaseSensitive(m, "nee")),
                           .no_mis = cJSON_IsFalse(cJSON_GetObjectItemCaseSensitive(m, "mis"))};
    snprintf(cl->req.name, sizeof cl->req.name, "%s", cJSON_IsString(name) ? name->valuestring : "scene");
    const cJSON *user = cJSON_GetObjectItemCaseSensitive(m, "user");
    log_escape(cJSON_IsString(user) ? user->valuestring : "", cl->req.user, sizeof cl->req.user);
    cl->validating = 1;
    upload_queue_add(&s->uploads, u);
}

static cJSON *job_status_json(const sjob *j) {
    cJSON *o = cJSON_CreateObject();
    /* Speed and ETA over the time the job rendered: from its first tile
     * handed out (in this run), not from its submission. */
    int queued = j->state == SJOB_RUNNING && j->first_tile == 0;
    double now = svc_wall_now();
    double el = j->first_tile > 0 ? (j->state == SJOB_RUNNING ? now : j->finished) - j->first_tile : 0;
    cJSON_AddNumberToObject(o, "job", j->desc.id);
    cJSON_AddStringToObject(o, "name", j->name);
    if (j->owner[0]) cJSON_AddStringToObject(o, "owner", j->owner);
    cJSON_AddStringToObject(o, "state", queued ? "queued" : state_names[j->state]);
    cJSON_AddNumberToObject(o, "priority", j->priority);
    cJSON_AddNumberToObject(o, "width", j->desc.width);
    cJSON_AddNumberToObject(o, "height", j->desc.height);
    cJSON_AddNumberToObject(o, "spp", j->desc.spp);
    char seed[24];
    snprintf(seed, sizeof seed, "%" PRIu64, j->desc.seed);
    cJSON_AddStringToObject(o, "seed", seed); /* for the header of fetched images */
    cJSON_AddNumberToObject(o, "tiles_done", j->state == SJOB_DONE ? j->tile_count : j->tiles_done);
    cJSON_AddNumberToObject(o, "tiles_total", j->tile_count);
    cJSON_AddNumberToObject(o, "tiles_resumed", j->tiles_resumed);
    double rendered = j->tiles_done - j->tiles_resumed;
    double rate = el > 0 ? (double)j->stats.samples / el : 0;
    cJSON_AddNumberToObject(o, "samples_per_s", rate);
    double left = j->tile_count - j->tiles_done;
    cJSON_AddNumberToObject(o, "eta_s", j->state == SJOB_RUNNING && rendered > 0 ? el / rendered * left : 0);
    cJSON_AddNumberToObject(o, "submitted", j->submitted);
    cJSON_AddStringToObject(o, "submitter", j->submitter);
    if (j->first_tile > 0) cJSON_AddNumberToObject(o, "rendering_since", j->first_tile);
    cJSON_AddStringToObject(o, "error", j->error);
    return o;
}

static void on_status(client *cl, const cJSON *m) {
    service *s = cl->svc;
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(m, "job");
    cJSON *r = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(r, "jobs");
    cJSON_AddStringToObject(r, "type", "status");
    sjob *j;
    TAILQ_FOREACH(j, &s->jobs, link)
        if (!cJSON_IsNumber(id) || id->valuedouble == j->desc.id) cJSON_AddItemToArray(arr, job_status_json(j));
    if (cJSON_IsNumber(id) && cJSON_GetArraySize(arr) == 0) {
        cJSON_Delete(r);
        return client_error(cl, "job %g: unknown job", id->valuedouble);
    }
    farm_worker_info wi[1];
    cJSON_AddNumberToObject(r, "workers", farm_list_workers(s->f, wi, 0));
    cJSON_AddNumberToObject(r, "longest_stall_ms", svc_longest_stall_ms(s));
    cJSON_AddNumberToObject(r, "longest_stall_cpu_ms", loopstat_longest_cpu_ms(&s->stat));
    paging_send(cl->c, r, "jobs"); /* pages when the listing passes a frame */
}

static void on_workers(client *cl) {
    service *s = cl->svc;
    int n = farm_list_workers(s->f, NULL, 0);
    farm_worker_info *wi = calloc((size_t)n + 1, sizeof *wi);
    if (!wi) return client_error(cl, "out of memory");
    n = farm_list_workers(s->f, wi, n);
    cJSON *r = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(r, "workers");
    cJSON_AddStringToObject(r, "type", "workers");
    for (int i = 0; i < n; i++) {
        cJSON *o = cJSON_CreateObject();
        cJSON_AddStringToObject(o, "name", wi[i].name);
        cJSON_AddStringToObject(o, "address", wi[i].addr);
        cJSON_AddNumberToObject(o, "threads", wi[i].threads);
        cJSON_AddNumberToObject(o, "tiles", (double)wi[i].tiles);
        cJSON_AddNumberToObject(o, "samples_per_s", wi[i].connected_s > 0 ? (double)wi[i].samples / wi[i].connected_s : 0);
        cJSON_AddNumberToObject(o, "last_seen_s", wi[i].silent_s);
        cJSON_AddBoolToObject(o, "stalled", wi[i].stalled);
        cJSON_AddNumberToObject(o, "quarantined", wi[i].quarantined); /* jobs whose audit it failed */
        cJSON_AddNumberToObject(o, "blocklisted", wi[i].blocklisted); /* running jobs it may not take now */
        cJSON_AddNumberToObject(o, "retry_s", wi[i].retry_s);
        cJSON_AddItemToArray(arr, o);
    }
    free(wi);
    paging_send(cl->c, r, "workers");
}

static sjob *request_job(client *cl, const cJSON *m, const char *type) {
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(m, "job");
    sjob *j = cJSON_IsNumber(id) && id->valuedouble >= 0 ? store_find_job(cl->svc, (uint32_t)id->valuedouble) : NULL;
    if (!cJSON_IsNumber(id))
        client_error(cl, "%s: expected a job number", type);
    else if (!j)
        client_error(cl, "job %g: unknown job", id->valuedouble);
    return j;
}

/* Whether cl may cancel, reprioritise or fetch j: its own job, or any with the admin
 * token (or without tokens); refused with a logged reason otherwise. */
static int owner_ok(client *cl, const sjob *j, const char *type) {
    if (cl->cls == AUTH_ADMIN || !j->owner[0] || strcmp(j->owner, cl->name) == 0) return 1;
    svc_log("client %s (%s, %s token): %s of job %u refused: it belongs to %s", cl->addr, cl->name,
            auth_class_name(cl->cls), type, j->desc.id, j->owner);
    client_error(cl, "job %u belongs to client %s: only it, or a client with the admin token, may %s it", j->desc.id,
                 j->owner, type);
    return 0;
}

static void on_cancel(client *cl, const cJSON *m) {
    sjob *j = request_job(cl, m, "cancel");
    if (!j || !owner_ok(cl, j, "cancel")) return;
    char why[200];
    if (svc_cancel_refused(j, why, sizeof why)) return client_error(cl, "%s", why);
    joblog_add(j->log, svc_wall_now(), "cancel asked by the client at %s", cl->addr);
    svc_cancel_job(cl->svc, j);
    cJSON *r = cJSON_CreateObject();
    cJSON_AddStringToObject(r, "type", "cancelled");
    cJSON_AddNumberToObject(r, "job", j->desc.id);
    client_send_json(cl, r);
}

/* priority: job, priority. Answered with the job's new priority. */
static void on_priority(client *cl, const cJSON *m) {
    sjob *j = request_job(cl, m, "priority");
    if (!j || !owner_ok(cl, j, "reprioritise")) return;
    long pri = 0;
    char err[600], who[128];
    if (!cJSON_GetObjectItemCaseSensitive(m, "priority") || opt_int(m, "priority", -LIMIT_PRIORITY, LIMIT_PRIORITY, &pri))
        return client_error(cl, "priority: priority must be an integer from %d to %d", -LIMIT_PRIORITY, LIMIT_PRIORITY);
    snprintf(who, sizeof who, "the client at %s", cl->addr);
    if (store_set_priority(cl->svc, j->desc.id, pri, who, err, sizeof err)) return client_error(cl, "%s", err);
    cJSON *r = cJSON_CreateObject();
    cJSON_AddStringToObject(r, "type", "priority");
    cJSON_AddNumberToObject(r, "job", j->desc.id);
    cJSON_AddNumberToObject(r, "priority", j->priority);
    client_send_json(cl, r);
}

/* logs: job, optional last (at most that many of the newest lines).
 * Answered with logs: job, state, dropped, lines (paged). */
static void on_logs(client *cl, const cJSON *m) {
    sjob *j = request_job(cl, m, "logs");
    if (!j) return;
    long last = 0;
    if (opt_int(m, "last", 1, JOBLOG_MAX, &last))
        return client_error(cl, "logs: last must be an integer from 1 to %d", JOBLOG_MAX);
    cJSON *r = cJSON_CreateObject();
    cJSON_AddStringToObject(r, "type", "logs");
    cJSON_AddNumberToObject(r, "job", j->desc.id);
    cJSON_AddStringToObject(r, "state", state_names[j->state]);
    if (joblog_to_json(j->log, r, (int)last)) {
        cJSON_Delete(r);
        return client_error(cl, "out of memory");
    }
    paging_send(cl->c, r, "lines");
}

/* fetch with "partial": the tiles journaled so far of a running or
 * cancelled job (the others black), made into a PFM and streamed as a
 * finished image is (fetch.h), after a "partial" message naming the
 * missing tiles; of any size, and off the loop. */
static void fetch_partial(client *cl, sjob *j) {
    service *s = cl->svc;
    if (j->noise_threshold > 0)
        return client_error(cl, "job %u samples adaptively: its rounds cover the whole image, which exists only "
                                "once the last round has ended (no partial image)", j->desc.id);
    if (cl->fetch) return client_error(cl, "fetch: this connection is already receiving an image");
    char journal[4096], tmp[4200], name[64];
    store_job_path(s, j->desc.id, "tiles", journal, sizeof journal);
    snprintf(name, sizeof name, "partial-%llu.pfm", (unsigned long long)s->next_partial++);
    store_job_path(s, j->desc.id, name, tmp, sizeof tmp);
    fetch_partial_spec p = {journal, state_names[j->state], j->desc.width, j->desc.height, j->tile_size, j->tile_count};
    if (fetch_start_partial(&s->loop, cl->c, j->desc.id, &p, tmp, s->fetch_chunk, &cl->fetch))
        client_error(cl, "out of memory");
}

static void on_fetch(client *cl, const cJSON *m) {
    sjob *j = request_job(cl, m, "fetch");
    if (!j || !owner_ok(cl, j, "fetch")) return;
    int unfinished = j->state == SJOB_RUNNING || j->state == SJOB_CANCELLED;
    if (unfinished && cJSON_IsTrue(cJSON_GetObjectItemCaseSensitive(m, "partial"))) return fetch_partial(cl, j);
    if (j->state != SJOB_DONE)
        return client_error(cl, "job %u is %s (%d of %d tiles)%s%s%s", j->desc.id, state_names[j->state], j->tiles_done,
                            j->tile_count, j->error[0] ? ": " : "", j->error,
                            unfinished ? "; fetch --partial writes what is done so far" : "");
    if (cl->fetch) return client_error(cl, "fetch: this connection is already receiving an image");
    char path[4096];
    store_job_path(cl->svc, j->desc.id, "pfm", path, sizeof path);
    if (fetch_start(&cl->svc->loop, cl->c, j->desc.id, path, cl->svc->fetch_chunk, &cl->fetch))
        client_error(cl, "out of memory");
}

static int client_on_frame(conn *c, int kind, const uint8_t *body, size_t len) {
    client *cl = conn_data(c);
    cl->last_frame = svc_mono_now();
    if (kind == WIRE_KIND_SCENE) {
        free(cl->bundle_mem);
        /* Keep the frame's own memory as it is: the bundle lies inside it,
         * so the loop thread neither copies nor moves its bytes. */
        uint8_t *mem = conn_take_frame(c);
        if (mem && body == mem + WIRE_HEADER_BYTES) {
            cl->bundle_mem = mem;
            cl->bundle = mem + WIRE_HEADER_BYTES;
        } else {
            cl->bundle = cl->bundle_mem = malloc(len ? len : 1);
            if (cl->bundle) memcpy(cl->bundle, body, len);
            free(mem); /* after the copy: body may lie in it */
        }
        if (!cl->bundle) {
            client_error(cl, "out of memory for a %zu-byte scene", len);
            conn_close(c, "out of memory", 1);
            return 1;
        }
        cl->bundle_len = len;
        return 0;
    }
    char err[256];
    const char *type;
    cJSON *m = kind == WIRE_KIND_JSON ? proto_parse_json(body, len, &type, err, sizeof err) : NULL;
    if (!m) {
        if (kind != WIRE_KIND_JSON) snprintf(err, sizeof err, "unexpected frame kind 0x%02x", kind);
        svc_log("client %s: %s; disconnecting", cl->addr, err);
        client_error(cl, "%s", err);
        conn_close(c, err, 1);
        return 1;
    }
    if (strcmp(type, "submit") == 0) on_submit(cl, m);
    else if (strcmp(type, "status") == 0) on_status(cl, m);
    else if (strcmp(type, "workers") == 0) on_workers(cl);
    else if (strcmp(type, "cancel") == 0) on_cancel(cl, m);
    else if (strcmp(type, "fetch") == 0) on_fetch(cl, m);
    else if (strcmp(type, "priority") == 0) on_priority(cl, m);
    else if (strcmp(type, "logs") == 0) on_logs(cl, m);
    else client_error(cl, "unknown request \"%.40s\"", type);
    cJSON_Delete(m);
    return 0;
}

static void client_on_close(conn *c, const char *reason) {
    client *cl = conn_data(c);
    fetch_detach(&cl->fetch);
    if (conn_malformed(c)) svc_log("client %s: %s; disconnecting", cl->addr, reason);
    free(cl->bundle_mem);
    cl->bundle = cl->bundle_mem = NULL;
    TAILQ_REMOVE(&cl->svc->clients, cl, link);
    farm_client_closed(cl->svc->f, cl->addr); /* no longer counts against --max-per-address */
    if (cl->validating) { /* its scene is being checked: freed by submit_checked */
        cl->closed = 1;
        return;
    }
    free(cl);
}

static const conn_callbacks client_cbs = {client_on_frame, client_on_close};

static void on_client(void *ctx, conn *c, const cJSON *hello, const char *addr, auth_class cls) {
    service *s = ctx;
    client *cl = calloc(1, sizeof *cl);
    if (!cl) {
        conn_close(c, "out of memory", 0);
        return;
    }
    cl->svc = s;
    cl->c = c;
    snprintf(cl->addr, sizeof cl->addr, "%s", addr);
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(hello, "name");
    snprintf(cl->name, sizeof cl->name, "%s", cJSON_IsString(name) ? name->valuestring : "?");
    cl->cls = auth_keyring_enabled(&s->o.farm.auth) ? cls : AUTH_ADMIN;
    const auth_key *k = auth_key_of(&s->o.farm.auth, cl->cls, cl->name); /* NULL without tokens */
    if ((cl->keyed = k != NULL)) memcpy(cl->key, k->key, sizeof cl->key);
    cl->last_bytes = cl->last_frame = cl->window_start = svc_mono_now();
    cl->seen_bytes = conn_bytes_in(c);
    TAILQ_INSERT_TAIL(&s->clients, cl, link);
    conn_set_callbacks(c, &client_cbs, cl);
    conn_set_max_frame(c, s->o.max_upload + 1);
    cJSON *w = cJSON_CreateObject();
    cJSON_AddStringToObject(w, "type", "welcome");
    cJSON_AddNumberToObject(w, "protocol", PROTOCOL_VERSION);
    cJSON_AddStringToObject(w, "build", protocol_build_id());
    cJSON_AddNumberToObject(w, "max_upload", (double)s->o.max_upload);
    farm_add_proof(s->f, cls, hello, w);
    client_send_json(cl, w);
}

static void on_expiry(uv_timer_t *t) {
    service *s = t->data;
    if (retention_sweep(s)) uv_timer_start(&s->expiry, on_expiry, 100, 2000); /* a backlog: soon again */
}

#define TRICKLE_WINDOW_S 10.0
#define TRICKLE_MIN_BYTES 1024 /* a frame in progress must grow by this much per window */

/* Close clients that are idle (no request and no byte for
 * --client-timeout; one whose submit is being checked or that is receiving
 * an image is busy, not idle)
 * or that trickle a frame (less than TRICKLE_MIN_BYTES in TRICKLE_WINDOW_S,
 * or in --client-timeout when that is shorter). Each close is logged once, naming the client. */
static void on_sweep(uv_timer_t *t) {
    service *s = t->data;
    double now = svc_mono_now(), limit = s->o.client_timeout_s > 0 ? s->o.client_timeout_s : 30;
    client *cl, *next;
    TAILQ_FOREACH_SAFE(cl, &s->clients, link, next) {
        uint64_t in = conn_bytes_in(cl->c);
        if (in != cl->seen_bytes) cl->last_bytes = now;
        cl->window_bytes += in - cl->seen_bytes;
        cl->seen_bytes = in;
        const char *why = NULL;
        char reason[160];
        if (!cl->validating && !cl->fetch && now - cl->last_bytes > limit) {
            snprintf(reason, sizeof reason, "idle for %.0f s (--client-timeout)", now - cl->last_bytes);
            why = reason;
        } else if (conn_pending(cl->c) == 0) { /* between frames: the trickle window starts with the next one */
            cl->window_bytes = 0;
            cl->window_start = now;
        } else if (now - cl->window_start >= (limit < TRICKLE_WINDOW_S ? limit : TRICKLE_WINDOW_S)) {
            if (cl->window_bytes < TRICKLE_MIN_BYTES) {
                snprintf(reason, sizeof reason, "sent %" PRIu64 " bytes of a frame in %.0f s (under %d bytes per %.0f s)",
                         cl->window_bytes, now - cl->window_start, TRICKLE_MIN_BYTES, TRICKLE_WINDOW_S);
                why = reason;
            }
            cl->window_bytes = 0;
            cl->window_start = now;
        }
        if (why) {
            svc_log("client %s closed: %s", cl->addr, why);
            client_error(cl, "closing the connection: %s", why);
            conn_close(cl->c, why, 1);
        }
    }
}

static void on_stat_timer(uv_timer_t *t) {
    service *s = t->data;
    svc_log("loop: longest iteration %.1f ms in the last 10 s (%.1f ms since the start)", loopstat_take_window(&s->stat),
            loopstat_longest_ms(&s->stat));
}

static void on_farm_closed(void *ctx) {
    service *s = ctx;
    svc_log("loop: longest iteration %.1f ms since the start (%.1f ms of CPU)", loopstat_longest_ms(&s->stat),
            loopstat_longest_cpu_ms(&s->stat));
    loopstat_stop(&s->stat);
    uv_close((uv_handle_t *)&s->stat_timer, NULL);
    uv_close((uv_handle_t *)&s->sweep, NULL);
    uv_close((uv_handle_t *)&s->admit, NULL);
    uv_close((uv_handle_t *)&s->expiry, NULL);
    uv_close((uv_handle_t *)&s->sigint, NULL);
    uv_close((uv_handle_t *)&s->sigterm, NULL);
    uv_close((uv_handle_t *)&s->sighup, NULL);
}

/* After SIGHUP: a client whose token is no longer in the ring (a user
 * whose file was deleted, a client or admin token replaced) is told so and
 * its link closed: revoking a token cuts its holder off at once. Workers
 * keep their links (their tiles in flight would be lost; a worker's token
 * is rotated, not revoked). */
static void close_revoked_clients(service *s) {
    client *cl, *next;
    TAILQ_FOREACH_SAFE(cl, &s->clients, link, next) {
        const auth_key *k = auth_key_of(&s->o.farm.auth, cl->cls, cl->name); /* the key it needs now */
        if (!cl->keyed || (k && sodium_memcmp(k->key, cl->key, sizeof cl->key) == 0)) continue;
        svc_log("SIGHUP: client %s at %s: its %s token is gone; link closed", cl->name, cl->addr,
                auth_class_name(cl->cls));
        client_error(cl, "your token was revoked or replaced (SIGHUP): connect again with the current one");
        conn_close(cl->c, "its token was revoked", 1);
    }
}

/* SIGHUP: re-read the dashboard's certificate and key, and the token
 * files. New connections need the new tokens;
 * worker links already authenticated keep going (their links are sealed
 * with session keys, which do not depend on the token any more); a client
 * link whose token is gone is closed (close_revoked_clients), and a
 * dashboard session whose token is gone ends (dashboard.c looks its token
 * up on every request). A file that cannot be read keeps
 * every old token (logged). */
static void on_sighup(uv_signal_t *h, int signum) {
    (void)signum;
    service *s = h->data;
    char err[600], which[64] = "";
    if (s->web) { /* a renewed dashboard certificate */
        int rc = dashboard_reload_tls(s->web, err, sizeof err);
        if (rc > 0) svc_log("SIGHUP: dashboard certificate re-read (%s); new connections get it", err);
        else if (rc < 0) svc_log("SIGHUP: %s; the dashboard keeps its previous certificate", err);
    }
    if (!auth_keyring_enabled(&s->o.farm.auth)) {
        svc_log("SIGHUP: no token files to re-read");
        return;
    }
    if (auth_keyring_reload(&s->o.farm.auth, err, sizeof err)) {
        svc_log("SIGHUP: %s; keeping the previous tokens", err);
        return;
    }
    farm_set_auth(s->f, &s->o.farm.auth);
    close_revoked_clients(s);
    for (int c = AUTH_WORKER; c < AUTH_CLASSES; c++)
        if (s->o.farm.auth.paths[c])
            snprintf(which + strlen(which), sizeof which - strlen(which), "%s%s", which[0] ? ", " : "",
                     auth_class_name((auth_class)c));
    if (s->o.farm.auth.users_dir)
        snprintf(which + strlen(which), sizeof which - strlen(which), "%s%d users", which[0] ? ", " : "",
                 s->o.farm.auth.user_count);
    svc_log("SIGHUP: token files re-read (%s); new connections need the new tokens, open worker links go on", which);
}

static void on_signal(uv_signal_t *h, int signum) {
    service *s = h->data;
    if (s->stopping) return;
    s->stopping = 1;
    svc_log("%s: stopping; running jobs resume at the next start", signum == SIGINT ? "SIGINT" : "SIGTERM");
    client *cl, *next; /* a connected client must not keep the process alive */
    TAILQ_FOREACH_SAFE(cl, &s->clients, link, next) {
        client_error(cl, "the coordinator is stopping (%s)", signum == SIGINT ? "SIGINT" : "SIGTERM");
        conn_close(cl->c, "the coordinator is stopping", 1);
    }
    service_web_stop(s);
    farm_close(s->f, on_farm_closed, s);
}

/* Create DIR, DIR/scenes, DIR/jobs and check that files can be written. */
static int prepare_data_dir(const char *dir, char *err, size_t err_len) {
    char path[4096];
    const char *subs[] = {"", "/scenes", "/jobs"};
    for (int i = 0; i < 3; i++) {
        snprintf(path, sizeof path, "%s%s", dir, subs[i]);
        if (mkdir(path, 0755) != 0 && errno != EEXIST) {
            snprintf(err, err_len, "%.400s: cannot create the data dir: %s", path, strerror(errno));
            return -1;
        }
    }
    snprintf(path, sizeof path, "%s/.probe", dir);
    if (file_write_atomic(path, "ok", 2, err, err_len)) return -1;
    unlink(path);
    return 0;
}

int service_run(const service_options *o) {
    service *s = calloc(1, sizeof *s);
    char err[600];
    if (!s) return 1;
    TAILQ_INIT(&s->jobs);
    TAILQ_INIT(&s->clients);
    s->o = *o;
    s->next_id = 1;
    s->fetch_chunk = fetch_chunk_size();
    char how[160] = "--max-memory";
    if (!s->o.max_memory) s->o.max_memory = membudget_default(how, sizeof how);
    if (prepare_data_dir(o->data_dir, err, sizeof err) || data_dir_lock(o->data_dir, err, sizeof err) < 0) {
        fprintf(stderr, "tessera-coordinator: %s\n", err);
        free(s);
        return 1;
    }
    signal(SIGXFSZ, SIG_IGN); /* a file-size limit is a write error to report, not a reason to die */
    uv_loop_init(&s->loop);
    if (loopstat_start(&s->loop, &s->stat)) svc_log("loop: cannot measure its iterations; stalls go unreported");
    s->o.farm.on_client = on_client;
    s->o.farm.client_ctx = s;
    double idle = s->o.client_timeout_s > 0 ? s->o.client_timeout_s : 30;
    if (s->o.farm.hello_timeout_s <= 0) s->o.farm.hello_timeout_s = idle < 10 ? idle : 10;
    int reserve = 64 + 2 * s->o.max_jobs; /* stdio, listeners, data files, a journal per running job */
    long nofile = connlimit_defaults(&s->o.farm.limits, reserve);
    if (s->o.farm.limits.max_total > nofile - reserve)
        svc_log("warning: --max-connections %d leaves under %d of the %ld descriptors (RLIMIT_NOFILE) for files; "
                "raise `ulimit -n` or lower it", s->o.farm.limits.max_total, reserve, nofile);
    s->f = farm_new(&s->loop, &s->o.farm, err, sizeof err);
    if (!s->f) {
        fprintf(stderr, "tessera-coordinator: %s\n", err);
        loopstat_stop(&s->stat); /* else the loop stays busy and its memory leaks (LeakSanitizer) */
        uv_run(&s->loop, UV_RUN_DEFAULT);
        uv_loop_close(&s->loop);
        free(s);
        return 1;
    }
    char where[300];
    address_format(o->farm.host, farm_port(s->f), where, sizeof where);
    svc_log("listening on %s, data in %s", where, o->data_dir);
    farm_set_event_cb(s->f, service_on_farm_event, s); /* the jobs' logs, and the dashboard's events */
    svc_log("connections: at most %d in all (--max-connections), %d per address before a worker hello or as "
            "clients (--max-per-address), %d workers per address (--max-workers-per-address); idle ones close after "
            "%.1f s before a hello, %.1f s as clients", s->o.farm.limits.max_total, s->o.farm.limits.max_open,
            s->o.farm.limits.max_workers, s->o.farm.hello_timeout_s, idle);
    char budget[32];
    membudget_format(s->o.max_memory, budget, sizeof budget);
    svc_log("memory: jobs are admitted while their frames and scenes fit in %s (%s)", budget, how);
    if (service_web_start(s, err, sizeof err)) {
        fprintf(stderr, "tessera-coordinator: %s\n", err);
        farm_close(s->f, NULL, NULL);
        loopstat_stop(&s->stat);
        uv_run(&s->loop, UV_RUN_DEFAULT);
        farm_free(s->f);
        uv_loop_close(&s->loop);
        free(s);
        return 1;
    }
    uv_timer_init(&s->loop, &s->admit); /* before the jobs: a failed resume releases memory */
    s->admit.data = s;
    store_load_jobs(s);
    svc_admit_waiting(s); /* the jobs that fit resume, their journals replayed on the pool while the loop serves */
    upload_queue_init(&s->uploads, &s->loop);
    uv_signal_init(&s->loop, &s->sigint);
    uv_signal_init(&s->loop, &s->sigterm);
    s->sigint.data = s->sigterm.data = s;
    uv_signal_start(&s->sigint, on_signal, SIGINT);
    uv_signal_start(&s->sigterm, on_signal, SIGTERM);
    uv_signal_init(&s->loop, &s->sighup);
    s->sighup.data = s;
    uv_signal_start(&s->sighup, on_sighup, SIGHUP);
    uv_timer_init(&s->loop, &s->expiry);
    s->expiry.data = s;
    uv_timer_start(&s->expiry, on_expiry, 1000, 2000);
    uv_timer_init(&s->loop, &s->stat_timer);
    s->stat_timer.data = s;
    if (o->farm.verbose) uv_timer_start(&s->stat_timer, on_stat_timer, 10000, 10000);
    uv_timer_init(&s->loop, &s->sweep);
    s->sweep.data = s;
    uv_timer_start(&s->sweep, on_sweep, 1000, 1000);
    uv_run(&s->loop, UV_RUN_DEFAULT);
    farm_free(s->f);
    while (!TAILQ_EMPTY(&s->jobs)) store_job_unlink_free(s, TAILQ_FIRST(&s->jobs));
    uv_run(&s->loop, UV_RUN_NOWAIT); /* the close callbacks of the jobs' journals and timers */
    uv_loop_close(&s->loop);
    free(s);
    return 0;
}
