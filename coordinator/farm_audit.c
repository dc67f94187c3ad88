/* farm_audit.c - audited tiles (farm_options.audit, `--audit FRACTION`).
 *
 * Tessera renders bit-deterministically, so two honest workers return the
 * same bytes for a tile. For each job a secret seed (libsodium's
 * randombytes, never sent to anyone) picks a fraction of the tiles; such a
 * tile counts as done only once two different workers have returned the
 * same bytes for it. The first result is kept here until a copy from
 * another worker arrives; on a mismatch a third worker (neither of the
 * first two) decides. Every worker whose result differs from the accepted
 * bytes is quarantined for the job: it gets no more of the job's tiles, its
 * copies in flight are cancelled, and the tiles it alone delivered are put
 * back in the queue to be rendered again by someone else (and compared with
 * what it had sent, for the log). A worker cannot tell an audited tile from
 * any other: assignments look the same, and the choice is a hash of a seed
 * it never sees.
 *
 * State per job (job_audit), all on the loop thread:
 *   chosen[t]  - the tile needs two matching results;
 *   pending[t] - results so far for a chosen tile not yet accepted;
 *   by[t]      - for a done tile, the serial of the one worker whose result
 *                was taken unchecked (0: checked, resumed, or nobody);
 *   recheck[t] - a quarantined worker's pixels for a tile it alone had
 *                delivered, until the tile is rendered again.
 * A pending tile is never in the job's queue: audit_pick hands it to a
 * worker that has not rendered it yet (job_enqueue leaves it out).
 *
 * Nobody to compare with (audit_settle, on every tick): when no connected
 * worker in good standing may render a pending tile again (a farm of one
 * worker, the others gone, stalled, quarantined or blocklisted), its single
 * result is accepted unchecked (logged for the first such tile of a job,
 * counted in the workers table) once it has waited the worker timeout
 * (opt.timeout_s: time for the other workers of a farm that is starting to
 * join), or at once when nothing else of the job is left. So a one-worker
 * farm counts and journals its tiles a few seconds late, not at the end.
 * The same when the audit copy is running far longer than the job's tiles
 * do and no third worker could back it up (a stuck verifier would
 * otherwise hold the tile until its lease ends): the held result is
 * accepted and the copy cancelled. A verifier can thus only get the other
 * worker's result accepted unchecked, never its own.
 * Two results that disagree with no third worker to decide fail the job
 * once nothing else of it is left, with a message saying so. Waiting for a
 * worker that may never come would hang the render. */
#include <sodium.h>

#include "farm_internal.h"

#define AUDIT_MAX_VOTERS 4   /* this many results in good standing, no two agreeing, fail the job */

#define AUDIT_MAX_RESULTS 8  /* kept per tile, counting quarantined workers' */

typedef struct {
    uint32_t serial; /* the worker's peer_record.serial */
    char who[200];   /* its label at the time */
    char name[64];   /* its name, for the event if the tile is settled unchecked */
    float *px;
    trace_stats stats; /* as it reported them */
    double took;       /* seconds from assignment to result */
    double arrived;    /* farm_now() when it came in */
} audit_result;

typedef struct {
    int count;
    audit_result r[AUDIT_MAX_RESULTS];
} audit_tile;

struct job_audit {
    uint64_t seed;
    uint8_t *chosen;
    audit_tile **pending;
    uint32_t *by;
    float **recheck;
    char (*recheck_who)[200];
    uint32_t *barred;
    int barred_count;
    int unchecked; /* results accepted with nobody to compare them with */
};

static uint64_t splitmix64(uint64_t x) {
    x += 0x9e3779b97f4a7c15ULL;
    x = (x ^ (x >> 30)) * 0xbf58476d1ce4e5b9ULL;
    x = (x ^ (x >> 27)) * 0x94d049bb133111ebULL;
    return x ^ (x >> 31);
}

