/* pool.h - a worker's render threads, the jobs they render, and the queue
 * of tiles between the event loop and them.
 *
 * The event loop thread (worker.c) creates jobs and pushes tasks; render
 * threads pop tasks, load the job's scene on first use, render the tile and
 * hand the finished task back through pool_take_done(), after calling the
 * `wake` callback (a uv_async_send) so the loop collects it. Network I/O
 * therefore never blocks a render thread, and rendering never blocks the
 * loop. All functions are called from the loop thread unless noted. */
#ifndef TESSERA_WORKER_POOL_H
#define TESSERA_WORKER_POOL_H

#include <stdatomic.h>
#include <stddef.h>
#include <stdint.h>

#include "job/job.h"
#include "list.h"
#include "net/protocol.h"
#include "render/scene_bundle.h"

typedef struct pool pool;
typedef struct pool_job pool_job;

typedef enum { TASK_DONE, TASK_CANCELLED, TASK_FAILED } task_status;

typedef struct pool_task {
    pool_job *job;
    proto_assign assign;
    uint64_t generation; /* the connection it came on (worker.c's counter) */
    atomic_int cancel;
    /* Filled by the render thread: */
    task_status status;
    uint8_t *frame; /* TASK_DONE: the complete 'T' frame; the loop frees it */
    size_t frame_len;
    char error[512]; /* TASK_FAILED: why */
    STAILQ_ENTRY(pool_task) link; /* on the pool's queue or finished list */
} pool_task;

typedef struct {
    int threads;      /* render threads, >= 1 */
    int throttle_ms;  /* > 0: sleep that long after each tile (tests: a slow machine) */
    double keep_s;    /* keep a loaded scene this long after its last job (pool_trim); 0: free it with that job */
    void (*wake)(void *ctx); /* from a render thread, whenever a task finishes */
    void *wake_ctx;
    /* From a render thread: a line saying a scene loaded (with its size,
     * intersector and time) or why it failed. May be NULL. */
    void (*log)(void *ctx, const char *line);
    void *log_ctx;
} pool_config;

/* Start cfg->threads render threads. Returns NULL when the threads or
 * memory can't be had. */
pool *pool_new(const pool_config *cfg);

/* Cancel everything, join the threads and free the pool, its jobs, its
 * scenes and any finished tasks not taken. */
void pool_free(pool *p);

/* A job of desc over the scene bundle's bytes (bundle, len: the worker's,
 * not taken; NULL for a scene the pool holds, pinned or loaded, else an
 * error). Jobs that would load the same scene (the same bundle hash,
 * width, height, max_depth and seed, whatever their spp: an adaptive
 * render's rounds, a service's jobs of one scene) share one: *shared is set to 1 when this job
 * joins a scene the pool holds, and the bytes are then not even read; else
 * they are copied for a render thread to load from, and the scenes no job
 * holds are freed first. Returns NULL with the reason in err (out of
 * memory, a malformed bundle). */
pool_job *pool_job_new(pool *p, const proto_job *desc, const uint8_t *bundle, size_t len, int *shared, char *err,
                       size_t err_len);

/* Hand the pool a scene already loaded, intersector built, as the bundle
 * of this hash would load (a local farm's forked worker: the coordinator
 * loaded it before the fork). The pool owns s from here on (scene_free).
 * It is pinned: jobs of that hash take it without their bundle
 * (pool_job_new with bundle NULL), and no trim or other scene drops it
 * until pool_unpin. Returns 0, or -1 when out of memory (s not taken). */
int pool_preload(pool *p, const char *hash, struct scene *s);

/* Whether the scene of this hash is pinned here (pool_preload). */
int pool_pinned(pool *p, const char *hash);

/* The pinned scenes' hashes, at most max of them into out; returns how
 * many. */
int pool_pinned_hashes(pool *p, char (*out)[SCENE_BUNDLE_HASH_HEX], int max);

/* The coordinator forgot the pinned scene of this hash: from now on it is
 * kept and dropped like any loaded scene. Returns 1 if it was pinned. */
int pool_unpin(pool *p, const char *hash);

/* Free the scenes no job has held for keep_s seconds. Called on the loop's
 * timer. Can't fail. */
void pool_trim(pool *p);

/* Look up a live job by id, or NULL. */
pool_job *pool_job_find(pool *p, uint32_t id);
const proto_job *pool_job_desc(const pool_job *j);

/* Forget a job: it is freed when its last task is done. Queued tasks of it
 * are cancelled. */
void pool_job_end(pool *p, pool_job *j);

/* End every job (a new connection may reuse their ids). */
void pool_job_end_all(pool *p);

/* Queue a tile. The task is the pool's until it comes back from
 * pool_take_done(). Returns 0 or -1 when out of memory. */
int pool_push(pool *p, pool_job *j, const proto_assign *a, uint64_t generation);

/* Ask the task rendering or queued for (job, tile) to stop. Returns 1 if
 * one was found. */
int pool_cancel(pool *p, uint32_t job, uint32_t tile);

/* The worker is leaving: every task is cancelled (queued ones come back
 * as TASK_CANCELLED), and a scene being loaded stops at its next step
 * (between mesh files and shapes, or within the BVH build) and fails with
 * "cancelled", so that pool_free does not wait for a load whose result
 * nobody will use. Irreversible. */
void pool_leave(pool *p);

/* Finished tasks, oldest first: the first, the others following it by
 * STAILQ_NEXT(t, link); the caller frees each with pool_task_free (which
 * releases the task's hold on its job). Can't fail; NULL when none. */
pool_task *pool_take_done(pool *p);
void pool_task_free(pool *p, pool_task *t);

#endif
