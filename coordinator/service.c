/* service.c - the long-running coordinator: jobs, clients, journal (see
 * service.h).
 *
 * Data dir layout (every file written whole to a temporary name, synced and
 * renamed, except the tile journal, which is appended and synced per tile):
 *   scenes/HASH     uploaded scene bundles, named by their BLAKE2b hash
 *   jobs/ID.json    a job: what to render and its state
 *   jobs/ID.tiles   finished tiles of a running job: records of
 *                   u32 magic, u32 tile, u32 float count, floats, u32 check
 *   jobs/ID.pfm     the finished image
 * A tile counts as done only after its record is on disk, so after kill -9
 * and a restart every journalled tile is kept and only the others are
 * rendered again. Nothing a client sends names a path: scenes are stored by
 * hash, jobs by number. */
#define _GNU_SOURCE
#include "service.h"

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <uv.h>

#include "../common/conn.h"
#include "../common/fileio.h"
#include "../common/image.h"
#include "../common/scene.h"
#include "../common/wire.h"

#define TILE_MAGIC 0x454c4954u /* "TILE" */
#define WIRE_KIND_IMAGE 'I'

typedef enum { SJOB_RUNNING, SJOB_DONE, SJOB_FAILED, SJOB_CANCELLED } sjob_state;
static const char *const state_names[] = {"running", "done", "failed", "cancelled"};

typedef struct sjob {
    struct service *svc;
    proto_job desc;
    char name[256]; /* the scene's file name, for people */
    int priority, tile_size, tile_count;
    sjob_state state;
    char error[512];
    float *rgb;         /* while running */
    uint8_t *journaled; /* tiles on disk before this run */
    int tiles_done, tiles_resumed;
    trace_stats stats;
    double submitted, started, finished; /* wall clock, seconds */
    int tiles_fd;
    struct sjob *next;
} sjob;

typedef struct service {
    service_options o;
    uv_loop_t loop;
    farm *f;
    uv_signal_t sigint, sigterm;
    uv_timer_t expiry;
    sjob *jobs;
    uint32_t next_id;
    int stopping;
} service;

typedef struct {
    service *svc;
    conn *c;
    char addr[64];
    uint8_t *bundle; /* the last scene uploaded */
    size_t bundle_len;
} client;

static void svc_log(const char *fmt, ...) __attribute__((format(printf, 1, 2)));
static void svc_log(const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fputs("tessera-coordinator: ", stderr);
    vfprintf(stderr, fmt, ap);
    fputc('\n', stderr);
    fflush(stderr);
    va_end(ap);
}

static double wall_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

/* ---- files --------------------------------------------------------------------- */

static void job_path(const service *s, uint32_t id, const char *ext, char *out, size_t n) {
    snprintf(out, n, "%s/jobs/%u.%s", s->o.data_dir, id, ext);
}

/* Write data to path through a synced temporary file. Returns 0 or -1 with
 * "PATH: reason" in err. */
static int write_atomic(const char *path, const void *data, size_t len, char *err, size_t err_len) {
    char tmp[4200];
    snprintf(tmp, sizeof tmp, "%s.tmp", path);
    int fd = open(tmp, O_WRONLY | O_CREAT | O_TRUNC, 0644);
    int ok = fd >= 0;
    const char *p = data;
    for (size_t left = len; ok && left > 0;) {
        ssize_t n = write(fd, p, left);
        if (n <= 0) ok = 0;
        else p += n, left -= (size_t)n;
    }
    if (ok && fsync(fd) != 0) ok = 0;
    if (fd >= 0 && close(fd) != 0) ok = 0;
    if (ok && rename(tmp, path) != 0) ok = 0;
    if (!ok) {
        snprintf(err, err_len, "%.400s: cannot write: %s", path, strerror(errno));
        unlink(tmp);
        return -1;
    }
    return 0;
}

