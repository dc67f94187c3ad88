/* jobstore.c - the job store and its journal (layout in service_internal.h):
 * jobs written whole, tiles appended and synced before they count, the
 * farm's callbacks that journal and finish jobs, and the restart that reads
 * it all back. */
#define _GNU_SOURCE
#include "service_internal.h"
#include "render/adaptive.h"
#include <math.h>
#include <time.h>
#include <unistd.h>

void store_job_path(const service *s, uint32_t id, const char *ext, char *out, size_t n) {
    snprintf(out, n, "%s/jobs/%u.%s", s->o.data_dir, id, ext);
}

int store_save_job(sjob *j, char *err, size_t err_len) {
    char seed[32], path[4096];
    snprintf(seed, sizeof seed, "%" PRIu64, j->desc.seed);
    cJSON *m = cJSON_CreateObject();
    cJSON_AddNumberToObject(m, "job", j->desc.id);
    cJSON_AddStringToObject(m, "name", j->name);
    if (j->owner[0]) cJSON_AddStringToObject(m, "owner", j->owner);
    cJSON_AddStringToObject(m, "scene", j->desc.scene_hash);
    cJSON_AddNumberToObject(m, "width", j->desc.width);
    cJSON_AddNumberToObject(m, "height", j->desc.height);
    cJSON_AddNumberToObject(m, "spp", j->desc.spp);
    cJSON_AddNumberToObject(m, "max_depth", j->desc.max_depth);
    cJSON_AddNumberToObject(m, "roulette_depth", j->desc.roulette_depth);
    cJSON_AddStringToObject(m, "seed", seed);
    cJSON_AddBoolToObject(m, "nee", !j->desc.integrator.no_nee);
    cJSON_AddBoolToObject(m, "mis", !j->desc.integrator.no_mis);
    cJSON_AddStringToObject(m, "sampler", sampler_name(j->desc.integrator.sampler));
    cJSON_AddNumberToObject(m, "priority", j->priority);
    cJSON_AddNumberToObject(m, "tile_size", j->tile_size);
    if (j->noise_threshold > 0) {
        cJSON_AddNumberToObject(m, "noise_threshold", j->noise_threshold);
        cJSON_AddNumberToObject(m, "min_spp", j->min_spp);
    }
    cJSON_AddStringToObject(m, "state", state_names[j->state]);
    cJSON_AddStringToObject(m, "error", j->error);
    cJSON_AddNumberToObject(m, "submitted", j->submitted);
    cJSON_AddStringToObject(m, "submitter", j->submitter);
    cJSON_AddNumberToObject(m, "finished", j->finished);
    if (j->first_tile > 0) cJSON_AddNumberToObject(m, "rendering_since", j->first_tile);
    char *text = cJSON_Print(m);
    cJSON_Delete(m);
    store_job_path(j->svc, j->desc.id, "json", path, sizeof path);
    int rc = text ? file_write_atomic(path, text, strlen(text), err, err_len) : -1;
    if (!text) snprintf(err, err_len, "out of memory");
    free(text);
    return rc;
}

static void on_save_timer_closed(uv_handle_t *h);

static void store_job_release(sjob *j) {
    if (j->save_timer) uv_close((uv_handle_t *)j->save_timer, on_save_timer_closed);
    j->save_timer = NULL;
    if (j->round_timer) uv_close((uv_handle_t *)j->round_timer, on_save_timer_closed);
    j->round_timer = NULL;
    adaptive_free(j->ad);
    free(j->sums);
    free(j->mask);
    free(j->skip);
    conn_blob_unref(j->scene);
    j->scene = NULL;
    j->ad = NULL;
    j->sums = NULL;
    j->mask = j->skip = NULL;
    if (j->rgb) svc_memory_released(j->svc); /* its need no longer counts (svc_memory_in_use) */
    free(j->rgb);
    free(j->journaled);
    j->rgb = NULL;
    j->journaled = NULL;
    tjournal_close(j->journal);
    j->journal = NULL;
}

sjob *store_find_job(service *s, uint32_t id) {
    sjob *j;
    TAILQ_FOREACH(j, &s->jobs, link)
        if (j->desc.id == id) return j;
    return NULL;
}

