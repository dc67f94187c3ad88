/* farm_peers.c - the farm's side of each worker connection: accept, the
 * authenticated hello, control messages (ready, give back, failed), the
 * heartbeat clock that finds stalled and silent workers, departures. */
#include <sodium.h>

#include "farm_internal.h"

static void peer_send(peer *p, uint8_t *frame, size_t len) {
    if (!frame) return;
    conn_send(p->c, frame, len);
    p->last_sent = farm_now(p->f);
}

void peer_send_json(peer *p, cJSON *m) {
    size_t len;
    uint8_t *f = m ? wire_frame_json(m, &len) : NULL;
    cJSON_Delete(m);
    peer_send(p, f, len);
}

/* {"type": TYPE, "job": J[, "tile": T]} */
void peer_send_ids(peer *p, const char *type, uint32_t job, long tile) {
    cJSON *m = cJSON_CreateObject();
    cJSON_AddStringToObject(m, "type", type);
    cJSON_AddNumberToObject(m, "job", job);
    if (tile >= 0) cJSON_AddNumberToObject(m, "tile", (double)tile);
    peer_send_json(p, m);
}

/* Send {"type": type, "reason": reason} and close once it is written.
 * Returns 1 (for on_frame). */
static int peer_refuse(peer *p, const char *type, const char *reason) {
    size_t len;
    uint8_t *frame = proto_frame_reason(type, reason, &len);
    peer_send(p, frame, len);
    conn_close(p->c, reason, 1);
    return 1;
}

int peer_violation(peer *p, const char *fmt, ...) {
    char reason[512];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(reason, sizeof reason, fmt, ap);
    va_end(ap);
    farm_log(p->f, "%s: %s; disconnecting", p->label, reason);
    return peer_refuse(p, "error", reason);
}

static void peer_unlink(farm *f, peer *p) {
    (void)f;
    LIST_REMOVE(p, link);
}

/* Refuse p over a connection cap (why from connlimit.h): an "error" (a
 * worker retries later; a client says why and exits), and a log line at
 * most once per CONNLIMIT_LOG_S per cap. Returns 1 (for on_frame). */
static int peer_refuse_cap(peer *p, const char *why) {
    farm *f = p->f;
    unsigned long more = 0;
    if (connlimit_should_log(f->limits, connlimit_last_kind(f->limits), farm_now(f), &more)) {
        char also[96] = "";
        if (more) snprintf(also, sizeof also, " (%lu more refused over this cap since the last such line)", more);
        farm_log(f, "refused a connection from %s: %s; further refusals over this cap are logged at most every %.0f s%s",
                 p->rec.addr, why, CONNLIMIT_LOG_S, also);
    }
    char reason[400];
    snprintf(reason, sizeof reason, "too many connections: %s; try again later", why);
    return peer_refuse(p, "error", reason);
}

/* p stops counting against the caps (at its close, or as a client that
 * the service now counts). */
static void peer_uncount(farm *f, peer *p) {
    if (p->limit_class < 0) return;
    char ip[64];
    connlimit_ip_of(p->rec.addr, ip, sizeof ip);
    connlimit_release(f->limits, ip, (connlimit_class)p->limit_class);
    p->limit_class = -1;
}

void farm_client_closed(farm *f, const char *addr) {
    char ip[64];
    connlimit_ip_of(addr, ip, sizeof ip);
    connlimit_release(f->limits, ip, CONNLIMIT_OPEN);
}

/* Seal p's link with the keys of key (auth_link_keys) from the next frame
 * on: the welcome went in clear. */
static void peer_seal(conn *c, const auth_key *key, const char *nonce, const char *peer_nonce) {
    unsigned char down[AUTH_KEY_BYTES], up[AUTH_KEY_BYTES];
    auth_link_keys(key, nonce, peer_nonce, down, up);
    conn_seal(c, down, up);
    sodium_memzero(down, sizeof down);
    sodium_memzero(up, sizeof up);
}

/* Give a client's connection to opt.on_client (which sends the welcome),
 * seal it when a token was proved, and forget the peer. */