static int save_job(sjob *j, char *err, size_t err_len) {
    char seed[32], path[4096];
    snprintf(seed, sizeof seed, "%" PRIu64, j->desc.seed);
    cJSON *m = cJSON_CreateObject();
    cJSON_AddNumberToObject(m, "job", j->desc.id);
    cJSON_AddStringToObject(m, "name", j->name);
    cJSON_AddStringToObject(m, "scene", j->desc.scene_hash);
    cJSON_AddNumberToObject(m, "width", j->desc.width);
    cJSON_AddNumberToObject(m, "height", j->desc.height);
    cJSON_AddNumberToObject(m, "spp", j->desc.spp);
    cJSON_AddNumberToObject(m, "max_depth", j->desc.max_depth);
    cJSON_AddStringToObject(m, "seed", seed);
    cJSON_AddBoolToObject(m, "nee", !j->desc.integrator.no_nee);
    cJSON_AddBoolToObject(m, "mis", !j->desc.integrator.no_mis);
    cJSON_AddStringToObject(m, "sampler", sampler_name(j->desc.integrator.sampler));
    cJSON_AddNumberToObject(m, "priority", j->priority);
    cJSON_AddNumberToObject(m, "tile_size", j->tile_size);
    cJSON_AddStringToObject(m, "state", state_names[j->state]);
    cJSON_AddStringToObject(m, "error", j->error);
    cJSON_AddNumberToObject(m, "submitted", j->submitted);
    cJSON_AddNumberToObject(m, "finished", j->finished);
    char *text = cJSON_Print(m);
    cJSON_Delete(m);
    job_path(j->svc, j->desc.id, "json", path, sizeof path);
    int rc = text ? write_atomic(path, text, strlen(text), err, err_len) : -1;
    if (!text) snprintf(err, err_len, "out of memory");
    free(text);
    return rc;
}

static uint32_t record_check(uint32_t tile, const float *px, size_t n) {
    uint32_t h = 2166136261u ^ tile; /* FNV-1a over the bytes: catches torn writes */
    const uint8_t *b = (const uint8_t *)px;
    for (size_t i = 0; i < 4 * n; i++) h = (h ^ b[i]) * 16777619u;
    return h;
}

/* ---- jobs ------------------------------------------------------------------------ */

static void job_release(sjob *j) {
    free(j->rgb);
    free(j->journaled);
    j->rgb = NULL;
    j->journaled = NULL;
    if (j->tiles_fd >= 0) close(j->tiles_fd);
    j->tiles_fd = -1;
}

static sjob *find_job(service *s, uint32_t id) {
    for (sjob *j = s->jobs; j; j = j->next)
        if (j->desc.id == id) return j;
    return NULL;
}

/* Append a finished tile to the journal and sync it: the farm counts the
 * tile only when this returns 0. */
static int on_tile_done(void *ctx, uint32_t tile, const tile_rect *r, char *err, size_t err_len) {
    sjob *j = ctx;
    size_t w = (size_t)tile_width(r), n = 3 * w * (size_t)tile_height(r);
    size_t len = 16 + 4 * n;
    uint8_t *rec = malloc(len);
    if (!rec) {
        snprintf(err, err_len, "out of memory journaling tile %u", tile);
        return -1;
    }
    wire_put_u32(rec, TILE_MAGIC);
    wire_put_u32(rec + 4, tile);
    wire_put_u32(rec + 8, (uint32_t)n);
    float *px = (float *)malloc(4 * n);
    for (int y = r->y0; px && y < r->y1; y++)
        memcpy(px + 3 * w * (size_t)(y - r->y0), j->rgb + 3 * ((size_t)y * (size_t)j->desc.width + (size_t)r->x0),
               12 * w);
    for (size_t i = 0; px && i < n; i++) wire_put_f32(rec + 12 + 4 * i, px[i]);
    if (px) wire_put_u32(rec + 12 + 4 * n, record_check(tile, px, n));
    size_t written = 0;
    int e = px ? 0 : ENOMEM;
    while (!e && written < len) { /* a short write (disk full, file limit) is followed by the error */
        ssize_t wr = write(j->tiles_fd, rec + written, len - written);
        if (wr > 0) written += (size_t)wr;
        else e = wr < 0 ? errno : EIO;
    }
    if (!e && fdatasync(j->tiles_fd) != 0) e = errno;
    int rc = e ? -1 : 0;
    if (rc) {
        char path[4096];
        job_path(j->svc, j->desc.id, "tiles", path, sizeof path);
        snprintf(err, err_len, "%.400s: cannot journal tile %u: %s", path, tile, strerror(e));
        off_t end = lseek(j->tiles_fd, 0, SEEK_CUR);
        if (written > 0 && end >= (off_t)written && ftruncate(j->tiles_fd, end - (off_t)written) != 0) {
            /* a torn record left behind is cut off at the next start */
        }
    }
    free(px);
    free(rec);
    if (rc == 0) j->tiles_done++;
    return rc;
}

