/* retention.c - finished jobs expire (--keep-hours), at most --keep-jobs
 * are kept, and an uploaded scene is removed once no job names it, so the
 * data dir returns to its starting size. Bounded work per sweep, so that
 * a backlog of thousands of expired jobs never stalls the loop. */
#define _GNU_SOURCE
#include "service_internal.h"

#include "render/name_index.h"

#define RETENTION_MAX_PER_SWEEP 200 /* jobs deleted per sweep; the rest at the next */

/* Delete a finished job's files and record; its scene hash goes to gone[]. */
static void delete_job(service *s, sjob *j, const char *why) {
    static const char *const exts[] = {"json", "pfm", "tiles", "log"};
    char path[4096];
    for (int i = 0; i < 4; i++) {
        store_job_path(s, j->desc.id, exts[i], path, sizeof path);
        unlink(path);
    }
    svc_log("job %u %s and was deleted", j->desc.id, why);
    store_job_unlink_free(s, j);
}

/* Remove scenes/HASH for each hash in gone[0..n) that no remaining job and
 * no upload being checked names. */
static void remove_orphan_scenes(service *s, char (*gone)[SCENE_BUNDLE_HASH_HEX], int n) {
    int jobs = 0;
    sjob *j;
    TAILQ_FOREACH(j, &s->jobs, link) jobs++;
    name_index used;
    if (name_index_init(&used, (size_t)jobs + 64)) return; /* out of memory: try at the next sweep's deletions */
    TAILQ_FOREACH(j, &s->jobs, link) name_index_add(&used, j->desc.scene_hash, 1);
    const upload *u;
    if (s->uploads.running) name_index_add(&used, s->uploads.running->claimed_hash, 1);
    TAILQ_FOREACH(u, &s->uploads.waiting, link) name_index_add(&used, u->claimed_hash, 1);
    char path[4096];
    for (int i = 0; i < n; i++) {
        if (name_index_find(&used, gone[i]) >= 0) continue;
        name_index_add(&used, gone[i], 1); /* once */
        snprintf(path, sizeof path, "%.3900s/scenes/%.64s", s->o.data_dir, gone[i]);
        if (unlink(path) == 0) svc_log("scene %.12s... removed: no kept job names it", gone[i]);
    }
    name_index_free(&used);
}

/* One sweep: expire, cap, remove orphan scenes. Returns 1 when work is
 * left for another sweep soon. */
int retention_sweep(service *s) {
    double now = svc_wall_now();
    int finished = 0, deleted = 0;
    sjob *j, *next;
    TAILQ_FOREACH(j, &s->jobs, link) finished += j->state != SJOB_RUNNING;
    int excess = s->o.keep_jobs > 0 && finished > s->o.keep_jobs ? finished - s->o.keep_jobs : 0;
    static char gone[RETENTION_MAX_PER_SWEEP][SCENE_BUNDLE_HASH_HEX];
    TAILQ_FOREACH_SAFE(j, &s->jobs, link, next) {
        if (deleted == RETENTION_MAX_PER_SWEEP) break;
        if (j->state == SJOB_RUNNING || j->save_timer || j->admitting) continue;
        int old = now - j->finished >= s->o.keep_s;
        if (!old && excess <= 0) continue;
        memcpy(gone[deleted++], j->desc.scene_hash, SCENE_BUNDLE_HASH_HEX);
        if (!old) excess--;
        delete_job(s, j, old ? "expired" : "was over --keep-jobs");
    }
    if (deleted) remove_orphan_scenes(s, gone, deleted);
    return deleted == RETENTION_MAX_PER_SWEEP;
}