static void peer_hand_over(peer *p, const cJSON *hello, auth_class cls, const auth_key *key) {
    farm *f = p->f;
    conn *c = p->c;
    char addr[64], nonce[AUTH_HEX];
    snprintf(addr, sizeof addr, "%s", p->rec.addr);
    snprintf(nonce, sizeof nonce, "%s", p->nonce);
    p->limit_class = -1; /* still counted as open: farm_client_closed releases it */
    peer_unlink(f, p);
    free(p->scenes);
    free(p->jobs);
    free(p);
    f->opt.on_client(f->opt.client_ctx, c, hello, addr, cls);
    const cJSON *peer_nonce = cJSON_GetObjectItemCaseSensitive(hello, "nonce");
    if (key && !conn_is_closing(c)) peer_seal(c, key, nonce, peer_nonce->valuestring);
}

void farm_add_proof(const farm *f, auth_class cls, const cJSON *hello, cJSON *welcome) {
    const cJSON *nonce = cJSON_GetObjectItemCaseSensitive(hello, "nonce");
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(hello, "name");
    const auth_key *k = auth_key_of(&f->opt.auth, cls, cJSON_IsString(name) ? name->valuestring : NULL);
    if (!k || !cJSON_IsString(nonce)) return;
    char proof[AUTH_HEX];
    auth_proof(k, nonce->valuestring, "coordinator", proof);
    cJSON_AddStringToObject(welcome, "proof", proof);
}

void farm_set_auth(farm *f, const auth_keyring *r) { f->opt.auth = *r; }

/* The one refusal every authentication failure gets, whatever it was (no,
 * wrong or malformed proof, wrong class, a hello that is not one): the
 * same bytes, then the close. A stranger learns that a token is needed,
 * never whether one was close. who (what the peer called itself, or NULL)
 * and fault go to the log only. Returns 1. */
static int peer_refuse_auth(peer *p, const char *who, const char *fault) {
    if (who)
        farm_log(p->f, "peer %s (calling itself %s): authentication failed (%s); refused", p->rec.addr, who, fault);
    else
        farm_log(p->f, "peer %s: authentication failed (%s); refused", p->rec.addr, fault);
    p->rec.name[0] = '\0';
    return peer_refuse(p, "refused", "authentication failed: this coordinator requires a token");
}

/* A refusal before any hello could be checked (not JSON, another message
 * or frame first): the check runs all the same on nothing, so this costs
 * what a wrong proof costs. Returns 1. */
static int peer_refuse_unheard(peer *p, const char *fault) {
    auth_class offered;
    const auth_key *key;
    auth_check_hello(&p->f->opt.auth, p->nonce, NULL, &offered, &key);
    return peer_refuse_auth(p, NULL, fault);
}

/* With tokens: check hello's proof, class and nonce. Returns the class
 * proved (and *key), or AUTH_NONE after refusing p. */
static auth_class hello_auth(peer *p, const cJSON *m, const auth_key **key) {
    auth_class offered;
    auth_class cls = auth_check_hello(&p->f->opt.auth, p->nonce, m, &offered, key);
    const cJSON *role = cJSON_GetObjectItemCaseSensitive(m, "role"), *name = cJSON_GetObjectItemCaseSensitive(m, "name");
    const cJSON *proof = cJSON_GetObjectItemCaseSensitive(m, "proof"), *nonce = cJSON_GetObjectItemCaseSensitive(m, "nonce");
    int client = cJSON_IsString(role) && strcmp(role->valuestring, "client") == 0;
    char who[100], fault[160];
    if (cls == AUTH_NONE && offered != AUTH_NONE)
        snprintf(fault, sizeof fault, "the %s token, which may not %s", auth_class_name(offered),
                 client ? "act as a client" : "register as a worker");
    else if (cls == AUTH_NONE && client && cJSON_IsString(name) && auth_is_user(&p->f->opt.auth, name->valuestring))
        snprintf(fault, sizeof fault, "%s token for user %.60s, who has a token of their own",
                 cJSON_IsString(proof) ? "wrong" : "no", name->valuestring);
    else if (cls == AUTH_NONE)
        snprintf(fault, sizeof fault, "%s token", cJSON_IsString(proof) ? "wrong" : "no");
    else if (!(cJSON_IsString(nonce) && strlen(nonce->valuestring) >= 32 && strlen(nonce->valuestring) < 200))
        snprintf(fault, sizeof fault, "no nonce of 32 to 199 characters: the link keys need one");
    else
        return cls;
    snprintf(who, sizeof who, "%s %.60s", client ? "client" : "worker", cJSON_IsString(name) ? name->valuestring : "?");
    peer_refuse_auth(p, who, fault);
    return AUTH_NONE;
}