sjob *store_find_farm_job(service *s, uint32_t farm_id) {
    sjob *j;
    TAILQ_FOREACH(j, &s->jobs, link)
        if (j->farm_id == farm_id) return j;
    return NULL;
}

/* A batch of the job's journal ended (tjournal_cb): its tiles count now,
 * or the job fails naming the journal and the fault. */
static void store_on_batch(void *ctx, const uint32_t *tiles, int n, int error) {
    sjob *j = ctx;
    service *s = j->svc;
    uint32_t id = j->desc.id;
    char msg[600], path[4096];
    if (error) {
        store_job_path(s, id, "tiles", path, sizeof path);
        snprintf(msg, sizeof msg, "%.400s: cannot journal tile %u: %s", path, tiles[0], strerror(error));
    }
    for (int i = 0; i < n && j->state == SJOB_RUNNING && j->journal; i++) {
        j->tiles_done += !error;
        farm_tile_durable(s->f, id, tiles[i], error ? msg : NULL); /* may end the job */
    }
}

/* Queue a finished tile's record in the journal: the farm counts the tile
 * when its batch is synced (store_on_batch). */
static int store_on_tile_done(void *ctx, uint32_t tile, const tile_rect *r, char *err, size_t err_len) {
    sjob *j = ctx;
    size_t w = (size_t)tile_width(r), n = 3 * w * (size_t)tile_height(r);
    size_t len = JOURNAL_RECORD_OVERHEAD + 4 * n;
    uint8_t *rec = malloc(len);
    float *px = malloc(4 * n);
    if (!rec || !px) {
        free(rec);
        free(px);
        snprintf(err, err_len, "out of memory journaling tile %u", tile);
        return -1;
    }
    wire_put_u32(rec, JOURNAL_MAGIC);
    wire_put_u32(rec + 4, tile);
    wire_put_u32(rec + 8, (uint32_t)n);
    for (int y = r->y0; y < r->y1; y++)
        memcpy(px + 3 * w * (size_t)(y - r->y0), j->rgb + 3 * ((size_t)y * (size_t)j->desc.width + (size_t)r->x0),
               12 * w);
    for (size_t i = 0; i < n; i++) wire_put_f32(rec + 12 + 4 * i, px[i]);
    wire_put_u32(rec + 12 + 4 * n, journal_record_check(tile, px, n));
    int rc = tjournal_append(j->journal, tile, rec, len);
    free(px);
    free(rec);
    if (rc) snprintf(err, err_len, "out of memory journaling tile %u", tile);
    return rc ? -1 : FARM_TILE_PENDING;
}

/* Whether an error is the disk being full (wait for space, lose nothing)
 * rather than a fault. */
static int out_of_space(int e, const char *msg) {
    return e == ENOSPC || e == EDQUOT || strstr(msg, strerror(ENOSPC)) || strstr(msg, strerror(EDQUOT));
}

/* Record the job's end: its file, the log, and (done and recorded) its
 * journal removed; a failed or cancelled job keeps its journal until it
 * expires, so nothing durable is deleted. */
static void store_job_conclude(sjob *j) {
    service *s = j->svc;
    char err[600], path[4096];
    int saved = store_save_job(j, err, sizeof err) == 0;
    if (!saved) svc_log("job %u: %s", j->desc.id, err);
    svc_log("job %u %s (%d tiles from the journal, %d rendered in this run)%s%s", j->desc.id, state_names[j->state],
            j->tiles_resumed, j->tiles_done - j->tiles_resumed, j->error[0] ? ": " : "", j->error);
    joblog_add(j->log, svc_wall_now(), "job %s (%d tiles from the journal, %d rendered in this run)%s%.60s",
               state_names[j->state], j->tiles_resumed, j->tiles_done - j->tiles_resumed, j->error[0] ? ": " : "",
               j->error);
    if (j->journal) {
        uint64_t batches;
        int largest;
        tjournal_stats(j->journal, &batches, &largest);
        svc_log("job %u: journal: %" PRIu64 " synced batches, up to %d tiles in one", j->desc.id, batches, largest);
    }
    store_job_path(s, j->desc.id, "tiles", path, sizeof path);
    if (j->state == SJOB_DONE && saved) unlink(path); /* the image has it all */
    store_job_release(j);
}

