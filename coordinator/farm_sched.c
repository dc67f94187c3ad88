/* farm_sched.c - jobs and their tile queues, leases, assignment to workers
 * with credits, backup copies of slow tiles, and the public job calls
 * (submit, cancel, forget, report). Invariant: farm_internal.h. */
#include "farm_internal.h"

static void job_enqueue(job *j, uint32_t t) {
    if (j->done[t] || j->holders[t] || j->queued[t] || j->finished || audit_is_pending(j, t)) return;
    j->queue[(j->q_head + j->q_len) % j->tile_count] = t;
    j->q_len++;
    j->queued[t] = 1;
}

static int job_dequeue(job *j, uint32_t *t) {
    while (j->q_len > 0) {
        uint32_t x = j->queue[j->q_head];
        j->q_head = (j->q_head + 1) % j->tile_count;
        j->q_len--;
        j->queued[x] = 0;
        if (!j->done[x] && !j->holders[x]) {
            *t = x;
            return 1;
        }
    }
    return 0;
}

void farm_requeue_tile(job *j, uint32_t t) { job_enqueue(j, t); }

/* A lease stops counting as a holder; the tile is queued if nobody else
 * holds it. */
void farm_lease_release(lease *l) {
    if (!l->live) return;
    l->live = 0;
    job *j = l->job;
    if (j->holders[l->tile] > 0) j->holders[l->tile]--;
    if (!j->done[l->tile] && j->holders[l->tile] == 0) {
        job_enqueue(j, l->tile);
        j->rep.requeued++;
        if (!j->finished) farm_emit(j->owner, FARM_EV_REQUEUE, j, l->tile, NULL, 0, 0, 0);
    }
}

job *farm_find_job(const farm *f, uint32_t id) {
    job *j;
    TAILQ_FOREACH(j, &f->jobs, link)
        if (j->desc.id == id) return j;
    return NULL;
}

void farm_job_free(job *j) {
    audit_free(j);
    free(j->blocks);
    conn_blob_unref(j->scene);
    free(j->rects);
    free(j->done);
    free(j->holders);
    free(j->queued);
    free(j->failures);
    free(j->first_start);
    free(j->queue);
    free(j);
}

void farm_report_fill(const farm *f, const job *j, farm_report *r) {
    *r = j->rep;
    r->tiles_total = j->tile_count;
    r->workers = 0;
    r->bytes_in = f->closed_bytes_in;
    r->bytes_out = f->closed_bytes_out;
    peer *p;
    LIST_FOREACH(p, &f->peers, link) {
        if (p->state == PEER_ACTIVE) r->workers++;
        r->bytes_in += conn_bytes_in(p->c);
        r->bytes_out += conn_bytes_out(p->c);
    }
}

/* The job is complete or has failed: tell its workers and the caller. */
void farm_job_finish(farm *f, job *j) {
    j->finished = 1;
    peer *p;
    LIST_FOREACH(p, &f->peers, link)
        for (int i = 0; i < p->job_count; i++)
            if (p->jobs[i] == j->desc.id && !conn_is_closing(p->c)) peer_send_ids(p, "job_end", j->desc.id, -1);
    farm_report r;
    farm_report_fill(f, j, &r);
    if (j->cb) j->cb(j->ctx, &r, 1);
}

void farm_job_fail(farm *f, job *j, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(j->rep.error, sizeof j->rep.error, fmt, ap);
    va_end(ap);
    j->rep.failed = 1;
    farm_log(f, "job %u failed: %s", j->desc.id, j->rep.error);
    farm_job_finish(f, j);
}

/* Whether a job that has not finished renders the scene of this hash. */
static int scene_in_use(const farm *f, const char *hash) {
    const job *j;
    TAILQ_FOREACH(j, &f->jobs, link)
        if (!j->finished && strcmp(j->desc.scene_hash, hash) == 0) return 1;
    return 0;
}

/* Before p is sent another bundle: if it holds FARM_PEER_SCENES or more,
 * tell it to forget the one used longest ago that no unfinished job needs
 * (none: it keeps them all). Both sides then agree on what it holds, as
 * the messages arrive in order; the worker's copy of a job's bundle is
 * taken when the job arrives, so forgetting the bytes later is safe. */
static void peer_make_room(peer *p) {
    if (p->scene_count < FARM_PEER_SCENES) return;
    int oldest = -1;
    for (int i = 0; i < p->scene_count; i++)
        if ((oldest < 0 || p->scenes[i].used < p->scenes[oldest].used) && !scene_in_use(p->f, p->scenes[i].hash))
            oldest = i;
    if (oldest < 0) return;
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", "forget_scene");
    cJSON_AddStringToObject(m, "scene", p->scenes[oldest].hash);
    peer_send_json(p, m);
    p->scenes[oldest] = p->scenes[--p->scene_count];
}