static void on_job_event(void *ctx, const farm_report *r, int done) {
    sjob *j = ctx;
    service *s = j->svc;
    j->stats = r->stats;
    if (!done) return;
    char err[600] = "", path[4096];
    j->finished = wall_now();
    if (r->cancelled) {
        j->state = SJOB_CANCELLED;
    } else if (r->failed) {
        j->state = SJOB_FAILED;
        snprintf(j->error, sizeof j->error, "%s", r->error);
    } else {
        image img = {j->desc.width, j->desc.height, j->rgb};
        image_write_options wo = {0};
        job_path(s, j->desc.id, "pfm", path, sizeof path);
        if (image_write(path, &img, &wo, err, sizeof err) == 0) {
            j->state = SJOB_DONE;
        } else {
            j->state = SJOB_FAILED;
            snprintf(j->error, sizeof j->error, "%.500s", err);
        }
    }
    if (save_job(j, err, sizeof err)) svc_log("job %u: %s", j->desc.id, err);
    svc_log("job %u %s (%d tiles from the journal, %d rendered in this run)%s%s", j->desc.id, state_names[j->state],
            j->tiles_resumed, j->tiles_done - j->tiles_resumed, j->error[0] ? ": " : "", j->error);
    job_path(s, j->desc.id, "tiles", path, sizeof path);
    unlink(path); /* done: the image has it; failed or cancelled: never resumed */
    job_release(j);
    farm_forget(s->f, j->desc.id);
}

