/* upload.c - submitted scenes validated on libuv's thread pool, one at a
 * time (upload.h). The pool thread touches only its upload; the queue is
 * the loop's. */
#include "upload.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "fileio.h"
#include "net/wire.h"

void upload_queue_init(upload_queue *q, uv_loop_t *loop) {
    q->loop = loop;
    TAILQ_INIT(&q->waiting);
    q->running = NULL;
}

/* On the pool: hash, parse, validate, store. */
static void validate(uv_work_t *w) {
    upload *u = w->data;
    scene_bundle_hash(u->bundle, u->len, u->hash);
    if (strcmp(u->claimed_hash, u->hash) != 0) {
        snprintf(u->err, sizeof u->err, "submit: \"scene\" is not the hash of the uploaded scene (%s)", u->hash);
        u->rc = -1;
        return;
    }
    scene_bundle b;
    if (scene_bundle_parse(u->bundle, u->len, &b, u->err, sizeof u->err)) {
        u->rc = -1;
        return;
    }
    if (b.count > 0 && b.files[0].len > UPLOAD_JSON_MAX) {
        snprintf(u->err, sizeof u->err,
                 "%.200s: the scene's JSON is %.1f MiB; the coordinator parses at most %d MiB of scene JSON "
                 "(put large geometry in OBJ meshes)",
                 b.files[0].name, (double)b.files[0].len / 1048576.0, UPLOAD_JSON_MAX_MIB);
        scene_bundle_free(&b);
        u->rc = -1;
        return;
    }
    scene *sc = scene_load_bundle(&b, &u->ov, u->err, sizeof u->err); /* the loader's message: file, field */
    scene_bundle_free(&b);
    if (!sc) {
        u->rc = -1;
        return;
    }
    u->settings = sc->settings;
    scene_free(sc);
    char path[4200];
    snprintf(path, sizeof path, "%s/%s", u->store_path_dir, u->hash);
    u->rc = file_write_atomic(path, u->bundle, u->len, u->err, sizeof u->err);
    if (u->rc == 0) u->blob = conn_blob_frame(WIRE_KIND_SCENE, u->bundle, u->len); /* fresh pages fault here, not on the loop */
}

static void start_next(upload_queue *q);

static void after_validate(uv_work_t *w, int status) {
    upload *u = w->data;
    upload_queue *q = u->queue;
    if (status != 0 && u->rc == 0) {
        u->rc = -1;
        snprintf(u->err, sizeof u->err, "the scene's validation was cancelled");
    }
    q->running = NULL;
    u->done(u); /* frees u */
    start_next(q);
}

static void start_next(upload_queue *q) {
    if (q->running || TAILQ_EMPTY(&q->waiting)) return;
    upload *u = TAILQ_FIRST(&q->waiting);
    TAILQ_REMOVE(&q->waiting, u, link);
    q->running = u;
    u->work.data = u;
    if (uv_queue_work(q->loop, &u->work, validate, after_validate) != 0) {
        validate(&u->work);
        after_validate(&u->work, 0);
    }
}

void upload_queue_add(upload_queue *q, upload *u) {
    u->queue = q;
    TAILQ_INSERT_TAIL(&q->waiting, u, link);
    start_next(q);
}

int upload_queue_length(const upload_queue *q) {
    int n = q->running != NULL;
    const upload *u;
    TAILQ_FOREACH(u, &q->waiting, link) n++;
    return n;
}

void upload_free(upload *u) {
    if (!u) return;
    free(u->bundle_mem);
    conn_blob_unref(u->blob);
    free(u);
}