/* Make sure p has the job's scene and description. */
static void peer_tell_job(peer *p, job *j) {
    for (int i = 0; i < p->job_count; i++)
        if (p->jobs[i] == j->desc.id) return;
    int have = -1;
    for (int i = 0; i < p->scene_count && have < 0; i++)
        if (strcmp(p->scenes[i].hash, j->desc.scene_hash) == 0) have = i;
    if (have < 0) {
        peer_make_room(p);
        void *s = realloc(p->scenes, (size_t)(p->scene_count + 1) * sizeof *p->scenes);
        if (s) {
            p->scenes = s;
            have = p->scene_count++;
            memcpy(p->scenes[have].hash, j->desc.scene_hash, SCENE_BUNDLE_HASH_HEX);
        }
        conn_send_blob(p->c, j->scene);
    }
    if (have >= 0) p->scenes[have].used = ++p->f->scene_uses;
    uint32_t *js = realloc(p->jobs, (size_t)(p->job_count + 1) * sizeof *p->jobs);
    if (js) {
        p->jobs = js;
        p->jobs[p->job_count++] = j->desc.id;
    }
    peer_send_json(p, proto_job_json(&j->desc));
}

int peer_told_job(const peer *p, uint32_t id) {
    for (int i = 0; i < p->job_count; i++)
        if (p->jobs[i] == id) return 1;
    return id <= p->forgotten_max;
}

/* The farm forgets job id: so do its peers' lists (which would otherwise
 * grow by one id per job for as long as a worker stays connected, and be
 * searched on every tile), each keeping only the highest such id. */
static void peers_forget_job(farm *f, uint32_t id) {
    peer *p;
    LIST_FOREACH(p, &f->peers, link)
        for (int i = 0; i < p->job_count; i++)
            if (p->jobs[i] == id) {
                p->jobs[i] = p->jobs[--p->job_count];
                if (id > p->forgotten_max) p->forgotten_max = id;
                break;
            }
}

lease *peer_find_lease(peer *p, uint32_t job_id, uint32_t tile) {
    lease *l;
    LIST_FOREACH(l, &p->leases, link)
        if (l->job->desc.id == job_id && l->tile == tile) return l;
    return NULL;
}

double job_backup_age(const job *j) {
    double age = BACKUP_AGE_FACTOR * j->tile_seconds / j->rep.tiles_done;
    return age < BACKUP_MIN_AGE_S ? BACKUP_MIN_AGE_S : age;
}

/* A tile worth backing up for p: not done, held once, not by p, running
 * longer than job_backup_age. Oldest first. */
static int job_pick_backup(const farm *f, job *j, peer *p, uint32_t *out) {
    if (j->rep.tiles_done == 0) return 0;
    double now = farm_now(f), best_age = job_backup_age(j);
    int found = 0;
    for (int t = 0; t < j->tile_count; t++) {
        if (j->done[t] || j->holders[t] != 1 || now - j->first_start[t] <= best_age) continue;
        if (peer_find_lease(p, j->desc.id, (uint32_t)t) || !audit_may_take(j, p->rec.serial, (uint32_t)t)) continue;
        best_age = now - j->first_start[t];
        *out = (uint32_t)t;
        found = 1;
    }
    return found;
}

/* The part of the job's mask under tile t, row-major (the caller frees), or
 * NULL when out of memory. */
static uint8_t *job_tile_mask(const job *j, uint32_t t) {
    const tile_rect *r = &j->rects[t];
    uint8_t *m = malloc((size_t)tile_width(r) * (size_t)tile_height(r)), *out = m;
    for (int y = r->y0; m && y < r->y1; y++, out += tile_width(r))
        memcpy(out, j->mask + (size_t)y * (size_t)j->desc.width + (size_t)r->x0, (size_t)tile_width(r));
    return m;
}

static int peer_assign(peer *p, job *j, uint32_t t, int backup) {
    proto_assign a = {j->desc.id, t, j->rects[t], j->first, j->count, NULL};
    lease *l = calloc(1, sizeof *l);
    if (!l || (j->mask && !(a.mask = job_tile_mask(j, t)))) {
        farm_log(p->f, "out of memory assigning tile %u of job %u; it stays queued", t, j->desc.id);
        free(l);
        job_enqueue(j, t);
        return -1;
    }
    double now = farm_now(p->f);
    *l = (lease){.job = j, .tile = t, .start = now, .live = 1};
    LIST_INSERT_HEAD(&p->leases, l, link);
    if (j->holders[t]++ == 0) j->first_start[t] = now;
    if (backup) j->rep.backups++;
    if (j->on_first_assign) {
        void (*first)(void *) = j->on_first_assign;
        j->on_first_assign = NULL;
        first(j->ctx);
    }
    p->credits--;
    peer_tell_job(p, j);
    peer_send_json(p, proto_assign_json(&a));
    free(a.mask);
    farm_emit(p->f, FARM_EV_ASSIGN, j, t, p->rec.name, 0, 0, backup);
    return 0;
}