int audit_new(job *j, double fraction) {
    if (!(fraction > 0)) return 0;
    job_audit *a = calloc(1, sizeof *a);
    size_t n = (size_t)j->tile_count;
    if (!a) return -1;
    j->audit = a;
    a->chosen = calloc(n, 1);
    a->pending = calloc(n, sizeof *a->pending);
    a->by = calloc(n, sizeof *a->by);
    a->recheck = calloc(n, sizeof *a->recheck);
    a->recheck_who = calloc(n, sizeof *a->recheck_who);
    if (!a->chosen || !a->pending || !a->by || !a->recheck || !a->recheck_who) return -1;
    randombytes_buf(&a->seed, sizeof a->seed);
    for (size_t t = 0; t < n; t++) {
        double u = (double)(splitmix64(a->seed ^ splitmix64(t)) >> 11) * 0x1p-53;
        a->chosen[t] = fraction >= 1.0 || u < fraction;
    }
    return 0;
}

static void tile_free(audit_tile *at) {
    if (!at) return;
    for (int i = 0; i < at->count; i++) free(at->r[i].px);
    free(at);
}

void audit_free(job *j) {
    job_audit *a = j->audit;
    if (!a) return;
    for (int t = 0; t < j->tile_count; t++) {
        if (a->pending) tile_free(a->pending[t]);
        if (a->recheck) free(a->recheck[t]);
    }
    free(a->pending);
    free(a->recheck);
    free(a->chosen);
    free(a->by);
    free(a->recheck_who);
    free(a->barred);
    free(a);
    j->audit = NULL;
}

int audit_is_barred(const job *j, uint32_t serial) {
    const job_audit *a = j->audit;
    for (int i = 0; a && i < a->barred_count; i++)
        if (a->barred[i] == serial) return 1;
    return 0;
}

int audit_is_pending(const job *j, uint32_t t) { return j->audit && j->audit->pending[t] != NULL; }

/* Whether the worker with this serial may render tile t of the job: not
 * barred, and (for a pending tile) not one whose result is already in. */
int audit_may_take(const job *j, uint32_t serial, uint32_t t) {
    const job_audit *a = j->audit;
    if (!a) return 1;
    if (audit_is_barred(j, serial)) return 0;
    const audit_tile *at = a->pending[t];
    for (int i = 0; at && i < at->count; i++)
        if (at->r[i].serial == serial) return 0;
    return 1;
}

int audit_pick(const job *j, const peer *p, uint32_t *out) {
    const job_audit *a = j->audit;
    if (!a || audit_is_barred(j, p->rec.serial)) return 0;
    for (int t = 0; t < j->tile_count; t++)
        if (a->pending[t] && !j->done[t] && j->holders[t] == 0 && audit_may_take(j, p->rec.serial, (uint32_t)t)) {
            *out = (uint32_t)t;
            return 1;
        }
    return 0;
}

void audit_accepted(job *j, uint32_t t, uint32_t serial, int verified) {
    if (j->audit) j->audit->by[t] = verified ? 0 : serial;
}

/* The index of the first of n floats whose bytes differ, or -1. */
static long first_difference(const float *x, const float *y, size_t n) {
    for (size_t i = 0; i < n; i++)
        if (memcmp(&x[i], &y[i], sizeof *x) != 0) return (long)i;
    return -1;
}

/* "float I (pixel X,Y channel C of the frame): A vs B" into buf. */
static void describe_difference(const job *j, uint32_t t, const float *x, const float *y, size_t n, char *buf,
                                size_t len) {
    long i = first_difference(x, y, n);
    if (i < 0) {
        snprintf(buf, len, "identical");
        return;
    }
    const tile_rect *r = &j->rects[t];
    int ch = j->film.channels, w = tile_width(r);
    long px = i / ch;
    snprintf(buf, len, "first differing float %ld (pixel %ld,%ld channel %ld): %.9g vs %.9g", i, r->x0 + px % w,
             r->y0 + px / w, i % ch, (double)x[i], (double)y[i]);
}

static size_t tile_floats(const job *j, uint32_t t) {
    return (size_t)tile_width(&j->rects[t]) * (size_t)tile_height(&j->rects[t]) * (size_t)j->film.channels;
}