static void on_save_timer_closed(uv_handle_t *h) { free(h); }

/* The finished image's write, on libuv's pool: a 4096x4096 frame is 200
 * MB of PFM, which on the loop held up every worker and client while it
 * went to disk. The frame is only read there; the job's state changes on
 * the loop (store_image_saved). */
typedef struct {
    uv_work_t work;
    sjob *j;   /* touched on the loop only */
    uint32_t id;
    image img; /* the job's frame, borrowed */
    char path[4096], err[600];
    int rc; /* 0; 1 the disk is full; -1 another error, in err */
} save_work;

/* Test hook, inert unless $TESSERA_TEST_SAVE_HOLD_FILE is set: the write
 * waits while that file exists (at most 120 s; logged once), so a test can
 * hold a job between its last tile and its saved image. On the pool. */
static void save_test_hold(const save_work *sw) {
    const char *hold = getenv("TESSERA_TEST_SAVE_HOLD_FILE");
    for (int waited = 0; hold && access(hold, F_OK) == 0 && waited < 12000; waited++) {
        if (!waited) fprintf(stderr, "tessera-coordinator: test hold: saving job %u waits while %s exists\n",
                             sw->id, hold);
        struct timespec ts = {0, 10 * 1000000L};
        nanosleep(&ts, NULL);
    }
}

static void save_image_work(uv_work_t *w) {
    save_work *sw = w->data;
    save_test_hold(sw);
    image_write_options wo = {0};
    errno = 0;
    if (image_write(sw->path, &sw->img, &wo, sw->err, sizeof sw->err) == 0) sw->rc = 0;
    else sw->rc = out_of_space(errno, sw->err) ? 1 : -1;
}

static void store_image_saved(sjob *j, int rc);

static void save_image_done(uv_work_t *w, int status) {
    save_work *sw = w->data;
    sjob *j = sw->j;
    int rc = status ? -1 : sw->rc;
    j->saving = 0;
    if (rc == -1) snprintf(j->error, sizeof j->error, "%.500s", status ? uv_strerror(status) : sw->err);
    free(sw);
    store_image_saved(j, rc);
}

/* Start writing the finished image (j->saving until store_image_saved).
 * Can't fail: without memory or a pool, the job fails with the reason. */
static void store_save_image(sjob *j) {
    save_work *sw = calloc(1, sizeof *sw);
    if (!sw) {
        snprintf(j->error, sizeof j->error, "out of memory to save the image");
        store_image_saved(j, -1);
        return;
    }
    sw->j = j;
    sw->id = j->desc.id;
    sw->img = (image){j->desc.width, j->desc.height, j->rgb};
    store_job_path(j->svc, j->desc.id, "pfm", sw->path, sizeof sw->path);
    sw->work.data = sw;
    j->saving = 1;
    int rc = uv_queue_work(&j->svc->loop, &sw->work, save_image_work, save_image_done);
    if (rc) {
        j->saving = 0;
        snprintf(j->error, sizeof j->error, "cannot start saving the image: %s", uv_strerror(rc));
        free(sw);
        store_image_saved(j, -1);
    }
}

static void on_save_retry(uv_timer_t *t) {
    sjob *j = t->data;
    if (!j->saving) store_save_image(j); /* store_image_saved stops the timer, or leaves it on */
}

/* After the finished image's write (rc: 0 saved; 1 the disk is full; -1
 * another error, in j->error): the job is done or failed; or, on a full
 * disk, it stays running with its frame and journal while a timer tries
 * again every TJOURNAL_RETRY_MS. */