/* Hand a job (new or resumed) to the farm, opening its tile journal. */
static int job_start(service *s, sjob *j, const uint8_t *bundle, size_t len, char *err, size_t err_len) {
    char path[4096];
    job_path(s, j->desc.id, "tiles", path, sizeof path);
    j->tiles_fd = open(path, O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (j->tiles_fd < 0) {
        snprintf(err, err_len, "%.400s: cannot open the tile journal: %s", path, strerror(errno));
        return -1;
    }
    farm_job_options fo = {.tile_size = j->tile_size, .priority = j->priority, .done = j->journaled,
                           .on_tile = on_tile_done};
    j->started = wall_now();
    if (farm_submit(s->f, &j->desc, bundle, len, &fo, j->rgb, on_job_event, j)) {
        snprintf(err, err_len, "out of memory for job %u", j->desc.id);
        return -1;
    }
    return 0;
}

static sjob *job_new(service *s) {
    sjob *j = calloc(1, sizeof *j);
    if (!j) return NULL;
    j->svc = s;
    j->tiles_fd = -1;
    sjob **pp = &s->jobs;
    while (*pp) pp = &(*pp)->next;
    *pp = j;
    return j;
}

static void job_unlink_free(service *s, sjob *j) {
    for (sjob **pp = &s->jobs; *pp; pp = &(*pp)->next)
        if (*pp == j) {
            *pp = j->next;
            break;
        }
    job_release(j);
    free(j);
}

static int running_jobs(const service *s) {
    int n = 0;
    for (const sjob *j = s->jobs; j; j = j->next) n += j->state == SJOB_RUNNING;
    return n;
}

/* ---- restart: read the journal back ---------------------------------------------------- */

/* Replay jobs/ID.tiles into j->rgb; a torn or corrupt tail is cut off. */
static void replay_tiles(service *s, sjob *j, const tile_rect *rects) {
    char path[4096], err[512];
    job_path(s, j->desc.id, "tiles", path, sizeof path);
    size_t len = 0;
    char *data = file_read_all(path, (size_t)1 << 40, &len, err, sizeof err);
    if (!data) return; /* no journal yet */
    size_t off = 0;
    while (off + 16 <= len) {
        const uint8_t *p = (const uint8_t *)data + off;
        uint32_t tile = wire_get_u32(p + 4), n = wire_get_u32(p + 8);
        if (wire_get_u32(p) != TILE_MAGIC || tile >= (uint32_t)j->tile_count) break;
        const tile_rect *r = &rects[tile];
        size_t w = (size_t)tile_width(r);
        if (n != 3 * w * (size_t)tile_height(r) || off + 16 + 4 * (size_t)n > len) break;
        float *px = malloc(4 * (size_t)n);
        if (!px) break;
        for (uint32_t i = 0; i < n; i++) px[i] = wire_get_f32(p + 12 + 4 * i);
        int ok = record_check(tile, px, n) == wire_get_u32(p + 12 + 4 * (size_t)n);
        for (int y = r->y0; ok && y < r->y1; y++)
            memcpy(j->rgb + 3 * ((size_t)y * (size_t)j->desc.width + (size_t)r->x0), px + 3 * w * (size_t)(y - r->y0),
                   12 * w);
        free(px);
        if (!ok) break;
        if (!j->journaled[tile]) j->tiles_resumed++;
        j->journaled[tile] = 1;
        off += 16 + 4 * (size_t)n;
    }
    if (off < len) {
        svc_log("job %u: %s: dropping %zu bytes of a torn or corrupt record at the end", j->desc.id, path, len - off);
        if (truncate(path, (off_t)off) != 0) svc_log("%s: cannot truncate: %s", path, strerror(errno));
    }
    free(data);
    j->tiles_done = j->tiles_resumed;
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
    static const char *const extra[] = {"name", "state", "priority", "tile_size", "error", "submitted", "finished"};
    for (size_t i = 0; jobmsg && i < sizeof extra / sizeof extra[0]; i++) cJSON_DeleteItemFromObject(jobmsg, extra[i]);
    if (!m || st < 0 || !cJSON_IsString(name) || !cJSON_IsNumber(pri) || !cJSON_IsNumber(ts) || !jobmsg ||
        proto_job_parse(jobmsg, path, &d, err, sizeof err) || !(j = job_new(s))) {
        svc_log("%s: not a job file I can read (%s); left alone", path, m ? err : "not JSON");
        cJSON_Delete(m);
        cJSON_Delete(jobmsg);
        return;
    }
    j->desc = d;
    snprintf(j->name, sizeof j->name, "%s", name->valuestring);
    j->priority = (int)pri->valuedouble;
    j->tile_size = (int)ts->valuedouble;
    j->state = (sjob_state)st;
    if (cJSON_IsString(error)) snprintf(j->error, sizeof j->error, "%s", error->valuestring);
    const cJSON *sub = cJSON_GetObjectItemCaseSensitive(m, "submitted"), *fin = cJSON_GetObjectItemCaseSensitive(m, "finished");
    j->submitted = cJSON_IsNumber(sub) ? sub->valuedouble : wall_now();
    j->finished = cJSON_IsNumber(fin) ? fin->valuedouble : 0;
    cJSON_Delete(m);
    cJSON_Delete(jobmsg);
    if (d.id >= s->next_id) s->next_id = d.id + 1;
    j->tile_count = render_split_tiles(d.width, d.height, j->tile_size, NULL, 0);
    if (j->state != SJOB_RUNNING) return;
    /* Resume: the scene from its hash, the tiles from the journal. */
    snprintf(path, sizeof path, "%s/scenes/%s", s->o.data_dir, d.scene_hash);
    char *bundle = file_read_all(path, s->o.max_upload, &len, err, sizeof err);
    tile_rect *rects = calloc((size_t)j->tile_count, sizeof *rects);
    j->rgb = calloc((size_t)d.width * (size_t)d.height * 3, sizeof(float));
    j->journaled = calloc((size_t)j->tile_count, 1);
    if (!bundle || !rects || !j->rgb || !j->journaled) {
        j->state = SJOB_FAILED;
        snprintf(j->error, sizeof j->error, "cannot resume: %.480s", bundle ? "out of memory" : err);
        svc_log("job %u: %s", d.id, j->error);
        save_job(j, err, sizeof err);
        job_release(j);
    } else {
        render_split_tiles(d.width, d.height, j->tile_size, rects, j->tile_count);
        replay_tiles(s, j, rects);
        svc_log("job %u resumed: %d of %d tiles from the journal", d.id, j->tiles_resumed, j->tile_count);
        if (job_start(s, j, (const uint8_t *)bundle, len, err, sizeof err)) {
            j->state = SJOB_FAILED;
            snprintf(j->error, sizeof j->error, "%.500s", err);
            save_job(j, err, sizeof err);
            job_release(j);
        }
    }
    free(rects);
    free(bundle);
}

static int cmp_job_files(const void *a, const void *b) {
    return (int)(strtoul(*(char *const *)a, NULL, 10) > strtoul(*(char *const *)b, NULL, 10)) -
           (int)(strtoul(*(char *const *)a, NULL, 10) < strtoul(*(char *const *)b, NULL, 10));
}

/* Resume every job in the data dir, oldest first. */
static void load_jobs(service *s) {
    char path[4096];
    snprintf(path, sizeof path, "%s/jobs", s->o.data_dir);
    DIR *d = opendir(path);
    if (!d) return;
    char **names = NULL;
    size_t n = 0;
    struct dirent *e;
    while ((e = readdir(d)) != NULL) {
        size_t l = strlen(e->d_name);
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

/* ---- clients ------------------------------------------------------------------------ */

static void client_send_json(client *cl, cJSON *m) {
    size_t len;
    uint8_t *f = m ? wire_frame_json(m, &len) : NULL;
    cJSON_Delete(m);
    if (f) conn_send(cl->c, f, len);
}

static void client_error(client *cl, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
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

static void on_submit(client *cl, const cJSON *m) {
    service *s = cl->svc;
    char err[1024], hash[SCENE_BUNDLE_HASH_HEX], path[4096];
    const cJSON *h = cJSON_GetObjectItemCaseSensitive(m, "scene"), *name = cJSON_GetObjectItemCaseSensitive(m, "name");
    if (!cl->bundle) return client_error(cl, "submit: no scene was uploaded before it");
    scene_bundle_hash(cl->bundle, cl->bundle_len, hash);
    if (!cJSON_IsString(h) || strcmp(h->valuestring, hash) != 0)
        return client_error(cl, "submit: \"scene\" is not the hash of the uploaded scene (%s)", hash);
    long w = -1, ht = -1, spp = -1, depth = -1, pri = 0, tile = s->o.tile_size;
    if (opt_int(m, "width", 1, 32768, &w) || opt_int(m, "height", 1, 32768, &ht) ||
        opt_int(m, "spp", 1, 1 << 24, &spp) || opt_int(m, "max_depth", 1, 1024, &depth) ||
        opt_int(m, "priority", -1000000, 1000000, &pri) || opt_int(m, "tile_size", 1, s->o.farm.max_tile_side, &tile))
        return client_error(cl, "submit: width, height, spp, max_depth, priority or tile_size out of range");
    const cJSON *sname = cJSON_GetObjectItemCaseSensitive(m, "sampler");
    sampler_kind sampler = SAMPLER_SOBOL;
    if (sname && (!cJSON_IsString(sname) || sampler_parse(sname->valuestring, &sampler) != 0))
        return client_error(cl, "submit: sampler must be \"sobol\" or \"random\"");
    if (running_jobs(s) >= s->o.max_jobs)
        return client_error(cl, "the queue is full (%d jobs); try again later", s->o.max_jobs);
    scene_bundle b;
    if (scene_bundle_parse(cl->bundle, cl->bundle_len, &b, err, sizeof err)) return client_error(cl, "%s", err);
    scene_overrides ov = {(int)w, (int)ht, (int)spp, (int)depth, 0, 0, 1}; /* workers build the intersector */
    const cJSON *seed = cJSON_GetObjectItemCaseSensitive(m, "seed");
    if (cJSON_IsString(seed)) {
        ov.has_seed = 1;
        ov.seed = strtoull(seed->valuestring, NULL, 10);
    }
    scene *sc = scene_load_bundle(&b, &ov, err, sizeof err);
    scene_bundle_free(&b);
    if (!sc) return client_error(cl, "%s", err); /* the scene's own message: file, line, field */
    sjob *j = job_new(s);
    if (!j) {
        scene_free(sc);
        return client_error(cl, "out of memory");
    }
    j->desc = (proto_job){.id = s->next_id++, .width = sc->settings.width, .height = sc->settings.height,
                          .spp = sc->settings.spp, .max_depth = sc->settings.max_depth, .seed = sc->settings.seed};
    j->desc.integrator.no_nee = cJSON_IsFalse(cJSON_GetObjectItemCaseSensitive(m, "nee"));
    j->desc.integrator.no_mis = cJSON_IsFalse(cJSON_GetObjectItemCaseSensitive(m, "mis"));
    j->desc.integrator.sampler = sampler;
    memcpy(j->desc.scene_hash, hash, sizeof hash);
    snprintf(j->name, sizeof j->name, "%s", cJSON_IsString(name) ? name->valuestring : "scene");
    scene_free(sc);
    j->priority = (int)pri;
    j->tile_size = (int)tile;
    j->submitted = wall_now();
    j->tile_count = render_split_tiles(j->desc.width, j->desc.height, j->tile_size, NULL, 0);
    j->rgb = calloc((size_t)j->desc.width * (size_t)j->desc.height * 3, sizeof(float));
    snprintf(path, sizeof path, "%s/scenes/%s", s->o.data_dir, hash);
    int rc = j->rgb ? 0 : -1;
    if (!j->rgb) snprintf(err, sizeof err, "out of memory for a %dx%d image", j->desc.width, j->desc.height);
    if (rc == 0) rc = write_atomic(path, cl->bundle, cl->bundle_len, err, sizeof err);
    if (rc == 0) rc = save_job(j, err, sizeof err);
    if (rc == 0) rc = job_start(s, j, cl->bundle, cl->bundle_len, err, sizeof err);
    if (rc) {
        svc_log("submit from %s refused: %s", cl->addr, err);
        job_path(s, j->desc.id, "json", path, sizeof path);
        unlink(path);
        job_unlink_free(s, j);
        return client_error(cl, "%s", err);
    }
    svc_log("job %u submitted from %s: %s, %dx%d, %d spp, priority %d", j->desc.id, cl->addr, j->name, j->desc.width,
            j->desc.height, j->desc.spp, j->priority);
    cJSON *r = cJSON_CreateObject();
    cJSON_AddStringToObject(r, "type", "submitted");
    cJSON_AddNumberToObject(r, "job", j->desc.id);
    client_send_json(cl, r);
}

static cJSON *job_status_json(const sjob *j) {
    cJSON *o = cJSON_CreateObject();
    double now = wall_now(), el = (j->state == SJOB_RUNNING ? now : j->finished) - j->started;
    cJSON_AddNumberToObject(o, "job", j->desc.id);
    cJSON_AddStringToObject(o, "name", j->name);
    cJSON_AddStringToObject(o, "state", state_names[j->state]);
    cJSON_AddNumberToObject(o, "priority", j->priority);
    cJSON_AddNumberToObject(o, "width", j->desc.width);
    cJSON_AddNumberToObject(o, "height", j->desc.height);
    cJSON_AddNumberToObject(o, "spp", j->desc.spp);
    cJSON_AddNumberToObject(o, "tiles_done", j->state == SJOB_DONE ? j->tile_count : j->tiles_done);
    cJSON_AddNumberToObject(o, "tiles_total", j->tile_count);
    cJSON_AddNumberToObject(o, "tiles_resumed", j->tiles_resumed);
    double rendered = j->tiles_done - j->tiles_resumed;
    double rate = el > 0 ? (double)j->stats.samples / el : 0;
    cJSON_AddNumberToObject(o, "samples_per_s", rate);
    double left = j->tile_count - j->tiles_done;
    cJSON_AddNumberToObject(o, "eta_s", j->state == SJOB_RUNNING && rendered > 0 ? el / rendered * left : 0);
    cJSON_AddNumberToObject(o, "submitted", j->submitted);
    cJSON_AddStringToObject(o, "error", j->error);
    return o;
}

static void on_status(client *cl, const cJSON *m) {
    service *s = cl->svc;
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(m, "job");
    cJSON *r = cJSON_CreateObject(), *arr = cJSON_AddArrayToObject(r, "jobs");
    cJSON_AddStringToObject(r, "type", "status");
    for (sjob *j = s->jobs; j; j = j->next)
        if (!cJSON_IsNumber(id) || id->valuedouble == j->desc.id) cJSON_AddItemToArray(arr, job_status_json(j));
    if (cJSON_IsNumber(id) && cJSON_GetArraySize(arr) == 0) {
        cJSON_Delete(r);
        return client_error(cl, "job %g: unknown job", id->valuedouble);
    }
    farm_worker_info wi[1];
    cJSON_AddNumberToObject(r, "workers", farm_list_workers(s->f, wi, 0));
    client_send_json(cl, r);
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
        cJSON_AddItemToArray(arr, o);
    }
    free(wi);
    client_send_json(cl, r);
}

static sjob *request_job(client *cl, const cJSON *m, const char *type) {
    const cJSON *id = cJSON_GetObjectItemCaseSensitive(m, "job");
    sjob *j = cJSON_IsNumber(id) && id->valuedouble >= 0 ? find_job(cl->svc, (uint32_t)id->valuedouble) : NULL;
    if (!cJSON_IsNumber(id))
        client_error(cl, "%s: expected a job number", type);
    else if (!j)
        client_error(cl, "job %g: unknown job", id->valuedouble);
    return j;
}

static void on_cancel(client *cl, const cJSON *m) {
    sjob *j = request_job(cl, m, "cancel");
    if (!j) return;
    if (j->state != SJOB_RUNNING) return client_error(cl, "job %u is already %s", j->desc.id, state_names[j->state]);
    farm_cancel(cl->svc->f, j->desc.id); /* on_job_event records the state */
    cJSON *r = cJSON_CreateObject();
    cJSON_AddStringToObject(r, "type", "cancelled");
    cJSON_AddNumberToObject(r, "job", j->desc.id);
    client_send_json(cl, r);
}

static void on_fetch(client *cl, const cJSON *m) {
    sjob *j = request_job(cl, m, "fetch");
    if (!j) return;
    if (j->state != SJOB_DONE)
        return client_error(cl, "job %u is %s (%d of %d tiles)%s%s", j->desc.id, state_names[j->state], j->tiles_done,
                            j->tile_count, j->error[0] ? ": " : "", j->error);
    char path[4096], err[600];
    image img;
    job_path(cl->svc, j->desc.id, "pfm", path, sizeof path);
    if (image_read(path, &img, err, sizeof err)) return client_error(cl, "%s", err);
    size_t n = (size_t)img.width * (size_t)img.height * 3, len;
    uint8_t *f = wire_frame_new(WIRE_KIND_IMAGE, 8 + 4 * n, &len);
    if (!f) {
        image_free(&img);
        return client_error(cl, "out of memory");
    }
    wire_put_u32(f + WIRE_HEADER_BYTES, (uint32_t)img.width);
    wire_put_u32(f + WIRE_HEADER_BYTES + 4, (uint32_t)img.height);
    for (size_t i = 0; i < n; i++) wire_put_f32(f + WIRE_HEADER_BYTES + 8 + 4 * i, img.rgb[i]);
    image_free(&img);
    conn_send(cl->c, f, len);
}

static int client_on_frame(conn *c, int kind, const uint8_t *body, size_t len) {
    client *cl = conn_data(c);
    if (kind == WIRE_KIND_SCENE) {
        free(cl->bundle);
        cl->bundle = malloc(len ? len : 1);
        if (!cl->bundle) {
            client_error(cl, "out of memory for a %zu-byte scene", len);
            conn_close(c, "out of memory", 1);
            return 1;
        }
        memcpy(cl->bundle, body, len);
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
    else client_error(cl, "unknown request \"%.40s\"", type);
    cJSON_Delete(m);
    return 0;
}

static void client_on_close(conn *c, const char *reason) {
    client *cl = conn_data(c);
    if (conn_malformed(c)) svc_log("client %s: %s; disconnecting", cl->addr, reason);
    free(cl->bundle);
    free(cl);
}

static const conn_callbacks client_cbs = {client_on_frame, client_on_close};

static void on_client(void *ctx, conn *c, const cJSON *hello, const char *addr) {
    service *s = ctx;
    client *cl = calloc(1, sizeof *cl);
    if (!cl) {
        conn_close(c, "out of memory", 0);
        return;
    }
    cl->svc = s;
    cl->c = c;
    snprintf(cl->addr, sizeof cl->addr, "%s", addr);
    conn_set_callbacks(c, &client_cbs, cl);
    conn_set_max_frame(c, s->o.max_upload + 1);
    cJSON *w = cJSON_CreateObject();
    cJSON_AddStringToObject(w, "type", "welcome");
    cJSON_AddNumberToObject(w, "protocol", PROTOCOL_VERSION);
    cJSON_AddStringToObject(w, "build", protocol_build_id());
    cJSON_AddNumberToObject(w, "max_upload", (double)s->o.max_upload);
    farm_add_proof(s->f, hello, w);
    client_send_json(cl, w);
}

/* ---- the service ------------------------------------------------------------------------ */

static void on_expiry(uv_timer_t *t) {
    service *s = t->data;
    double now = wall_now();
    for (sjob *j = s->jobs, *next; j; j = next) {
        next = j->next;
        if (j->state == SJOB_RUNNING || now - j->finished < s->o.keep_s) continue;
        static const char *const exts[] = {"json", "pfm", "tiles"};
        char path[4096];
        for (int i = 0; i < 3; i++) {
            job_path(s, j->desc.id, exts[i], path, sizeof path);
            unlink(path);
        }
        svc_log("job %u expired and was deleted", j->desc.id);
        job_unlink_free(s, j);
    }
}

static void on_farm_closed(void *ctx) {
    service *s = ctx;
    uv_close((uv_handle_t *)&s->expiry, NULL);
    uv_close((uv_handle_t *)&s->sigint, NULL);
    uv_close((uv_handle_t *)&s->sigterm, NULL);
}

static void on_signal(uv_signal_t *h, int signum) {
    service *s = h->data;
    if (s->stopping) return;
    s->stopping = 1;
    svc_log("%s: stopping; running jobs resume at the next start", signum == SIGINT ? "SIGINT" : "SIGTERM");
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
    if (write_atomic(path, "ok", 2, err, err_len)) return -1;
    unlink(path);
    return 0;
}

int service_run(const service_options *o) {
    service *s = calloc(1, sizeof *s);
    char err[600];
    if (!s) return 1;
    s->o = *o;
    s->next_id = 1;
    if (prepare_data_dir(o->data_dir, err, sizeof err)) {
        fprintf(stderr, "tessera-coordinator: %s\n", err);
        free(s);
        return 1;
    }
    signal(SIGXFSZ, SIG_IGN); /* a file-size limit is a write error to report, not a reason to die */
    uv_loop_init(&s->loop);
    s->o.farm.on_client = on_client;
    s->o.farm.client_ctx = s;
    s->f = farm_new(&s->loop, &s->o.farm, err, sizeof err);
    if (!s->f) {
        fprintf(stderr, "tessera-coordinator: %s\n", err);
        uv_loop_close(&s->loop);
        free(s);
        return 1;
    }
    svc_log("listening on %s:%d, data in %s", o->farm.host, farm_port(s->f), o->data_dir);
    load_jobs(s);
    uv_signal_init(&s->loop, &s->sigint);
    uv_signal_init(&s->loop, &s->sigterm);
    s->sigint.data = s->sigterm.data = s;
    uv_signal_start(&s->sigint, on_signal, SIGINT);
    uv_signal_start(&s->sigterm, on_signal, SIGTERM);
    uv_timer_init(&s->loop, &s->expiry);
    s->expiry.data = s;
    uv_timer_start(&s->expiry, on_expiry, 1000, 60000);
    uv_run(&s->loop, UV_RUN_DEFAULT);
    farm_free(s->f);
    while (s->jobs) job_unlink_free(s, s->jobs);
    uv_loop_close(&s->loop);
    free(s);
    return 0;
}
