/* pool.c - render threads fed from a queue of tile tasks (see pool.h).
 *
 * One mutex guards the queue, the finished list, the running slots, the
 * job and scene reference counts; render threads hold it only to pop and
 * push tasks. A scene is built by the first thread that needs it, under the
 * scene's own lock, so a big mesh never stalls the event loop; jobs that
 * would load the same scene share it (pool_scene). */
#include "pool.h"

#include <math.h>
#include <pthread.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

#include "render/accel.h"
#include "render/scene.h"
#include "render/scene_memory.h"

/* A loaded scene and the jobs that share it: those of one bundle (by hash)
 * at any image size, seed, depth and spp (each job renders through
 * job_view). An adaptive render's rounds, and a service's jobs of one
 * scene (a preview, then the final), load it once. Once its last
 * job is gone it is kept for cfg.keep_s (pool_trim), or until a job needs
 * a scene it is not; a failed load is never shared. */
typedef struct pool_scene {
    char hash[SCENE_BUNDLE_HASH_HEX];
    int width, height;   /* the loading job's, as are the next three: stored in the scene, replaced by job_view */
    int max_depth, spp;
    uint64_t seed;
    scene_bundle bundle; /* until the scene is loaded */
    scene *s;
    int load_state;      /* under load_lock: 0 not tried, 1 loaded, -1 failed (load_error says why) */
    atomic_int failed;   /* load_state == -1, read without load_lock */
    char load_error[512];
    pthread_mutex_t load_lock;
    int refs;            /* jobs holding it; under pool.lock */
    int pinned;          /* handed over loaded (pool_preload) and claimed in the hello: kept until unpinned */
    double idle_since;   /* pool_clock() when refs fell to 0 */
    LIST_ENTRY(pool_scene) link; /* on the pool's scene list */
} pool_scene;

struct pool_job {
    proto_job desc;
    pool_scene *sc;
    int refs;  /* the pool's table (until ended) + one per task; under pool.lock */
    int ended;
    LIST_ENTRY(pool_job) link; /* on the pool's table */
};

struct pool {
    pthread_mutex_t lock;
    pthread_cond_t cond;
    STAILQ_HEAD(task_queue, pool_task) queue, done; /* waiting; finished, for the loop */
    pool_task **running; /* per thread, or NULL */
    LIST_HEAD(job_table, pool_job) jobs;
    LIST_HEAD(scene_list, pool_scene) scenes;
    pool_config cfg;
    pthread_t *threads;
    int thread_count;
    int stopping;
    atomic_int leaving;    /* pool_leave: loads in progress give up */
    const char *hold_path; /* test hook, see test_hold(); NULL unless set */
    long hold_after, hold_seen;
    int fault_kind;       /* test hook, see test_fault(): 0 none, 1 scale, 2 flipbit, 3 crash, 4 fail */
    double fault_scale;   /* scale: multiply every value by this */
    long fault_every, fault_seen; /* flipbit: one tile in fault_every, counting from the first */
};

typedef struct {
    pool *p;
    int index;
} thread_arg;