static void store_image_saved(sjob *j, int rc) {
    service *s = j->svc;
    if (rc == 1 && j->save_timer) return; /* still full: the timer goes on */
    if (rc == 1 && (j->save_timer = malloc(sizeof *j->save_timer)) != NULL) {
        snprintf(j->error, sizeof j->error, "paused: no space left to save the image; retrying every %d s",
                 TJOURNAL_RETRY_MS / 1000);
        svc_log("job %u: %s (its tiles stay in the journal)", j->desc.id, j->error);
        uv_timer_init(&s->loop, j->save_timer);
        uv_unref((uv_handle_t *)j->save_timer); /* a stopping service does not wait for space */
        j->save_timer->data = j;
        uv_timer_start(j->save_timer, on_save_retry, TJOURNAL_RETRY_MS, TJOURNAL_RETRY_MS);
        return; /* still "running": a restart replays the journal */
    }
    if (j->save_timer) {
        uv_close((uv_handle_t *)j->save_timer, on_save_timer_closed);
        j->save_timer = NULL;
        if (rc == 0) j->error[0] = 0;
        svc_log("job %u: %s", j->desc.id, rc == 0 ? "space is back; the image is saved" : "the image cannot be saved");
    } else if (rc == 1) {
        snprintf(j->error, sizeof j->error, "no space left to save the image");
    }
    j->state = rc == 0 ? SJOB_DONE : SJOB_FAILED;
    store_job_conclude(j);
}

/* The farm handed out the job's first tile: it is rendering, not queued. */
static void store_on_first_assign(void *ctx) {
    sjob *j = ctx;
    j->first_tile = svc_wall_now();
}

void store_on_job_event(void *ctx, const farm_report *r, int done) {
    sjob *j = ctx;
    service *s = j->svc;
    j->stats = r->stats;
    if (!done) return;
    j->finished = svc_wall_now();
    if (r->cancelled) {
        j->state = SJOB_CANCELLED;
    } else if (r->failed) {
        j->state = SJOB_FAILED;
        snprintf(j->error, sizeof j->error, "%s", r->error);
    } else { /* the farm is done with it; the image is written off the loop, then the job concludes */
        farm_forget(s->f, j->farm_id);
        store_save_image(j);
        return;
    }
    store_job_conclude(j);
    farm_forget(s->f, j->farm_id);
}

/* The journal of j ran out of space or got it back (tjournal_pause_cb):
 * logged once each way, and shown in status as the job's note. */
static void store_on_journal_pause(void *ctx, int error) {
    sjob *j = ctx;
    if (error) {
        snprintf(j->error, sizeof j->error, "paused: the tile journal is out of space (%s); finished tiles wait in "
                 "memory and count once written", strerror(error));
        svc_log("job %u: %s; retrying every %d s", j->desc.id, j->error, TJOURNAL_RETRY_MS / 1000);
    } else {
        j->error[0] = 0;
        svc_log("job %u: space is back; the tile journal resumed", j->desc.id);
    }
}

static void store_on_round_event(void *ctx, const farm_report *r, int done);

/* Hand the farm an adaptive job's next round, or (none left) finish the job
 * as the farm would: the image saved and the state recorded. Returns 0, or
 * -1 when out of memory. */
static int store_submit_round(sjob *j) {
    service *s = j->svc;
    uint32_t first, count;
    if (adaptive_next_round(j->ad, &first, &count, j->mask) == 0) {
        adaptive_result(j->ad, j->rgb, NULL);
        farm_report rep = {.stats = j->round_stats, .tiles_total = j->tile_count, .tiles_done = j->tile_count};
        store_on_job_event(j, &rep, 1);
        return 0;
    }
    if (render_mark_idle_tiles(j->desc.width, j->desc.height, j->tile_size, j->mask, j->skip)) return -1;
    proto_job round = j->desc;
    round.id = j->farm_id = SVC_ROUND_IDS + (s->next_round++ & (SVC_ROUND_IDS - 1));
    round.adaptive = 1;
    farm_job_options fo = {.tile_size = j->tile_size, .priority = j->priority, .done = j->skip, .mask = j->mask,
                           .first = first, .count = count, .on_first_assign = j->first_tile > 0 ? NULL : store_on_first_assign,
                           .scene = j->scene};
    return farm_submit(s->f, &round, NULL, 0, &fo, j->sums, store_on_round_event, j);
}

/* The round timer: the last round is over and the farm done with it. */
static void on_round_timer(uv_timer_t *t) {
    sjob *j = t->data;
    if (j->state != SJOB_RUNNING || !j->ad || j->svc->stopping) return; /* stopping: the next start redoes it */
    farm_forget(j->svc->f, j->farm_id);
    if (store_submit_round(j) == 0) return;
    farm_report rep = {.failed = 1, .stats = j->round_stats};
    snprintf(rep.error, sizeof rep.error, "out of memory for an adaptive round");
    store_on_job_event(j, &rep, 1);
}

