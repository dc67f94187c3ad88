/* upload.h - a submitted scene checked off the loop thread: hashing the
 * bundle, parsing and validating the scene and its meshes, and storing the
 * bundle (scenes/HASH, synced) run on libuv's thread pool (uv_queue_work),
 * one upload at a time, so that the loop keeps serving heartbeats, tiles
 * and `status` however large the scene. What one validation may allocate
 * is bounded: the scene's JSON text is refused past UPLOAD_JSON_MAX before
 * it is parsed (cJSON takes 17 to 42 times the text's size). */
#ifndef TESSERA_UPLOAD_H
#define TESSERA_UPLOAD_H

#include <stddef.h>
#include <stdint.h>
#include <uv.h>

#include "list.h"
#include "net/conn.h"
#include "render/scene.h"
#include "render/scene_bundle.h"

#define UPLOAD_JSON_MAX_MIB 16
#define UPLOAD_JSON_MAX ((size_t)UPLOAD_JSON_MAX_MIB << 20) /* a scene's JSON text, bytes */

typedef struct upload upload;
typedef void (*upload_cb)(upload *u);

/* One submit's scene, from the loop to the pool and back. */
struct upload {
    uv_work_t work;
    /* in (the loop's) */
    uint8_t *bundle;     /* the bundle's bytes, inside bundle_mem */
    uint8_t *bundle_mem; /* owned: the memory to free (the client's whole frame) */
    size_t len;
    char claimed_hash[SCENE_BUNDLE_HASH_HEX]; /* the submit's "scene" */
    scene_overrides ov;
    char store_path_dir[4096];  /* DATA/scenes */
    upload_cb done;             /* on the loop, after the work */
    void *ctx;
    /* out (the pool's until done runs) */
    int rc;                     /* 0, or -1 with err */
    char err[1024];
    char hash[SCENE_BUNDLE_HASH_HEX];
    render_settings settings;   /* the loaded scene's, with the overrides */
    conn_blob *blob;            /* the bundle framed for the farm (farm_job_options.scene), copied on
                                 * the pool so that the loop copies nothing; NULL when out of memory */
    struct upload_queue *queue;
    TAILQ_ENTRY(upload) link;   /* on the queue while waiting its turn */
};

typedef struct upload_queue {
    uv_loop_t *loop;
    TAILQ_HEAD(upload_list, upload) waiting;
    upload *running;
} upload_queue;

void upload_queue_init(upload_queue *q, uv_loop_t *loop);

/* Queue u; it is validated after those before it, and u->done(u) runs on
 * the loop when it ends (the callee frees u with upload_free). Can't fail. */
void upload_queue_add(upload_queue *q, upload *u);

/* How many uploads are waiting or being validated. */
int upload_queue_length(const upload_queue *q);

void upload_free(upload *u);

#endif