/* A bundle hash as scene_bundle_hash writes it: lowercase hex, full length. */
static int is_bundle_hash(const char *h) {
    size_t n = 0;
    for (; h[n]; n++)
        if (!((h[n] >= '0' && h[n] <= '9') || (h[n] >= 'a' && h[n] <= 'f'))) return 0;
    return n == SCENE_BUNDLE_HASH_HEX - 1;
}

/* The hello's "scenes": bundles the worker holds already (a local farm's
 * forked worker, loaded before it started), counted as sent on this
 * connection, so peer_tell_job does not send them and forget_scene may
 * name them. Anything but an array of bundle hashes is ignored, and so
 * are claims beyond PROTOCOL_HELLO_SCENES or FARM_PEER_SCENES. */
static void peer_claim_scenes(peer *p, const cJSON *scenes) {
    if (!cJSON_IsArray(scenes)) return;
    const cJSON *h;
    int seen = 0;
    cJSON_ArrayForEach(h, scenes) {
        if (++seen > PROTOCOL_HELLO_SCENES || p->scene_count >= FARM_PEER_SCENES) return;
        if (!cJSON_IsString(h) || !is_bundle_hash(h->valuestring)) continue;
        int dup = 0;
        for (int i = 0; i < p->scene_count; i++) dup |= strcmp(p->scenes[i].hash, h->valuestring) == 0;
        if (dup) continue;
        void *grown = realloc(p->scenes, (size_t)(p->scene_count + 1) * sizeof *p->scenes);
        if (!grown) return; /* not claimed: the bundle is sent, which is always right */
        p->scenes = grown;
        peer_scene *ps = &p->scenes[p->scene_count++];
        memcpy(ps->hash, h->valuestring, SCENE_BUNDLE_HASH_HEX);
        ps->used = 0;
    }
}

static int on_hello(peer *p, const cJSON *m) {
    farm *f = p->f;
    const auth_key *key = NULL;
    auth_class cls = AUTH_NONE;
    if (auth_keyring_enabled(&f->opt.auth) && (cls = hello_auth(p, m, &key)) == AUTH_NONE) return 1;
    const cJSON *proto = cJSON_GetObjectItemCaseSensitive(m, "protocol");
    const cJSON *build = cJSON_GetObjectItemCaseSensitive(m, "build");
    const cJSON *name = cJSON_GetObjectItemCaseSensitive(m, "name");
    const cJSON *threads = cJSON_GetObjectItemCaseSensitive(m, "threads");
    if (!cJSON_IsNumber(proto) || !cJSON_IsString(build) || !cJSON_IsString(name) || !cJSON_IsNumber(threads) ||
        !(threads->valuedouble >= 1 && threads->valuedouble <= 4096))
        return peer_violation(p, "hello: expected protocol, build, name and threads (1 to 4096)");
    snprintf(p->rec.name, sizeof p->rec.name, "%s", name->valuestring);
    snprintf(p->label, sizeof p->label, "worker %s (%s)", p->rec.name, p->rec.addr);
    const cJSON *role = cJSON_GetObjectItemCaseSensitive(m, "role");
    if (cJSON_IsString(role) && strcmp(role->valuestring, "client") == 0) {
        if (!f->opt.on_client) return peer_violation(p, "this coordinator takes no clients (it renders one scene)");
        if (proto->valuedouble != PROTOCOL_VERSION)
            return peer_violation(p, "version mismatch: client speaks protocol %g; coordinator speaks protocol %d",
                                  proto->valuedouble, PROTOCOL_VERSION);
        peer_hand_over(p, m, cls, key);
        return 0; /* the connection lives on with the client's callbacks */
    }
    if (proto->valuedouble != PROTOCOL_VERSION || strcmp(build->valuestring, protocol_build_id()) != 0) {
        char reason[400];
        snprintf(reason, sizeof reason,
                 "version mismatch: worker speaks protocol %g, build %.100s; coordinator speaks protocol %d, "
                 "build %s",
                 proto->valuedouble, build->valuestring, PROTOCOL_VERSION, protocol_build_id());
        farm_log(f, "%s refused: %s", p->label, reason);
        return peer_refuse(p, "refused", reason);
    }
    char ip[64], why[300];
    connlimit_ip_of(p->rec.addr, ip, sizeof ip);
    if (p->limit_class == CONNLIMIT_OPEN) {
        if (connlimit_promote(f->limits, ip, why, sizeof why)) return peer_refuse_cap(p, why);
        p->limit_class = CONNLIMIT_WORKER;
    }
    p->rec.threads = (int)threads->valuedouble;
    peer_claim_scenes(p, cJSON_GetObjectItemCaseSensitive(m, "scenes"));
    p->state = PEER_ACTIVE;
    size_t max_frame = proto_tile_frame_max(f->opt.max_tile_side);
    conn_set_max_frame(p->c, max_frame > WIRE_JSON_MAX + 1 ? max_frame : WIRE_JSON_MAX + 1);
    cJSON *w = cJSON_CreateObject();
    cJSON_AddStringToObject(w, "type", "welcome");
    cJSON_AddNumberToObject(w, "protocol", PROTOCOL_VERSION);
    cJSON_AddStringToObject(w, "build", protocol_build_id());
    cJSON_AddNumberToObject(w, "heartbeat_ms", f->opt.heartbeat_s * 1e3);
    cJSON_AddNumberToObject(w, "timeout_ms", f->opt.timeout_s * 1e3);
    farm_add_proof(f, cls, m, w);
    peer_send_json(p, w);
    if (key) peer_seal(p->c, key, p->nonce, cJSON_GetObjectItemCaseSensitive(m, "nonce")->valuestring);
    if (f->opt.verbose) farm_log(f, "%s joined with %d threads", p->label, p->rec.threads);
    farm_emit(f, FARM_EV_JOIN, NULL, 0, p->rec.name, 0, 0, 0);
    return 0;
}