/* farm_job_cb of an adaptive round: progress (the whole job's samples);
 * at the round's end its sums go to the adaptive state and the next round
 * is submitted from the timer; a failed or cancelled round ends the job. */
static void store_on_round_event(void *ctx, const farm_report *r, int done) {
    sjob *j = ctx;
    farm_report rep = *r;
    trace_stats_add(&rep.stats, &j->round_stats);
    j->tiles_done = r->tiles_done;
    if (!done || r->failed || r->cancelled) {
        store_on_job_event(j, &rep, done);
        return;
    }
    j->stats = rep.stats;
    j->round_stats = rep.stats;
    adaptive_add_round(j->ad, j->sums);
    uv_timer_start(j->round_timer, on_round_timer, 0, 0);
}

/* Set up an adaptive job's state and hand the farm its first round; every
 * round shares one framed copy of the scene: framed (a reference is taken)
 * or, when NULL, one made from bundle. Returns 0, or -1 with err set. */
static int store_adaptive_start(service *s, sjob *j, const uint8_t *bundle, size_t len, conn_blob *framed,
                                char *err, size_t err_len) {
    size_t px = (size_t)j->desc.width * (size_t)j->desc.height;
    j->desc.adaptive = 1;
    j->ad = adaptive_new(j->desc.width, j->desc.height, j->desc.spp, j->min_spp, j->noise_threshold);
    j->sums = calloc(px * ADAPTIVE_CHANNELS, sizeof(float));
    j->mask = malloc(px);
    j->skip = malloc((size_t)j->tile_count);
    if (framed) framed->refs++;
    j->scene = framed ? framed : conn_blob_frame(WIRE_KIND_SCENE, bundle, len);
    j->round_timer = malloc(sizeof *j->round_timer);
    if (!j->ad || !j->sums || !j->mask || !j->skip || !j->scene || !j->round_timer) {
        free(j->round_timer);
        j->round_timer = NULL;
        snprintf(err, err_len, "out of memory for adaptive sampling of job %u", j->desc.id);
        return -1;
    }
    uv_timer_init(&s->loop, j->round_timer);
    j->round_timer->data = j;
    j->round_stats = (trace_stats){0};
    j->tiles_done = j->tiles_resumed = 0;
    j->started = svc_wall_now();
    j->first_tile = 0;
    if (store_submit_round(j)) {
        snprintf(err, err_len, "out of memory for job %u", j->desc.id);
        return -1;
    }
    return 0;
}

int store_job_cancel(service *s, sjob *j) {
    if (farm_cancel(s->f, j->farm_id) == 0) return 0;
    if (!j->ad || j->state != SJOB_RUNNING) return -1;
    /* Between two adaptive rounds: no farm job to cancel, end it here. */
    farm_report rep = {.cancelled = 1, .stats = j->round_stats};
    snprintf(rep.error, sizeof rep.error, "cancelled");
    store_on_job_event(j, &rep, 1);
    return 0;
}

/* Hand a job (new or resumed) to the farm, opening its tile journal (or,
 * with a noise threshold, its first adaptive round). */
int store_job_start(service *s, sjob *j, const uint8_t *bundle, size_t len, conn_blob *framed, char *err,
                    size_t err_len) {
    char path[4096];
    j->farm_id = j->desc.id;
    if (j->noise_threshold > 0) return store_adaptive_start(s, j, bundle, len, framed, err, err_len);
    store_job_path(s, j->desc.id, "tiles", path, sizeof path);
    j->journal = tjournal_open(&s->loop, path, store_on_batch, store_on_journal_pause, j, err, err_len);
    if (!j->journal) return -1;
    farm_job_options fo = {.tile_size = j->tile_size, .priority = j->priority, .done = j->journaled,
                           .on_tile = store_on_tile_done, .on_first_assign = store_on_first_assign,
                           .scene = framed};
    j->started = svc_wall_now();
    j->first_tile = 0;
    if (farm_submit(s->f, &j->desc, bundle, len, &fo, j->rgb, store_on_job_event, j)) {
        snprintf(err, err_len, "out of memory for job %u", j->desc.id);
        return -1;
    }
    return 0;
}