/* A copy of tile t's values as they stand in the film (the caller frees),
 * or NULL when out of memory. */
static float *film_copy_tile(const job *j, uint32_t t) {
    const tile_rect *r = &j->rects[t];
    int ch = j->film.channels, w = tile_width(r);
    float *px = malloc(tile_floats(j, t) * sizeof *px), *o = px;
    for (int y = r->y0; px && y < r->y1; y++, o += (size_t)w * ch)
        memcpy(o, j->film.px + ((size_t)y * j->film.width + r->x0) * ch, (size_t)w * ch * sizeof *px);
    return px;
}

static peer *farm_find_serial(farm *f, uint32_t serial) {
    peer *p;
    LIST_FOREACH(p, &f->peers, link)
        if (p->rec.serial == serial) return p;
    return NULL;
}

/* Quarantine worker `serial` for job j: no more of its tiles, its copies
 * in flight cancelled, the tiles it alone delivered queued again. */
static void audit_quarantine(farm *f, job *j, uint32_t serial, const char *who) {
    job_audit *a = j->audit;
    if (audit_is_barred(j, serial)) return;
    uint32_t *b = realloc(a->barred, (size_t)(a->barred_count + 1) * sizeof *b);
    if (!b) {
        farm_job_fail(f, j, "out of memory quarantining %s", who);
        return;
    }
    a->barred = b;
    a->barred[a->barred_count++] = serial;
    j->rep.quarantined++;
    f->quarantined++;
    peer *p = farm_find_serial(f, serial);
    if (p) {
        p->rec.quarantined++;
        lease *l;
        LIST_FOREACH(l, &p->leases, link)
            if (l->job == j && l->live) {
                farm_lease_release(l); /* stays listed: its late answer is recognised */
                peer_send_ids(p, "cancel", j->desc.id, l->tile);
            }
    }
    for (int i = 0; !p && i < f->departed_count; i++) /* it left: the table shows it anyway */
        if (f->departed[i].serial == serial) f->departed[i].quarantined++;
    int redo = 0;
    for (int t = 0; t < j->tile_count; t++) {
        if (!j->done[t] || a->by[t] != serial) continue;
        free(a->recheck[t]);
        a->recheck[t] = film_copy_tile(j, (uint32_t)t);
        snprintf(a->recheck_who[t], sizeof a->recheck_who[t], "%s", who);
        a->by[t] = 0;
        j->done[t] = 0;
        j->rep.tiles_done--;
        redo++;
        farm_requeue_tile(j, (uint32_t)t); /* unless held or still in the ring */
    }
    farm_log(f, "job %u: %s is quarantined for this job; %d tiles it alone delivered will be rendered again",
             j->desc.id, who, redo);
}

/* A result for tile t of job j from p, after the farm's checks (px: its
 * decoded values; the caller keeps ownership unless told; stats and took:
 * what p reported and how long it took, kept with a held result). Returns:
 *   AUDIT_ACCEPT - stitch *px (possibly swapped for the agreed bytes; the
 *                  old buffer freed) and count the tile; *verified says
 *                  whether two workers agreed on it;
 *   AUDIT_HOLD   - kept for comparison (*px taken: set to NULL);
 *   AUDIT_DROP   - ignore it (a quarantined worker's, or a repeat);
 *   AUDIT_FAILED - the job failed (no two of AUDIT_MAX_RESULTS agreed). */