static int read_tile_ids(peer *p, const cJSON *m, const char *type, uint32_t *job, uint32_t *tile) {
    const cJSON *j = cJSON_GetObjectItemCaseSensitive(m, "job"), *t = cJSON_GetObjectItemCaseSensitive(m, "tile");
    if (!cJSON_IsNumber(j) || !cJSON_IsNumber(t) || j->valuedouble < 0 || t->valuedouble < 0 ||
        j->valuedouble > UINT32_MAX || t->valuedouble > UINT32_MAX) {
        peer_violation(p, "%s: expected job and tile numbers", type);
        return -1;
    }
    *job = (uint32_t)j->valuedouble;
    *tile = (uint32_t)t->valuedouble;
    return 0;
}

/* "cancelled" or "failed": p gives a tile back. */
static int on_give_back(peer *p, const cJSON *m, int failed) {
    farm *f = p->f;
    uint32_t job_id, tile;
    if (read_tile_ids(p, m, failed ? "failed" : "cancelled", &job_id, &tile)) return 1;
    lease *l = peer_find_lease(p, job_id, tile);
    if (!l) return 0; /* its result or an earlier answer already settled it */
    job *j = l->job;
    LIST_REMOVE(l, link);
    if (failed) {
        const cJSON *r = cJSON_GetObjectItemCaseSensitive(m, "reason");
        const char *why = cJSON_IsString(r) ? r->valuestring : "no reason given";
        farm_log(f, "%s: tile %u of job %u failed: %.300s", p->label, tile, job_id, why);
        p->failures++;
        block_note_failure(f, j, p, "tile %u failed: %.200s", tile, why);
        if (!j->finished && ++j->failures[tile] >= MAX_TILE_FAILURES) {
            farm_lease_release(l);
            free(l);
            farm_job_fail(f, j, "tile %u failed %d times, last on %s: %.300s", tile, MAX_TILE_FAILURES, p->label, why);
            return 0;
        }
    }
    farm_lease_release(l);
    free(l);
    farm_schedule_all(f);
    return 0;
}