void store_job_persist_log(service *s, sjob *j, int existing) {
    char path[4096], err[600];
    store_job_path(s, j->desc.id, "log", path, sizeof path);
    if (joblog_persist(j->log, &s->loop, path, existing, err, sizeof err))
        svc_log("job %u: its log stays in memory only: %s", j->desc.id, err);
}

sjob *store_job_new(service *s) {
    sjob *j = calloc(1, sizeof *j);
    if (!j) return NULL;
    j->svc = s;
    j->log = joblog_new(); /* NULL (out of memory): the job runs without a log */
    TAILQ_INSERT_TAIL(&s->jobs, j, link);
    return j;
}

void store_job_unlink_free(service *s, sjob *j) {
    TAILQ_REMOVE(&s->jobs, j, link);
    store_job_release(j);
    joblog_free(j->log);
    free(j);
}

int store_set_priority(service *s, uint32_t id, long priority, const char *who, char *err, size_t err_len) {
    sjob *j = store_find_job(s, id);
    if (!j) return snprintf(err, err_len, "job %u: unknown job", id), -1;
    if (priority < -LIMIT_PRIORITY || priority > LIMIT_PRIORITY)
        return snprintf(err, err_len, "priority must be an integer from %d to %d", -LIMIT_PRIORITY, LIMIT_PRIORITY), -1;
    if (j->state != SJOB_RUNNING) return snprintf(err, err_len, "job %u is already %s", id, state_names[j->state]), -1;
    int old = j->priority;
    j->priority = (int)priority;
    if (store_save_job(j, err, err_len)) {
        j->priority = old;
        return -1;
    }
    farm_set_priority(s->f, j->farm_id, j->priority); /* -1 once rendered and waiting for disk space: nothing to reorder */
    svc_log("job %u: priority %d -> %d (%s)", id, old, j->priority, who);
    joblog_add(j->log, svc_wall_now(), "priority changed from %d to %d by %.60s", old, j->priority, who);
    return 0;
}

int store_running_jobs(const service *s) {
    int n = 0;
    const sjob *j;
    TAILQ_FOREACH(j, &s->jobs, link) n += j->state == SJOB_RUNNING;
    return n;
}

int store_resume_prepare(const char *journal, int width, int height, int tile_size, int tile_count, store_resume *r) {
    memset(r, 0, sizeof *r);
    snprintf(r->journal, sizeof r->journal, "%s", journal);
    tile_rect *rects = calloc((size_t)tile_count, sizeof *rects);
    r->rgb = calloc((size_t)width * (size_t)height * 3, sizeof(float));
    r->journaled = calloc((size_t)tile_count, 1);
    char err[512], *data = NULL;
    size_t len = 0;
    if (!rects || !r->rgb || !r->journaled) {
        free(rects);
        store_resume_free(r);
        return -1;
    }
    render_split_tiles(width, height, tile_size, rects, tile_count);
    if ((data = file_read_all(journal, (size_t)1 << 40, &len, err, sizeof err))) { /* NULL: no journal yet */
        film f = {r->rgb, width, height, 3};
        r->journal_len = len;
        r->journal_good = journal_replay((const uint8_t *)data, len, rects, tile_count, &f, r->journaled,
                                         &r->tiles_resumed);
        if (r->journal_good < len && truncate(journal, (off_t)r->journal_good) != 0) r->truncate_errno = errno;
    }
    free(data);
    free(rects);
    return 0;
}

void store_resume_free(store_resume *r) {
    free(r->rgb);
    free(r->journaled);
    r->rgb = NULL;
    r->journaled = NULL;
}