int audit_on_result(farm *f, job *j, peer *p, uint32_t t, float **px, const trace_stats *stats, double took,
                    int *verified) {
    job_audit *a = j->audit;
    *verified = 0;
    if (!a) return AUDIT_ACCEPT;
    if (audit_is_barred(j, p->rec.serial)) return AUDIT_DROP;
    size_t n = tile_floats(j, t);
    if (a->recheck[t]) {
        char diff[200];
        describe_difference(j, t, a->recheck[t], *px, n, diff, sizeof diff);
        farm_log(f, "job %u tile %u rendered again by %s: %s %s", j->desc.id, t, p->label,
                 strcmp(diff, "identical") == 0 ? "the same as from" : "differs from what was sent by",
                 a->recheck_who[t]);
        if (strcmp(diff, "identical") != 0) farm_log(f, "job %u tile %u: %s", j->desc.id, t, diff);
        free(a->recheck[t]);
        a->recheck[t] = NULL;
    }
    if (!a->chosen[t]) return AUDIT_ACCEPT;
    audit_tile *at = a->pending[t];
    if (!at && !(at = a->pending[t] = calloc(1, sizeof *at))) {
        farm_job_fail(f, j, "out of memory auditing tile %u", t);
        return AUDIT_FAILED;
    }
    for (int i = 0; i < at->count; i++)
        if (at->r[i].serial == p->rec.serial) return AUDIT_DROP;
    if (at->count == AUDIT_MAX_RESULTS) return AUDIT_DROP;
    audit_result *r = &at->r[at->count++];
    r->serial = p->rec.serial;
    snprintf(r->who, sizeof r->who, "%s", p->label);
    snprintf(r->name, sizeof r->name, "%s", p->rec.name);
    r->stats = *stats;
    r->took = took;
    r->arrived = farm_now(f);
    r->px = *px;
    *px = NULL;
    /* Two results from workers in good standing that agree decide. */
    int agree = -1, live = 0;
    for (int i = 0; i < at->count && agree < 0; i++) {
        if (audit_is_barred(j, at->r[i].serial)) continue;
        live++;
        for (int k = i + 1; k < at->count && agree < 0; k++)
            if (!audit_is_barred(j, at->r[k].serial) && memcmp(at->r[i].px, at->r[k].px, n * sizeof(float)) == 0)
                agree = i;
    }
    if (agree < 0) {
        live = 0;
        for (int i = 0; i < at->count; i++) live += !audit_is_barred(j, at->r[i].serial);
        if (live >= 2) {
            char diff[200];
            describe_difference(j, t, at->r[0].px, r->px, n, diff, sizeof diff);
            j->rep.audit_mismatches++;
            f->audit_mismatches++;
            farm_log(f, "job %u tile %u: %s and %s disagree (%s); another worker decides", j->desc.id, t,
                     at->r[0].who, r->who, diff);
        }
        if (live >= AUDIT_MAX_VOTERS || at->count == AUDIT_MAX_RESULTS) {
            farm_job_fail(f, j, "tile %u: no two of %d workers returned the same pixels", t, live);
            return AUDIT_FAILED;
        }
        return AUDIT_HOLD;
    }
    /* Accept the agreed bytes; quarantine every other worker that voted. */
    a->pending[t] = NULL;
    const audit_result *good = &at->r[agree];
    for (int i = 0; i < at->count; i++) {
        const audit_result *o = &at->r[i];
        if (o == good || audit_is_barred(j, o->serial) || memcmp(o->px, good->px, n * sizeof(float)) == 0) continue;
        char diff[200];
        describe_difference(j, t, good->px, o->px, n, diff, sizeof diff);
        farm_log(f, "audit: job %u tile %u: %s returned different pixels from %s and at least one other worker (%s)",
                 j->desc.id, t, o->who, good->who, diff);
        audit_quarantine(f, j, o->serial, o->who);
    }
    *px = good->px;
    at->r[agree].px = NULL;
    tile_free(at);
    j->rep.audited++;
    f->audited++;
    *verified = 1;
    return j->finished ? AUDIT_FAILED : AUDIT_ACCEPT;
}

/* Whether a connected worker in good standing could render tile t again. */
static int audit_someone_may_take(const farm *f, job *j, uint32_t t) {
    const peer *p;
    LIST_FOREACH(p, &f->peers, link)
        if (p->state == PEER_ACTIVE && !conn_is_closing(p->c) && !block_is_blocked(f, j, p) &&
            audit_may_take(j, p->rec.serial, t))
            return 1;
    return 0;
}