/* Seconds on a clock that only goes forward. */
static double pool_clock(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static void scene_entry_free(pool_scene *sc) {
    scene_free(sc->s);
    scene_bundle_free(&sc->bundle);
    pthread_mutex_destroy(&sc->load_lock);
    free(sc);
}

/* Free the scenes no job holds (all of them, or those idle for longer than
 * max_idle_s); under the lock. */
static void scenes_drop_idle(pool *p, double max_idle_s) {
    double now = pool_clock();
    pool_scene *sc = LIST_FIRST(&p->scenes), *next;
    for (; sc; sc = next) {
        next = LIST_NEXT(sc, link);
        if (sc->refs > 0 || sc->pinned || (max_idle_s > 0 && now - sc->idle_since < max_idle_s)) continue;
        LIST_REMOVE(sc, link);
        scene_entry_free(sc);
    }
}

/* A job lets go of its scene; under the lock. A failed one goes at once,
 * and so does any when nothing is kept (keep_s 0). */
static void scene_unref(pool *p, pool_scene *sc) {
    if (--sc->refs > 0) return;
    sc->idle_since = pool_clock();
    if (sc->pinned || (p->cfg.keep_s > 0 && !atomic_load(&sc->failed))) return;
    LIST_REMOVE(sc, link);
    scene_entry_free(sc);
}

/* Unlink j from the table; under the lock. */
static void job_unlink(pool *p, pool_job *j) {
    (void)p;
    LIST_REMOVE(j, link);
}

/* Drop one reference; under the lock. Frees the job at zero. */
static void job_unref(pool *p, pool_job *j) {
    if (--j->refs > 0) return;
    scene_unref(p, j->sc);
    free(j);
}

/* One line through cfg.log, if set; from a render thread. */
static void pool_log(pool *p, const char *fmt, ...) __attribute__((format(printf, 2, 3)));
static void pool_log(pool *p, const char *fmt, ...) {
    if (!p->cfg.log) return;
    char line[700];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(line, sizeof line, fmt, ap);
    va_end(ap);
    p->cfg.log(p->cfg.log_ctx, line);
}

/* The scene as job j renders it: its loaded scene with the job's own
 * size, seed, depth and spp, and an automatic camera framed for that size
 * (the one part of a load that depends on it: scene_frame_camera). A
 * shallow copy (plain struct): everything else is the shared scene's,
 * read-only. */
static scene job_view(const pool_job *j) {
    scene v = *j->sc->s;
    v.settings.width = j->desc.width;
    v.settings.height = j->desc.height;
    v.settings.seed = j->desc.seed;
    v.settings.max_depth = j->desc.max_depth;
    v.settings.roulette_depth = j->desc.roulette_depth;
    v.settings.spp = j->desc.spp;
    scene_frame_camera(&v);
    return v;
}

/* scene_cancel_cb of the pool's loads: once it is leaving. */
static int pool_leaving(void *ctx) {
    pool *p = ctx;
    return atomic_load_explicit(&p->leaving, memory_order_relaxed);
}

/* Build job j's scene if no thread has yet. Returns 0 when it is ready. */
static int job_ensure_scene(pool *p, pool_job *j) {
    pool_scene *sc = j->sc;
    pthread_mutex_lock(&sc->load_lock);
    if (sc->load_state == 0) {
        double t0 = pool_clock();
        /* no_accel: the intersector is built below, once the bundle is gone */
        scene_overrides ov = {.width = sc->width, .height = sc->height, .spp = sc->spp, .max_depth = sc->max_depth,
                              .has_seed = 1, .seed = sc->seed, .no_accel = 1, .keep_spare = 1, .cancelled = pool_leaving,
                              .cancel_ctx = p};
        sc->s = scene_memory_check(&sc->bundle, sc->load_error, sizeof sc->load_error) ? NULL
                : scene_load_bundle(&sc->bundle, &ov, sc->load_error, sizeof sc->load_error);
        scene_bundle_free_keeping(&sc->bundle, sc->s); /* the scene holds what it needs: the meshes' text goes before the build */
        if (sc->s && scene_build_accel(sc->s, sc->load_error, sizeof sc->load_error)) {
            scene_free(sc->s);
            sc->s = NULL;
        }
        sc->load_state = sc->s ? 1 : -1;
        atomic_store(&sc->failed, sc->load_state == -1);
        if (sc->s)
            pool_log(p, "job %u: scene %.12s loaded, %u triangles, intersector %s, in %.2f s", j->desc.id, sc->hash,
                     sc->s->triangle_count, accel_kind_name(accel_get_kind(sc->s->accel)), pool_clock() - t0);
        else
            pool_log(p, "job %u: scene %.12s: %s", j->desc.id, sc->hash, sc->load_error);
    }
    int rc = sc->load_state == 1 ? 0 : -1;
    pthread_mutex_unlock(&sc->load_lock);
    return rc;
}

static void sleep_ms(int ms) {
    struct timespec ts = {ms / 1000, (long)(ms % 1000) * 1000000L};
    nanosleep(&ts, NULL);
}

/* Test hook, inert unless $TESSERA_TEST_HOLD_FILE is set (read once, in
 * pool_new): a finished tile is kept, not handed back, while that file
 * exists, except the first $TESSERA_TEST_HOLD_AFTER (default 0) tiles this
 * process finishes. The first wait for a tile is logged ("test hold:
 * keeping tile T of job J"); it ends when the file goes, or as cancelled
 * when the tile is cancelled or the worker stops. Tests use it to hold a
 * worker mid-render until they say so, whatever the machine's speed.
 * Called on a render thread. */
static void test_hold(pool *p, pool_task *t) {
    pthread_mutex_lock(&p->lock);
    int exempt = ++p->hold_seen <= p->hold_after;
    pthread_mutex_unlock(&p->lock);
    for (int waited = 0; !exempt && access(p->hold_path, F_OK) == 0; waited++) {
        if (atomic_load(&t->cancel)) {
            free(t->frame);
            t->frame = NULL;
            t->status = TASK_CANCELLED;
            return;
        }
        if (!waited)
            fprintf(stderr, "tessera-worker: test hold: keeping tile %u of job %u while %s exists\n", t->assign.tile,
                    t->assign.job, p->hold_path);
        sleep_ms(5);
    }
}

/* Test hook, inert unless $TESSERA_TEST_FAULT is set (read once, in
 * pool_new) - a deliberately faulty worker for the audit tests
 * (tests/test_audit.c, farm_audit.c):
 *   scale:S    every value of every tile is multiplied by 1 + S (1e-6: a
 *              wrong answer that looks right);
 *   flipbit:N  the lowest bit of one value is flipped in this process's 1st,
 *              (N+1)th, (2N+1)th... tile.
 * The values stay finite and non-negative, so only a comparison finds them.
 * And for the blocklist tests (farm_block.c), test_fault_early:
 *   crash      the process exits (status 70) as soon as it starts a tile;
 *   fail       every tile is reported failed.
 * Called on a render thread with the tile's n values. */
static void test_fault(pool *p, const pool_task *t, float *v, size_t n) {
    if (p->fault_kind == 1) {
        for (size_t i = 0; i < n; i++) v[i] = (float)((double)v[i] * p->fault_scale);
        return;
    }
    pthread_mutex_lock(&p->lock);
    int hit = p->fault_seen++ % p->fault_every == 0;
    pthread_mutex_unlock(&p->lock);
    if (!hit || n == 0) return;
    size_t i = (size_t)t->assign.tile % n;
    uint32_t bits;
    memcpy(&bits, &v[i], sizeof bits);
    bits ^= 1u;
    memcpy(&v[i], &bits, sizeof bits);
}

/* The crash and fail faults (see test_fault), before tile t is rendered:
 * 1 when t is failed on purpose, else 0. Called on a render thread. */
static int test_fault_early(const pool *p, pool_task *t) {
    if (p->fault_kind == 3) {
        fprintf(stderr, "tessera-worker: test fault crash: exiting on tile %u of job %u\n", t->assign.tile,
                t->assign.job);
        _exit(70);
    }
    if (p->fault_kind != 4) return 0;
    t->status = TASK_FAILED;
    snprintf(t->error, sizeof t->error, "test fault: tile %u failed on purpose", t->assign.tile);
    return 1;
}

/* Parse $TESSERA_TEST_FAULT into p (see test_fault); unset or malformed:
 * no fault (a malformed value is reported on stderr). */
static void test_fault_init(pool *p) {
    const char *s = getenv("TESSERA_TEST_FAULT");
    if (!s || !*s) return;
    double x;
    long every;
    if (sscanf(s, "scale:%lf", &x) == 1 && isfinite(x) && x > -1) {
        p->fault_kind = 1;
        p->fault_scale = 1.0 + x;
    } else if (sscanf(s, "flipbit:%ld", &every) == 1 && every >= 1) {
        p->fault_kind = 2;
        p->fault_every = every;
    } else if (strcmp(s, "crash") == 0 || strcmp(s, "fail") == 0) {
        p->fault_kind = s[0] == 'c' ? 3 : 4;
    } else {
        fprintf(stderr, "tessera-worker: TESSERA_TEST_FAULT=%s not understood (scale:S, flipbit:N, crash or fail); "
                "ignored\n", s);
        return;
    }
    fprintf(stderr, "tessera-worker: test fault %s: this worker %s on purpose\n", s,
            p->fault_kind == 3 ? "crashes" : p->fault_kind == 4 ? "fails its tiles" : "returns wrong tiles");
}

/* Render one task, setting its status and frame or error. */
static void task_render(pool *p, pool_task *t) {
    pool_job *j = t->job;
    const proto_assign *a = &t->assign;
    if (p->fault_kind >= 3 && test_fault_early(p, t)) return;
    if (job_ensure_scene(p, j)) {
        t->status = TASK_FAILED;
        snprintf(t->error, sizeof t->error, "%s", j->sc->load_error);
        return;
    }
    /* A plain job renders all its samples; an adaptive round, the range and
     * pixels it is given, within the job's samples. */
    int adaptive = j->desc.adaptive;
    if (a->rect.x1 > j->desc.width || a->rect.y1 > j->desc.height ||
        (!adaptive && (a->first != 0 || a->count != (uint32_t)j->desc.spp)) ||
        (adaptive && (!a->mask || (uint64_t)a->first + a->count > (uint64_t)j->desc.spp))) {
        t->status = TASK_FAILED;
        snprintf(t->error, sizeof t->error, "tile %u: rectangle, sample range or mask do not fit job %u", a->tile,
                 a->job);
        return;
    }
    int w = tile_width(&a->rect), h = tile_height(&a->rect);
    int channels = adaptive ? ADAPTIVE_CHANNELS : 3;
    double *accum = malloc(3 * sizeof(double) * (size_t)w);
    float *rgb = malloc((size_t)channels * sizeof(float) * (size_t)w * (size_t)h);
    proto_tile hdr = {a->job, a->tile, (uint32_t)w, (uint32_t)h, {0, 0, 0, 0}, (uint32_t)channels};
    t->status = TASK_FAILED;
    snprintf(t->error, sizeof t->error, "out of memory for tile %u", a->tile);
    if (accum && rgb) {
        scene view = job_view(j);
        int rc = adaptive ? render_tile_sums(&view, &j->desc.integrator, &a->rect, a->first, a->count, a->mask, rgb,
                                             &hdr.stats, &t->cancel)
                          : render_tile_means(&view, &j->desc.integrator, &a->rect, j->desc.spp, 1, accum, rgb,
                                              &hdr.stats, &t->cancel);
        if (rc == 0 && (p->fault_kind == 1 || p->fault_kind == 2)) test_fault(p, t, rgb, (size_t)channels * (size_t)w * (size_t)h);
        if (rc != 0) {
            t->status = TASK_CANCELLED;
        } else if ((t->frame = proto_tile_frame(&hdr, rgb, &t->frame_len)) != NULL) {
            t->status = TASK_DONE;
            if (p->cfg.throttle_ms > 0) sleep_ms(p->cfg.throttle_ms);
            if (p->hold_path) test_hold(p, t);
        }
    }
    free(accum);
    free(rgb);
}

/* Append t to the finished list; under the lock. */
static void done_append(pool *p, pool_task *t) {
    STAILQ_INSERT_TAIL(&p->done, t, link);
}

static void *pool_thread(void *arg) {
    thread_arg *ta = arg;
    pool *p = ta->p;
    pthread_mutex_lock(&p->lock);
    for (;;) {
        while (!p->stopping && STAILQ_EMPTY(&p->queue)) pthread_cond_wait(&p->cond, &p->lock);
        if (p->stopping) break;
        pool_task *t = STAILQ_FIRST(&p->queue);
        STAILQ_REMOVE_HEAD(&p->queue, link);
        p->running[ta->index] = t;
        pthread_mutex_unlock(&p->lock);
        if (atomic_load(&t->cancel))
            t->status = TASK_CANCELLED;
        else
            task_render(p, t);
        pthread_mutex_lock(&p->lock);
        p->running[ta->index] = NULL;
        done_append(p, t);
        pthread_mutex_unlock(&p->lock);
        p->cfg.wake(p->cfg.wake_ctx);
        pthread_mutex_lock(&p->lock);
    }
    pthread_mutex_unlock(&p->lock);
    free(ta);
    return NULL;
}

pool *pool_new(const pool_config *cfg) {
    pool *p = calloc(1, sizeof *p);
    if (!p) return NULL;
    int threads = cfg->threads;
    p->cfg = *cfg;
    p->running = calloc((size_t)threads, sizeof *p->running);
    p->threads = calloc((size_t)threads, sizeof *p->threads);
    p->hold_path = getenv("TESSERA_TEST_HOLD_FILE");
    if (p->hold_path && !*p->hold_path) p->hold_path = NULL;
    test_fault_init(p);
    if (p->hold_path && getenv("TESSERA_TEST_HOLD_AFTER")) p->hold_after = atol(getenv("TESSERA_TEST_HOLD_AFTER"));
    STAILQ_INIT(&p->queue);
    STAILQ_INIT(&p->done);
    LIST_INIT(&p->jobs);
    LIST_INIT(&p->scenes);
    pthread_mutex_init(&p->lock, NULL);
    pthread_cond_init(&p->cond, NULL);
    if (!p->running || !p->threads) {
        pool_free(p);
        return NULL;
    }
    for (int i = 0; i < threads; i++) {
        thread_arg *ta = malloc(sizeof *ta);
        if (ta) *ta = (thread_arg){p, i};
        if (!ta || pthread_create(&p->threads[i], NULL, pool_thread, ta) != 0) {
            free(ta);
            pool_free(p);
            return NULL;
        }
        p->thread_count++;
    }
    return p;
}

void pool_free(pool *p) {
    if (!p) return;
    pool_leave(p);
    pthread_mutex_lock(&p->lock);
    p->stopping = 1;
    pthread_cond_broadcast(&p->cond);
    pthread_mutex_unlock(&p->lock);
    for (int i = 0; i < p->thread_count; i++) pthread_join(p->threads[i], NULL);
    pool_task *t = pool_take_done(p);
    while (t) {
        pool_task *next = STAILQ_NEXT(t, link);
        pool_task_free(p, t);
        t = next;
    }
    while (!LIST_EMPTY(&p->jobs)) {
        pool_job *j = LIST_FIRST(&p->jobs);
        LIST_REMOVE(j, link);
        job_unref(p, j);
    }
    pool_scene *sc; /* every job is gone, and every hold on a scene; the threads too (no lock needed) */
    LIST_FOREACH(sc, &p->scenes, link) sc->pinned = 0;
    scenes_drop_idle(p, 0);
    pthread_mutex_destroy(&p->lock);
    pthread_cond_destroy(&p->cond);
    free(p->running);
    free(p->threads);
    free(p);
}

/* The scene a job of desc would load, if the pool holds it and its load
 * has not failed; under the lock. */
static pool_scene *scene_find(pool *p, const proto_job *d) {
    pool_scene *sc;
    LIST_FOREACH(sc, &p->scenes, link)
        if (strcmp(sc->hash, d->scene_hash) == 0 && !atomic_load(&sc->failed))
            return sc;
    return NULL;
}

/* A new scene entry for desc from the bundle's bytes (copied). Returns
 * NULL with the reason in err. */
static pool_scene *scene_entry_new(const proto_job *d, const uint8_t *bundle, size_t len, char *err, size_t err_len) {
    pool_scene *sc = calloc(1, sizeof *sc);
    if (!sc) return snprintf(err, err_len, "out of memory for a job"), NULL;
    if (scene_bundle_parse(bundle, len, &sc->bundle, err, err_len)) {
        free(sc);
        return NULL;
    }
    memcpy(sc->hash, d->scene_hash, sizeof sc->hash);
    sc->width = d->width, sc->height = d->height, sc->spp = d->spp, sc->max_depth = d->max_depth;
    sc->seed = d->seed;
    atomic_init(&sc->failed, 0);
    pthread_mutex_init(&sc->load_lock, NULL);
    return sc;
}

pool_job *pool_job_new(pool *p, const proto_job *desc, const uint8_t *bundle, size_t len, int *shared, char *err,
                       size_t err_len) {
    pool_job *j = calloc(1, sizeof *j);
    if (!j) return snprintf(err, err_len, "out of memory for a job"), NULL;
    j->desc = *desc;
    j->refs = 1;
    pthread_mutex_lock(&p->lock);
    pool_scene *sc = scene_find(p, desc);
    *shared = sc != NULL;
    if (!sc && !bundle) {
        pthread_mutex_unlock(&p->lock);
        free(j);
        snprintf(err, err_len, "job %u: scene %s is not held here", desc->id, desc->scene_hash);
        return NULL;
    }
    if (!sc) {
        scenes_drop_idle(p, 0); /* before this scene's load: memory for one, not two */
        pthread_mutex_unlock(&p->lock);
        sc = scene_entry_new(desc, bundle, len, err, err_len); /* the copy, outside the lock */
        pthread_mutex_lock(&p->lock);
        if (sc) LIST_INSERT_HEAD(&p->scenes, sc, link);
    }
    if (!sc) {
        pthread_mutex_unlock(&p->lock);
        free(j);
        return NULL;
    }
    sc->refs++;
    j->sc = sc;
    LIST_INSERT_HEAD(&p->jobs, j, link);
    pthread_mutex_unlock(&p->lock);
    return j;
}

int pool_preload(pool *p, const char *hash, scene *s) {
    pool_scene *sc = calloc(1, sizeof *sc);
    if (!sc) return -1;
    snprintf(sc->hash, sizeof sc->hash, "%s", hash);
    sc->s = s; /* loaded: the load settings (width ... seed) are never read */
    sc->load_state = 1;
    sc->pinned = 1;
    atomic_init(&sc->failed, 0);
    pthread_mutex_init(&sc->load_lock, NULL);
    pthread_mutex_lock(&p->lock);
    sc->idle_since = pool_clock();
    LIST_INSERT_HEAD(&p->scenes, sc, link);
    pthread_mutex_unlock(&p->lock);
    return 0;
}

/* The pinned scene of this hash; under the lock. */
static pool_scene *pinned_find(pool *p, const char *hash) {
    pool_scene *sc;
    LIST_FOREACH(sc, &p->scenes, link)
        if (sc->pinned && strcmp(sc->hash, hash) == 0) return sc;
    return NULL;
}

int pool_pinned(pool *p, const char *hash) {
    pthread_mutex_lock(&p->lock);
    int found = pinned_find(p, hash) != NULL;
    pthread_mutex_unlock(&p->lock);
    return found;
}

int pool_pinned_hashes(pool *p, char (*out)[SCENE_BUNDLE_HASH_HEX], int max) {
    int n = 0;
    pthread_mutex_lock(&p->lock);
    pool_scene *sc;
    LIST_FOREACH(sc, &p->scenes, link)
        if (sc->pinned && n < max) memcpy(out[n++], sc->hash, SCENE_BUNDLE_HASH_HEX);
    pthread_mutex_unlock(&p->lock);
    return n;
}

int pool_unpin(pool *p, const char *hash) {
    pthread_mutex_lock(&p->lock);
    pool_scene *sc = pinned_find(p, hash);
    if (sc) {
        sc->pinned = 0;
        sc->idle_since = pool_clock();
        if (sc->refs == 0 && p->cfg.keep_s <= 0) {
            LIST_REMOVE(sc, link);
            scene_entry_free(sc);
        }
    }
    pthread_mutex_unlock(&p->lock);
    return sc != NULL;
}

void pool_trim(pool *p) {
    pthread_mutex_lock(&p->lock);
    scenes_drop_idle(p, p->cfg.keep_s);
    pthread_mutex_unlock(&p->lock);
}

pool_job *pool_job_find(pool *p, uint32_t id) {
    pthread_mutex_lock(&p->lock);
    pool_job *j;
    LIST_FOREACH(j, &p->jobs, link)
        if (j->desc.id == id) break;
    pthread_mutex_unlock(&p->lock);
    return j;
}

/* Any live job, or NULL. */
static pool_job *pool_job_first(pool *p) {
    pthread_mutex_lock(&p->lock);
    pool_job *j = LIST_FIRST(&p->jobs);
    pthread_mutex_unlock(&p->lock);
    return j;
}

const proto_job *pool_job_desc(const pool_job *j) { return &j->desc; }

/* Move queued tasks that match (job, or all when job is NULL) to the
 * finished list as cancelled, and flag matching running ones; under the
 * lock. Returns how many matched. */
static int cancel_matching(pool *p, const pool_job *job, int match_tile, uint32_t tile) {
    int n = 0;
    pool_task *t, *next;
    STAILQ_FOREACH_SAFE(t, &p->queue, link, next)
        if ((!job || t->job == job) && (!match_tile || t->assign.tile == tile)) {
            STAILQ_REMOVE(&p->queue, t, pool_task, link);
            t->status = TASK_CANCELLED;
            done_append(p, t);
            n++;
        }
    for (int i = 0; i < p->thread_count; i++) {
        pool_task *t = p->running[i];
        if (t && (!job || t->job == job) && (!match_tile || t->assign.tile == tile)) {
            atomic_store(&t->cancel, 1);
            n++;
        }
    }
    return n;
}

void pool_job_end(pool *p, pool_job *j) {
    pthread_mutex_lock(&p->lock);
    int n = 0;
    if (!j->ended) {
        j->ended = 1;
        job_unlink(p, j);
        n = cancel_matching(p, j, 0, 0);
        job_unref(p, j);
    }
    pthread_mutex_unlock(&p->lock);
    if (n) p->cfg.wake(p->cfg.wake_ctx);
}

void pool_job_end_all(pool *p) {
    pool_job *j;
    while ((j = pool_job_first(p)) != NULL) pool_job_end(p, j);
}

int pool_push(pool *p, pool_job *j, const proto_assign *a, uint64_t generation) {
    pool_task *t = calloc(1, sizeof *t);
    if (!t) return -1;
    t->job = j;
    t->assign = *a;
    t->generation = generation;
    atomic_init(&t->cancel, 0);
    pthread_mutex_lock(&p->lock);
    j->refs++;
    STAILQ_INSERT_TAIL(&p->queue, t, link);
    pthread_cond_signal(&p->cond);
    pthread_mutex_unlock(&p->lock);
    return 0;
}

int pool_cancel(pool *p, uint32_t job, uint32_t tile) {
    pthread_mutex_lock(&p->lock);
    pool_job *j;
    LIST_FOREACH(j, &p->jobs, link)
        if (j->desc.id == job) break;
    int n = j ? cancel_matching(p, j, 1, tile) : 0;
    pthread_mutex_unlock(&p->lock);
    if (n) p->cfg.wake(p->cfg.wake_ctx);
    return n > 0;
}

/* Cancel every task (queued ones come back as TASK_CANCELLED). */
static void pool_cancel_all(pool *p) {
    pthread_mutex_lock(&p->lock);
    int n = cancel_matching(p, NULL, 0, 0);
    pthread_mutex_unlock(&p->lock);
    if (n) p->cfg.wake(p->cfg.wake_ctx);
}

void pool_leave(pool *p) {
    atomic_store(&p->leaving, 1);
    pool_cancel_all(p);
}

pool_task *pool_take_done(pool *p) {
    pthread_mutex_lock(&p->lock);
    pool_task *t = STAILQ_FIRST(&p->done); /* the list's elements stay chained */
    STAILQ_INIT(&p->done);
    pthread_mutex_unlock(&p->lock);
    return t;
}

void pool_task_free(pool *p, pool_task *t) {
    if (!t) return;
    pthread_mutex_lock(&p->lock);
    job_unref(p, t->job);
    pthread_mutex_unlock(&p->lock);
    free(t->frame);
    free(t->assign.mask);
    free(t);
}