/* Read one job file; resume it if it was running. */
static void load_job(service *s, const char *file) {
    char path[4096], err[600];
    snprintf(path, sizeof path, "%s/jobs/%s", s->o.data_dir, file);
    size_t len;
    char *text = file_read_all(path, 1 << 20, &len, err, sizeof err);
    cJSON *m = text ? cJSON_Parse(text) : NULL;
    free(text);
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(m, "name"), *state = cJSON_GetObjectItemCaseSensitive(m, "state");
    const cJSON *pri = cJSON_GetObjectItemCaseSensitive(m, "priority"), *ts = cJSON_GetObjectItemCaseSensitive(m, "tile_size");
    const cJSON *error = cJSON_GetObjectItemCaseSensitive(m, "error");
    proto_job d;
    sjob *j = NULL;
    int st = -1;
    for (int i = 0; cJSON_IsString(state) && i < 4; i++)
        if (strcmp(state->valuestring, state_names[i]) == 0) st = i;
    cJSON *jobmsg = cJSON_Duplicate(m, 1); /* the job fields, as a job message */
    static const char *const extra[] = {"name", "state", "priority", "tile_size", "error", "submitted", "finished",
                                        "rendering_since", "noise_threshold", "min_spp", "submitter", "owner"};
    for (size_t i = 0; jobmsg && i < sizeof extra / sizeof extra[0]; i++) cJSON_DeleteItemFromObject(jobmsg, extra[i]);
    if (!m || st < 0 || !cJSON_IsString(name) || !cJSON_IsNumber(pri) || !cJSON_IsNumber(ts) ||
        !(fabs(pri->valuedouble) <= LIMIT_PRIORITY) || !(ts->valuedouble >= 1 && ts->valuedouble <= LIMIT_SIDE) ||
        !jobmsg ||
        proto_job_parse(jobmsg, path, &d, err, sizeof err) || !(j = store_job_new(s))) {
        svc_log("%s: not a job file I can read (%s); left alone", path, m ? err : "not JSON");
        cJSON_Delete(m);
        cJSON_Delete(jobmsg);
        return;
    }
    j->desc = d;
    store_job_persist_log(s, j, 1);
    snprintf(j->name, sizeof j->name, "%s", name->valuestring);
    j->priority = (int)pri->valuedouble;
    j->tile_size = (int)ts->valuedouble;
    j->state = (sjob_state)st;
    const cJSON *nt = cJSON_GetObjectItemCaseSensitive(m, "noise_threshold");
    const cJSON *ms = cJSON_GetObjectItemCaseSensitive(m, "min_spp");
    if (cJSON_IsNumber(nt) && nt->valuedouble > 0 && cJSON_IsNumber(ms) && ms->valuedouble >= 1 &&
        ms->valuedouble <= LIMIT_SPP) {
        j->noise_threshold = nt->valuedouble;
        j->min_spp = (int)ms->valuedouble;
        j->desc.adaptive = 1;
    }
    if (cJSON_IsString(error)) snprintf(j->error, sizeof j->error, "%s", error->valuestring);
    const cJSON *who = cJSON_GetObjectItemCaseSensitive(m, "submitter");
    if (cJSON_IsString(who)) snprintf(j->submitter, sizeof j->submitter, "%s", who->valuestring);
    const cJSON *owner = cJSON_GetObjectItemCaseSensitive(m, "owner");
    if (cJSON_IsString(owner)) snprintf(j->owner, sizeof j->owner, "%s", owner->valuestring);
    const cJSON *sub = cJSON_GetObjectItemCaseSensitive(m, "submitted"), *fin = cJSON_GetObjectItemCaseSensitive(m, "finished");
    j->submitted = cJSON_IsNumber(sub) ? sub->valuedouble : svc_wall_now();
    j->finished = cJSON_IsNumber(fin) ? fin->valuedouble : 0;
    cJSON_Delete(m);
    cJSON_Delete(jobmsg);
    if (d.id >= s->next_id) s->next_id = d.id + 1;
    j->tile_count = render_split_tiles(d.width, d.height, j->tile_size, NULL, 0);
    if (j->state != SJOB_RUNNING) return;
    struct stat sb;
    store_scene_path(s, j, path, sizeof path);
    j->need = membudget_job_bytes(d.width, d.height, j->tile_count, stat(path, &sb) == 0 ? (uint64_t)sb.st_size : 0);
    int adm = svc_admit_check(s, j, err, sizeof err);
    if (adm == 0) { /* svc_admit_waiting reads its scene and journal on the pool once every job is loaded */
        j->waiting = 1;
        j->restarting = 1;
        return;
    }
    j->state = adm < 0 ? SJOB_FAILED : SJOB_RUNNING;
    j->waiting = adm > 0;
    snprintf(j->error, sizeof j->error, "%s%.480s", adm < 0 ? "cannot resume: " : "", err);
    svc_log("job %u: %s", d.id, j->error);
    if (adm < 0) store_save_job(j, err, sizeof err);
}