/* Pending tile t's audit copy is running far longer than the job's tiles
 * do (longer than job_backup_age, the backup criterion), and no connected
 * worker in good standing that does not hold it may render it: a stuck or
 * very slow verifier in a farm with no third worker to back it up. */
static int audit_copy_stalled(const farm *f, job *j, uint32_t t) {
    if (!j->holders[t] || j->rep.tiles_done == 0) return 0;
    if (farm_now(f) - j->first_start[t] <= job_backup_age(j)) return 0;
    peer *p;
    LIST_FOREACH(p, &f->peers, link) {
        lease *l = peer_find_lease(p, j->desc.id, t);
        if (p->state == PEER_ACTIVE && !conn_is_closing(p->c) && !(l && l->live) && !block_is_blocked(f, j, p) &&
            audit_may_take(j, p->rec.serial, t))
            return 0;
    }
    return 1;
}

/* The results of pending tile t from workers not quarantined: how many,
 * and the first two (NULL when fewer). */
static int audit_live_results(const job *j, const audit_tile *at, const audit_result **r0, const audit_result **r1) {
    int live = 0;
    *r0 = *r1 = NULL;
    for (int i = 0; i < at->count; i++) {
        if (audit_is_barred(j, at->r[i].serial)) continue;
        if (live == 0) *r0 = &at->r[i];
        else if (live == 1) *r1 = &at->r[i];
        live++;
    }
    return live;
}

/* Whether everything of j but its pending tiles is done, and none of those
 * is running or could be rendered again by a connected worker. */
static int audit_stuck(const farm *f, job *j) {
    if (j->q_len > 0) return 0;
    for (int t = 0; t < j->tile_count; t++)
        if (!j->done[t] && (!j->audit->pending[t] || j->holders[t] || audit_someone_may_take(f, j, (uint32_t)t)))
            return 0;
    return 1;
}

/* Accept the one result of pending tile t unchecked (see the top of this
 * file). Returns 0, or -1 when the job ended (and may have been freed). */
static int audit_take_unchecked(farm *f, job *j, uint32_t t, const audit_result *r) {
    job_audit *a = j->audit;
    audit_tile *at = a->pending[t];
    uint32_t id = j->desc.id;
    if (!a->unchecked++)
        farm_log(f, "job %u: no other worker is connected to render audited tile %u again (the audit needs two "
                 "workers or more); accepted unchecked, as are any more such tiles of this job", id, t);
    f->audit_unchecked++;
    a->pending[t] = NULL;
    farm_tile_land(f, j, farm_find_serial(f, r->serial), r->name, r->serial, t, r->px, r->took, &r->stats, 0);
    tile_free(at);
    j = farm_find_job(f, id); /* landing the last tile may end the job, and its owner forget it */
    return j && !j->finished ? 0 : -1;
}

void audit_settle(farm *f, job *j) {
    if (!j->audit || j->finished) return;
    int stuck = -1; /* not yet known */
    for (int t = 0; t < j->tile_count; t++) {
        audit_tile *at = j->audit->pending[t];
        const audit_result *r0, *r1;
        if (!at || j->done[t]) continue;
        if (j->holders[t] ? !audit_copy_stalled(f, j, (uint32_t)t) : audit_someone_may_take(f, j, (uint32_t)t))
            continue;
        int live = audit_live_results(j, at, &r0, &r1);
        if (live == 0) continue; /* only quarantined workers' results: someone must render it */
        if (stuck < 0) stuck = audit_stuck(f, j);
        if (live == 1 && (stuck || farm_now(f) - r0->arrived >= f->opt.timeout_s)) {
            if (audit_take_unchecked(f, j, (uint32_t)t, r0)) return;
        } else if (live >= 2 && stuck) {
            farm_job_fail(f, j, "tile %d: %s and %s returned different pixels and no third worker is connected to "
                          "decide (the audit needs three workers to settle a mismatch)", t, r0->who, r1->who);
            return;
        }
    }
}