/* Use p's credits on queued tiles, then on backups. */
void peer_schedule(peer *p) {
    farm *f = p->f;
    if (p->state != PEER_ACTIVE || conn_is_closing(p->c)) return;
    job *j;
    TAILQ_FOREACH(j, &f->jobs, link) {
        if (p->credits <= 0) break;
        if (j->finished || audit_is_barred(j, p->rec.serial) || block_is_blocked(f, j, p)) continue;
        uint32_t t;
        while (!j->finished && p->credits > 0 && audit_pick(j, p, &t)) /* audit copies first */
            if (peer_assign(p, j, t, 0)) return;
        while (!j->finished && p->credits > 0 && job_dequeue(j, &t))
            if (peer_assign(p, j, t, 0)) return;
        while (!j->finished && p->credits > 0 && j->q_len == 0 && job_pick_backup(f, j, p, &t))
            if (peer_assign(p, j, t, 1)) return;
    }
}

void farm_schedule_all(farm *f) {
    peer *p;
    LIST_FOREACH(p, &f->peers, link)
        if (p->credits > 0) peer_schedule(p);
}

/* Link j into f->jobs by priority (higher first), then submission order. */
static void job_link_ordered(farm *f, job *j) {
    job *after = NULL, *k;
    TAILQ_FOREACH(k, &f->jobs, link) {
        if (k->priority < j->priority || (k->priority == j->priority && k->seq > j->seq)) break;
        after = k;
    }
    if (after) TAILQ_INSERT_AFTER(&f->jobs, after, j, link);
    else TAILQ_INSERT_HEAD(&f->jobs, j, link);
}

int farm_submit(farm *f, const proto_job *desc, const uint8_t *bundle, size_t bundle_len,
                const farm_job_options *o, float *rgb, farm_job_cb cb, void *ctx) {
    job *j = calloc(1, sizeof *j);
    if (j) j->owner = f;
    if (!j) return -1;
    j->desc = *desc;
    j->tile_size = o->tile_size;
    j->priority = o->priority;
    j->on_tile = o->on_tile;
    j->on_first_assign = o->on_first_assign;
    j->film = (film){rgb, desc->width, desc->height, desc->adaptive ? ADAPTIVE_CHANNELS : 3};
    j->mask = desc->adaptive ? o->mask : NULL;
    j->first = desc->adaptive ? o->first : 0;
    j->count = desc->adaptive ? o->count : (uint32_t)desc->spp;
    j->cb = cb;
    j->ctx = ctx;
    j->tile_count = render_split_tiles(desc->width, desc->height, o->tile_size, NULL, 0);
    size_t n = (size_t)j->tile_count;
    j->rects = calloc(n, sizeof *j->rects);
    j->done = calloc(n, 1);
    j->holders = calloc(n, 1);
    j->queued = calloc(n, 1);
    j->failures = calloc(n, 1);
    j->first_start = calloc(n, sizeof *j->first_start);
    j->queue = calloc(n, sizeof *j->queue);
    if (o->scene) o->scene->refs++; /* shared, not copied */
    j->scene = o->scene ? o->scene : conn_blob_frame(WIRE_KIND_SCENE, bundle, bundle_len);
    if (!j->rects || !j->done || !j->holders || !j->queued || !j->failures || !j->first_start || !j->queue ||
        !j->scene || audit_new(j, f->opt.audit)) {
        farm_job_free(j);
        return -1;
    }
    render_split_tiles(desc->width, desc->height, o->tile_size, j->rects, j->tile_count);
    for (int t = 0; t < j->tile_count; t++) {
        if (o->done && o->done[t]) {
            j->done[t] = 1;
            j->rep.tiles_done++;
        }
        job_enqueue(j, (uint32_t)t);
    }
    j->reported = j->rep.tiles_done;
    j->seq = ++f->next_job_seq;
    job_link_ordered(f, j);
    if (j->rep.tiles_done == j->tile_count)
        farm_job_finish(f, j);
    else
        farm_schedule_all(f);
    return 0;
}

int farm_cancel(farm *f, uint32_t id) {
    job *j = farm_find_job(f, id);
    if (!j || j->finished) return -1;
    j->rep.cancelled = 1;
    snprintf(j->rep.error, sizeof j->rep.error, "cancelled");
    farm_job_finish(f, j);
    farm_schedule_all(f); /* the freed workers take other jobs */
    return 0;
}

int farm_set_priority(farm *f, uint32_t id, int priority) {
    job *j = farm_find_job(f, id);
    if (!j || j->finished) return -1;
    TAILQ_REMOVE(&f->jobs, j, link);
    j->priority = priority;
    job_link_ordered(f, j);
    farm_schedule_all(f); /* idle slots may now take the job's tiles */
    return 0;
}

int farm_forget(farm *f, uint32_t id) {
    job *j = farm_find_job(f, id);
    if (!j || !j->finished) return -1;
    peer *p;
    LIST_FOREACH(p, &f->peers, link) { /* leases of it die with it */
        lease *l, *next;
        LIST_FOREACH_SAFE(l, &p->leases, link, next)
            if (l->job == j) {
                LIST_REMOVE(l, link);
                free(l);
            }
    }
    peers_forget_job(f, id);
    TAILQ_REMOVE(&f->jobs, j, link);
    farm_job_free(j);
    return 0;
}

int farm_job_report(const farm *f, uint32_t id, farm_report *r) {
    const job *j = farm_find_job(f, id);
    if (!j) return -1;
    farm_report_fill(f, j, r);
    return 0;
}
