/* farm_block.c - the per-job blocklist (after Flamenco's): a worker that
 * fails, crashes or times out MAX_PEER_FAILURES times on a job gets none of
 * that job's tiles for farm_options.blocklist_s seconds (doubled at each
 * new blocklisting of the same worker, up to 16 times), then may try again
 * on probation: one more failure blocklists it again. Other jobs still use
 * it. What counts, once per event and job:
 *   - a "failed" answer for one of the job's tiles;
 *   - leaving while holding live tiles of the job without saying bye (a
 *     crash, a kill, a protocol violation);
 *   - falling silent (stalled) while holding them;
 *   - holding a tile past its lease.
 * A worker is known by "name@host", so one that crashes and comes back
 * under a new connection is still the same worker; two workers sharing a
 * name on one host share their entries (give them distinct --name).
 * State: job.blocks (farm_internal.h), on the loop thread. */
#include "connlimit.h"
#include "farm_internal.h"

#define BLOCK_MAX_DOUBLINGS 4 /* the wait grows to at most 16 times blocklist_s */

/* "name@host" for p: its name and its address without the port. */
static void block_key(const peer *p, char *out, size_t len) {
    char host[sizeof p->rec.addr];
    connlimit_ip_of(p->rec.addr, host, sizeof host);
    snprintf(out, len, "%s@%s", p->rec.name, host);
}

static block_entry *block_find(const job *j, const peer *p) {
    char key[sizeof j->blocks->key];
    block_key(p, key, sizeof key);
    for (int i = 0; i < j->block_count; i++)
        if (strcmp(j->blocks[i].key, key) == 0) return &j->blocks[i];
    return NULL;
}

/* p's entry in j, made (with no failures) if it has none; NULL when out of
 * memory. */
static block_entry *block_get(job *j, const peer *p) {
    block_entry *e = block_find(j, p);
    if (e) return e;
    block_entry *b = realloc(j->blocks, (size_t)(j->block_count + 1) * sizeof *b);
    if (!b) return NULL;
    j->blocks = b;
    e = &b[j->block_count++];
    memset(e, 0, sizeof *e);
    block_key(p, e->key, sizeof e->key);
    return e;
}

int block_is_blocked(const farm *f, job *j, const peer *p) {
    block_entry *e = j->block_count ? block_find(j, p) : NULL;
    if (!e || e->until == 0) return 0;
    if (farm_now(f) < e->until) return 1;
    if (!e->announced) {
        e->announced = 1;
        farm_log(f, "job %u: %s may try again (blocklisted for this job until now; one more failure blocklists it "
                 "again)", j->desc.id, p->label);
    }
    return 0;
}

double block_remaining(const farm *f, const job *j, const peer *p) {
    const block_entry *e = j->block_count ? block_find(j, p) : NULL;
    double left = e ? e->until - farm_now(f) : 0;
    return left > 0 ? left : 0;
}

void block_note_failure(farm *f, job *j, peer *p, const char *fmt, ...) {
    if (j->finished || f->closing) return;
    char what[320];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(what, sizeof what, fmt, ap);
    va_end(ap);
    block_entry *e = block_get(j, p);
    if (!e) {
        farm_log(f, "job %u: out of memory counting a failure of %s (%s)", j->desc.id, p->label, what);
        return;
    }
    if (farm_now(f) < e->until) return; /* already blocklisted: a straggler's failure */
    if (++e->failures < MAX_PEER_FAILURES) return;
    int doublings = e->strikes < BLOCK_MAX_DOUBLINGS ? e->strikes : BLOCK_MAX_DOUBLINGS;
    double wait = f->opt.blocklist_s * (double)(1 << doublings);
    e->strikes++;
    e->until = farm_now(f) + wait;
    e->failures = MAX_PEER_FAILURES - 1; /* on probation once the wait is over */
    e->announced = 0;
    j->rep.blocklisted++;
    f->blocklisted++;
    char count[48];
    if (e->strikes == 1) snprintf(count, sizeof count, "%d failures", MAX_PEER_FAILURES);
    else snprintf(count, sizeof count, "failed again after its wait");
    farm_log(f, "job %u: %s is blocklisted for this job for %.0f s (%s; last: %s)", j->desc.id, p->label, wait, count,
             what);
}

void block_note_lost_leases(farm *f, peer *p, const char *why) {
    lease *l, *k;
    LIST_FOREACH(l, &p->leases, link) {
        if (!l->live) continue;
        int first = 1; /* one failure per job, named by its first live tile */
        for (k = LIST_FIRST(&p->leases); k != l && first; k = LIST_NEXT(k, link)) first = !(k->live && k->job == l->job);
        if (first) block_note_failure(f, l->job, p, "%s holding tile %u", why, l->tile);
    }
}

void block_list_peer(const farm *f, const peer *p, int *jobs, double *retry_s) {
    *jobs = 0;
    *retry_s = 0;
    job *j;
    TAILQ_FOREACH(j, &f->jobs, link) {
        double left = j->finished ? 0 : block_remaining(f, j, p);
        if (left <= 0) continue;
        (*jobs)++;
        if (*retry_s == 0 || left < *retry_s) *retry_s = left;
    }
}