static int on_json(peer *p, const uint8_t *body, size_t len) {
    char err[256];
    const char *type;
    cJSON *m = proto_parse_json(body, len, &type, err, sizeof err);
    if (!m && p->state == PEER_HELLO && auth_keyring_enabled(&p->f->opt.auth)) return peer_refuse_unheard(p, err);
    if (!m) return peer_violation(p, "%s", err);
    int rc = 0;
    if (p->state == PEER_HELLO) {
        if (strcmp(type, "hello") == 0) rc = on_hello(p, m);
        else if (auth_keyring_enabled(&p->f->opt.auth)) rc = peer_refuse_unheard(p, "a message before hello");
        else rc = peer_violation(p, "expected hello, got \"%.40s\"", type);
    } else if (strcmp(type, "ready") == 0) {
        const cJSON *s = cJSON_GetObjectItemCaseSensitive(m, "slots");
        if (!cJSON_IsNumber(s) || s->valuedouble < 1 || p->credits + s->valuedouble > MAX_CREDITS) {
            rc = peer_violation(p, "ready: slots must be a number from 1 to %d in all", MAX_CREDITS);
        } else {
            p->credits += (int)s->valuedouble;
            peer_schedule(p);
        }
    } else if (strcmp(type, "cancelled") == 0 || strcmp(type, "failed") == 0) {
        rc = on_give_back(p, m, type[0] == 'f');
    } else if (strcmp(type, "bye") == 0) {
        conn_close(p->c, "worker left", 0);
        rc = 1;
    } else if (strcmp(type, "heartbeat") != 0) {
        rc = peer_violation(p, "unknown message type \"%.40s\"", type);
    }
    cJSON_Delete(m);
    return rc;
}

static int on_frame(conn *c, int kind, const uint8_t *body, size_t len) {
    peer *p = conn_data(c);
    farm *f = p->f;
    p->last_heard = farm_now(f);
    if (p->state == PEER_STALLED) {
        p->state = PEER_ACTIVE;
        farm_log(f, "%s is responding again", p->label);
    }
    if (kind == WIRE_KIND_JSON) return on_json(p, body, len);
    if (kind == WIRE_KIND_TILE && p->state != PEER_HELLO) return farm_on_tile(p, body, len);
    if (p->state == PEER_HELLO && auth_keyring_enabled(&f->opt.auth))
        return peer_refuse_unheard(p, "a binary frame before hello");
    return peer_violation(p, "unexpected frame kind 0x%02x%s", kind, p->state == PEER_HELLO ? " before hello" : "");
}

static void peer_record_departure(farm *f, peer *p, const char *why) {
    p->rec.bytes_in = conn_bytes_in(p->c);
    p->rec.bytes_out = conn_bytes_out(p->c);
    p->rec.left = farm_now(f);
    snprintf(p->rec.why, sizeof p->rec.why, "%s", why);
    f->closed_bytes_in += p->rec.bytes_in;
    f->closed_bytes_out += p->rec.bytes_out;
    if (p->state == PEER_HELLO && p->rec.name[0] == '\0') return; /* never introduced itself */
    if (f->departed_count == FARM_DEPARTED_MAX) { /* a long-lived service: keep the latest, count the rest */
        memmove(f->departed, f->departed + 1, (size_t)(FARM_DEPARTED_MAX - 1) * sizeof *f->departed);
        f->departed_count--;
        f->departed_dropped++;
    }
    if (f->departed_count == f->departed_cap) {
        int cap = f->departed_cap ? 2 * f->departed_cap : 16;
        peer_record *d = realloc(f->departed, (size_t)cap * sizeof *d);
        if (!d) return;
        f->departed = d;
        f->departed_cap = cap;
    }
    f->departed[f->departed_count++] = p->rec;
}

static void on_conn_close(conn *c, const char *reason) {
    peer *p = conn_data(c);
    farm *f = p->f;
    int requeued = 0;
    if (p->state != PEER_HELLO && strcmp(reason, "worker left") != 0) { /* not a bye: a crash, a kill, a fault */
        char why[200];
        snprintf(why, sizeof why, "left (%.150s)", reason);
        block_note_lost_leases(f, p, why);
    }
    while (!LIST_EMPTY(&p->leases)) {
        lease *l = LIST_FIRST(&p->leases);
        LIST_REMOVE(l, link);
        requeued += l->live;
        farm_lease_release(l);
        free(l);
    }
    if (conn_malformed(c))
        farm_log(f, "%s: %s; disconnecting", p->label, reason);
    else if ((p->state != PEER_HELLO && !f->closing) || f->opt.verbose)
        farm_log(f, "%s left: %s (%llu tiles done%s)", p->label, reason, (unsigned long long)p->rec.tiles,
                 requeued ? ", its unfinished tiles go back to the queue" : "");
    peer_record_departure(f, p, reason);
    peer_uncount(f, p);
    if (p->state != PEER_HELLO) farm_emit(f, FARM_EV_LEAVE, NULL, 0, p->rec.name, 0, 0, 0);
    peer_unlink(f, p);
    free(p->scenes);
    free(p->jobs);
    memset(p, 0xdb, sizeof *p);
    free(p);
    if (requeued && !f->closing) farm_schedule_all(f);
}