int store_job_resume_with(service *s, sjob *j, const uint8_t *bundle, size_t len, conn_blob *framed,
                          const char *read_err, store_resume *r) {
    char err[600];
    if (!bundle || !r || !r->rgb) {
        j->state = SJOB_FAILED;
        snprintf(j->error, sizeof j->error, "cannot resume: %.480s", bundle ? "out of memory" : read_err);
        svc_log("job %u: %s", j->desc.id, j->error);
        store_save_job(j, err, sizeof err);
        store_job_release(j);
        return -1;
    }
    if (r->journal_good < r->journal_len)
        svc_log("job %u: %s: dropping %zu bytes of a torn or corrupt record at the end", j->desc.id, r->journal,
                r->journal_len - r->journal_good);
    if (r->truncate_errno) svc_log("%s: cannot truncate: %s", r->journal, strerror(r->truncate_errno));
    j->rgb = r->rgb;
    j->journaled = r->journaled;
    r->rgb = NULL;
    r->journaled = NULL;
    j->tiles_resumed = j->tiles_done = r->tiles_resumed;
    svc_log("job %u resumed: %d of %d tiles from the journal", j->desc.id, j->tiles_resumed, j->tile_count);
    joblog_add(j->log, svc_wall_now(), "job resumed after a restart: %d of %d tiles from the journal",
               j->tiles_resumed, j->tile_count);
    if (store_job_start(s, j, bundle, len, framed, err, sizeof err)) {
        j->state = SJOB_FAILED;
        snprintf(j->error, sizeof j->error, "%.500s", err);
        store_save_job(j, err, sizeof err);
        store_job_release(j);
        return -1;
    }
    return 0;
}

void store_scene_path(const service *s, const sjob *j, char *path, size_t path_len) {
    snprintf(path, path_len, "%s/scenes/%s", s->o.data_dir, j->desc.scene_hash);
}

int store_job_resume(service *s, sjob *j) {
    char path[4096], err[600];
    size_t len = 0;
    store_resume r;
    store_job_path(s, j->desc.id, "tiles", path, sizeof path);
    int prepared = store_resume_prepare(path, j->desc.width, j->desc.height, j->tile_size, j->tile_count, &r);
    store_scene_path(s, j, path, sizeof path);
    char *bundle = file_read_all(path, s->o.max_upload, &len, err, sizeof err);
    int rc = store_job_resume_with(s, j, (const uint8_t *)bundle, len, NULL, err, prepared ? NULL : &r);
    store_resume_free(&r); /* what j did not take */
    free(bundle);
    return rc;
}

static int cmp_job_files(const void *a, const void *b) {
    return (int)(strtoul(*(char *const *)a, NULL, 10) > strtoul(*(char *const *)b, NULL, 10)) -
           (int)(strtoul(*(char *const *)a, NULL, 10) < strtoul(*(char *const *)b, NULL, 10));
}

/* Resume every job in the data dir, oldest first. */
void store_load_jobs(service *s) {
    char path[4096];
    snprintf(path, sizeof path, "%s/jobs", s->o.data_dir);
    DIR *d = opendir(path);
    if (!d) return;
    char **names = NULL;
    size_t n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        size_t l = strlen(e->d_name);
        if (strstr(e->d_name, ".partial-") && l > 4 && strcmp(e->d_name + l - 4, ".pfm") == 0) {
            snprintf(path, sizeof path, "%s/jobs/%s", s->o.data_dir, e->d_name); /* a partial fetch cut short */
            unlink(path);
            continue;
        }
        if (l < 6 || strcmp(e->d_name + l - 5, ".json") != 0 || strspn(e->d_name, "0123456789") != l - 5) continue;
        char **nn = realloc(names, (n + 1) * sizeof *names);
        if (!nn) break;
        names = nn;
        names[n++] = strdup(e->d_name);
    }
    closedir(d);
    if (n) qsort(names, n, sizeof *names, cmp_job_files);
    for (size_t i = 0; i < n; i++) {
        if (names[i]) load_job(s, names[i]);
        free(names[i]);
    }
    free(names);
}
