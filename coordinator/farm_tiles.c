/* farm_tiles.c - a worker's tile result: checked against its lease and the
 * job, stitched into the job's film, and the other copies cancelled. */
#include "farm_internal.h"

/* Decode a checked tile's pixels into a new buffer (the caller frees) and
 * find the first value no radiance can be (bad: its index, or -1). NULL
 * when out of memory. */
static float *tile_decode(const uint8_t *body, const proto_tile *h, long *bad) {
    size_t n = (size_t)h->width * h->height * h->channels;
    float *px = malloc(n * sizeof *px);
    if (!px) return NULL;
    proto_tile_pixels(body, h, px);
    *bad = film_first_bad(px, n);
    return px;
}

/* Another copy of tile t won: tell the other holders to stop. */
static void job_cancel_copies(farm *f, job *j, uint32_t t, peer *winner) {
    peer *p;
    LIST_FOREACH(p, &f->peers, link) {
        if (p == winner) continue;
        lease *l = peer_find_lease(p, j->desc.id, t);
        if (!l || !l->live) continue;
        l->live = 0;
        j->holders[t]--;
        peer_send_ids(p, "cancel", j->desc.id, t);
    }
}

int farm_on_tile(peer *p, const uint8_t *body, size_t len) {
    farm *f = p->f;
    char err[256];
    proto_tile h;
    if (proto_tile_parse(body, len, &h, err, sizeof err)) return peer_violation(p, "%s", err);
    job *j = farm_find_job(f, h.job);
    if (!peer_told_job(p, h.job))
        return peer_violation(p, "sent tile %u of job %u, a job it was not given", h.tile, h.job);
    if (!j) return 0; /* a job that ended and was forgotten: a late result */
    lease *l = peer_find_lease(p, h.job, h.tile);
    if (!l) return peer_violation(p, "sent tile %u of job %u, which was not assigned to it", h.tile, h.job);
    const tile_rect *r = &j->rects[h.tile];
    if (h.width != (uint32_t)tile_width(r) || h.height != (uint32_t)tile_height(r))
        return peer_violation(p, "sent tile %u of job %u as %ux%u pixels; it is %dx%d", h.tile, h.job, h.width,
                              h.height, tile_width(r), tile_height(r));
    if (h.channels != (uint32_t)j->film.channels)
        return peer_violation(p, "sent tile %u of job %u with %u values per pixel; the job needs %d", h.tile, h.job,
                              h.channels, j->film.channels);
    long bad;
    float *px = tile_decode(body, &h, &bad);
    if (!px) return peer_violation(p, "tile %u of job %u: out of memory for its pixels", h.tile, h.job);
    if (bad >= 0) {
        free(px);
        return peer_violation(p, "sent tile %u of job %u with a NaN, infinite or negative value (float %ld)",
                              h.tile, h.job, bad);
    }
    double took = farm_now(f) - l->start;
    int was_live = l->live;
    LIST_REMOVE(l, link);
    free(l);
    if (was_live) j->holders[h.tile]--;
    if (j->finished || j->done[h.tile]) {
        free(px);
        j->rep.duplicates++;
        if (f->opt.verbose) farm_log(f, "%s: tile %u of job %u was already done; dropped", p->label, h.tile, h.job);
        return 0;
    }
    int verified = 0, verdict = audit_on_result(f, j, p, h.tile, &px, &h.stats, took, &verified);
    if (verdict != AUDIT_ACCEPT) { /* held for comparison, dropped, or the job failed */
        free(px);
        if (verdict == AUDIT_HOLD) farm_schedule_all(f); /* someone else renders it again */
        return 0;
    }
    if (!was_live && f->opt.verbose)
        farm_log(f, "%s: late result for tile %u of job %u used (nobody had finished it)", p->label, h.tile, h.job);
    farm_tile_land(f, j, p, p->rec.name, p->rec.serial, h.tile, px, took, &h.stats, verified);
    free(px);
    return 0;
}

void farm_tile_land(farm *f, job *j, peer *from, const char *name, uint32_t serial, uint32_t t, const float *px,
                    double took, const trace_stats *stats, int verified) {
    char err[256];
    film_put_tile(&j->film, &j->rects[t], px);
    int rc = j->on_tile ? j->on_tile(j->ctx, t, &j->rects[t], err, sizeof err) : 0;
    if (rc < 0) {
        farm_job_fail(f, j, "%s", err);
        return;
    }
    int pending = rc == FARM_TILE_PENDING;
    j->done[t] = pending ? 2 : 1; /* 2: landed, counted once durable (farm_tile_durable) */
    audit_accepted(j, t, serial, verified);
    j->rep.tiles_done += !pending;
    j->tile_seconds += took;
    trace_stats_add(&j->rep.stats, stats);
    if (from) {
        from->rec.tiles++;
        from->rec.samples += stats->samples;
    }
    farm_emit(f, FARM_EV_DONE, j, t, name, took, stats->samples, 0);
    if (j->holders[t]) job_cancel_copies(f, j, t, from);
    if (!pending && j->rep.tiles_done == j->tile_count) farm_job_finish(f, j);
}

void farm_tile_durable(farm *f, uint32_t job_id, uint32_t tile, const char *error) {
    job *j = farm_find_job(f, job_id);
    if (!j || j->finished || tile >= (uint32_t)j->tile_count || j->done[tile] != 2) return;
    if (error) {
        farm_job_fail(f, j, "%s", error);
        return;
    }
    j->done[tile] = 1;
    j->rep.tiles_done++;
    if (j->rep.tiles_done == j->tile_count) farm_job_finish(f, j);
}