static const conn_callbacks farm_conn_cb = {on_frame, on_conn_close};

void farm_on_connection(uv_stream_t *server, int status) {
    farm *f = server->data;
    if (status < 0) {
        farm_log(f, "accept failed: %s", uv_strerror(status));
        return;
    }
    peer *p = calloc(1, sizeof *p);
    conn *c = p ? conn_new(f->loop, &farm_conn_cb, p, WIRE_JSON_MAX + 1) : NULL;
    if (!c) {
        free(p);
        farm_log(f, "out of memory for a new connection");
        return;
    }
    p->f = f;
    p->c = c;
    p->joined = p->last_heard = p->last_sent = farm_now(f);
    p->rec.joined = p->joined;
    p->rec.serial = ++f->next_serial;
    p->limit_class = -1;
    if (uv_accept(server, (uv_stream_t *)conn_tcp(c)) != 0 || conn_start(c) != 0) {
        snprintf(p->label, sizeof p->label, "connection");
        LIST_INSERT_HEAD(&f->peers, p, link);
        conn_close(c, "accept failed", 0);
        return;
    }
    uv_tcp_nodelay(conn_tcp(c), 1);
    conn_peer_address(c, p->rec.addr, sizeof p->rec.addr);
    snprintf(p->label, sizeof p->label, "peer %s", p->rec.addr);
    LIST_INSERT_HEAD(&f->peers, p, link);
    char ip[64], why[300];
    connlimit_ip_of(p->rec.addr, ip, sizeof ip);
    if (connlimit_admit(f->limits, ip, why, sizeof why)) {
        peer_refuse_cap(p, why);
        return;
    }
    p->limit_class = CONNLIMIT_OPEN;
    auth_nonce(p->nonce);
    cJSON *ch = cJSON_CreateObject();
    cJSON_AddStringToObject(ch, "type", "challenge");
    cJSON_AddStringToObject(ch, "nonce", p->nonce);
    peer_send_json(p, ch);
}

static void peer_stall(peer *p, double silent) {
    p->state = PEER_STALLED;
    char why[64];
    snprintf(why, sizeof why, "silent for %.1f s", silent);
    block_note_lost_leases(p->f, p, why);
    int n = 0;
    lease *l;
    LIST_FOREACH(l, &p->leases, link) {
        n += l->live;
        farm_lease_release(l);
    }
    farm_log(p->f, "%s silent for %.1f s: %d tiles go back to the queue", p->label, silent, n);
}

static void peer_check(peer *p, double now) {
    farm *f = p->f;
    double silent = now - p->last_heard;
    if (p->state == PEER_HELLO && silent > f->opt.hello_timeout_s) {
        char why[64];
        snprintf(why, sizeof why, "no hello within %.1f s", f->opt.hello_timeout_s);
        conn_close(p->c, why, 0);
        return;
    }
    if (p->state == PEER_HELLO) return;
    if (silent > f->opt.drop_s) {
        char why[96];
        snprintf(why, sizeof why, "silent for %.1f s", silent);
        conn_close(p->c, why, 0);
        return;
    }
    if (p->state == PEER_ACTIVE && silent > f->opt.timeout_s) peer_stall(p, silent);
    lease *l;
    LIST_FOREACH(l, &p->leases, link)
        if (l->live && now - l->start > f->opt.lease_s) {
            farm_log(f, "%s held tile %u of job %u for %.0f s, past its lease; it goes back to the queue", p->label,
                     l->tile, l->job->desc.id, now - l->start);
            block_note_failure(f, l->job, p, "held tile %u for %.0f s, past its lease", l->tile, now - l->start);
            farm_lease_release(l);
        }
    if (now - p->last_sent >= f->opt.heartbeat_s) {
        size_t len;
        uint8_t *frame = proto_frame_simple("heartbeat", &len);
        peer_send(p, frame, len);
    }
}

void farm_on_tick(uv_timer_t *t) {
    farm *f = t->data;
    double now = farm_now(f);
    peer *p, *next;
    LIST_FOREACH_SAFE(p, &f->peers, link, next) /* p may be closed (but is freed only later) */
        if (!conn_is_closing(p->c)) peer_check(p, now);
    farm_schedule_all(f);
    job *j, *jn;
    TAILQ_FOREACH_SAFE(j, &f->jobs, link, jn) audit_settle(f, j); /* may end (and free) j */
    TAILQ_FOREACH(j, &f->jobs, link)
        if (!j->finished && j->cb && j->reported != j->rep.tiles_done) {
            farm_report r;
            farm_report_fill(f, j, &r);
            j->reported = j->rep.tiles_done;
            j->cb(j->ctx, &r, 0);
        }
}

int farm_list_workers(const farm *f, farm_worker_info *out, int max) {
    int n = 0;
    double now = farm_now(f);
    peer *p;
    LIST_FOREACH(p, &f->peers, link) {
        if (p->state == PEER_HELLO) continue;
        if (n < max) {
            farm_worker_info *w = &out[n];
            memset(w, 0, sizeof *w);
            snprintf(w->name, sizeof w->name, "%s", p->rec.name);
            snprintf(w->addr, sizeof w->addr, "%s", p->rec.addr);
            w->threads = p->rec.threads;
            w->stalled = p->state == PEER_STALLED;
            w->tiles = p->rec.tiles;
            w->samples = p->rec.samples;
            w->connected_s = now - p->joined;
            w->silent_s = now - p->last_heard;
            w->quarantined = p->rec.quarantined;
            w->failures = p->failures;
            block_list_peer(f, p, &w->blocklisted, &w->retry_s);
        }
        n++;
    }
    return n;
}

/* One line of farm_print_workers; blocked: the running jobs it is
 * blocklisted in, retry_s: when it may try the first again. */
static void print_record(FILE *out, const peer_record *r, const char *state, uint64_t in, uint64_t out_b, int blocked,
                         double retry_s) {
    char q[128] = "";
    if (r->quarantined)
        snprintf(q, sizeof q, "  QUARANTINED in %d job%s", r->quarantined, r->quarantined > 1 ? "s" : "");
    if (blocked)
        snprintf(q + strlen(q), sizeof q - strlen(q), "  BLOCKLISTED in %d job%s (retry in %.0f s)", blocked,
                 blocked > 1 ? "s" : "", retry_s);
    fprintf(out, "  %-20s %-22s %3d threads %6llu tiles %8.2f Msamples  in %8.1f KiB  out %8.1f KiB  %s%s\n",
            r->name, r->addr, r->threads, (unsigned long long)r->tiles, (double)r->samples / 1e6,
            (double)in / 1024.0, (double)out_b / 1024.0, state, q);
}

void farm_print_workers(const farm *f, FILE *out) {
    peer *p;
    LIST_FOREACH(p, &f->peers, link)
        if (p->state != PEER_HELLO) {
            int blocked;
            double retry_s;
            block_list_peer(f, p, &blocked, &retry_s);
            print_record(out, &p->rec, p->state == PEER_STALLED ? "stalled" : "connected", conn_bytes_in(p->c),
                         conn_bytes_out(p->c), blocked, retry_s);
        }
    if (f->departed_dropped)
        fprintf(out, "(%llu earlier departures not listed; the last %d follow)\n",
                (unsigned long long)f->departed_dropped, FARM_DEPARTED_MAX);
    for (int i = 0; i < f->departed_count; i++) {
        char state[160];
        snprintf(state, sizeof state, "left: %s", f->departed[i].why);
        print_record(out, &f->departed[i], state, f->departed[i].bytes_in, f->departed[i].bytes_out, 0, 0);
    }
    if (f->opt.audit > 0)
        fprintf(out,
                "  audit (%g of tiles): %llu tiles checked by two workers, %llu mismatches, %llu workers quarantined, "
                "%llu accepted unchecked (no second worker)\n",
                f->opt.audit, (unsigned long long)f->audited, (unsigned long long)f->audit_mismatches,
                (unsigned long long)f->quarantined, (unsigned long long)f->audit_unchecked);
    if (f->blocklisted)
        fprintf(out, "  blocklist: %llu times a worker was blocklisted for a job (failed, crashed or timed out %d "
                "times)\n", (unsigned long long)f->blocklisted, MAX_PEER_FAILURES);
}
