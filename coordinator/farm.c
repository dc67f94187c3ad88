/* farm.c - the farm: created on a libuv loop, listening for workers, closed
 * and freed (see farm.h; the parts are listed in farm_internal.h). */
#include "farm_internal.h"
#include "net/address.h"

void farm_log(const farm *f, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    log_vline(f->opt.log, LOG_INFO, "tessera-coordinator", fmt, ap);
    va_end(ap);
}

void farm_options_default(farm_options *o) {
    memset(o, 0, sizeof *o);
    o->host = "127.0.0.1";
    o->heartbeat_s = 1.0;
    o->timeout_s = 5.0;
    o->drop_s = 30.0;
    o->lease_s = 300.0;
    o->max_tile_side = 256;
    o->audit = FARM_AUDIT_DEFAULT;
    o->blocklist_s = FARM_BLOCKLIST_DEFAULT;
}

farm *farm_new(uv_loop_t *loop, const farm_options *o, char *err, size_t err_len) {
    farm *f = calloc(1, sizeof *f);
    if (!f) {
        snprintf(err, err_len, "out of memory");
        return NULL;
    }
    f->loop = loop;
    f->opt = *o;
    LIST_INIT(&f->peers);
    TAILQ_INIT(&f->jobs);
    if (f->opt.hello_timeout_s <= 0) f->opt.hello_timeout_s = HELLO_TIMEOUT_S;
    f->limits = connlimit_new(&o->limits);
    if (!f->limits) {
        snprintf(err, err_len, "out of memory");
        free(f);
        return NULL;
    }
    struct sockaddr_storage addr;
    char where[300];
    address_format(o->host, o->port, where, sizeof where);
    int rc = uv_ip4_addr(o->host, o->port, (struct sockaddr_in *)&addr);
    if (rc) rc = uv_ip6_addr(o->host, o->port, (struct sockaddr_in6 *)&addr);
    if (rc) {
        snprintf(err, err_len, "cannot listen on %s: not a numeric IPv4 or IPv6 address", where);
        connlimit_free(f->limits);
        free(f);
        return NULL;
    }
    uv_tcp_init(loop, &f->listener);
    f->listener.data = f;
    rc = uv_tcp_bind(&f->listener, (struct sockaddr *)&addr, 0);
    if (rc == 0) rc = uv_listen((uv_stream_t *)&f->listener, 1024, farm_on_connection);
    if (rc) {
        snprintf(err, err_len, "cannot listen on %s: %s", where, uv_strerror(rc));
        uv_close((uv_handle_t *)&f->listener, NULL);
        uv_run(loop, UV_RUN_NOWAIT); /* let the close finish before freeing */
        connlimit_free(f->limits);
        free(f);
        return NULL;
    }
    int n = sizeof addr;
    uv_tcp_getsockname(&f->listener, (struct sockaddr *)&addr, &n);
    f->port = ntohs(addr.ss_family == AF_INET ? ((struct sockaddr_in *)&addr)->sin_port
                                               : ((struct sockaddr_in6 *)&addr)->sin6_port);
    uv_timer_init(loop, &f->tick);
    f->tick.data = f;
    uv_timer_start(&f->tick, farm_on_tick, FARM_TICK_MS, FARM_TICK_MS);
    return f;
}

int farm_port(const farm *f) { return f->port; }

static void on_handle_closed(uv_handle_t *h) {
    farm *f = h->data;
    if (--f->open_handles == 0 && f->closed_cb) f->closed_cb(f->closed_ctx);
}

void farm_wind_down(farm *f) { f->closing = 1; }

void farm_close(farm *f, void (*cb)(void *ctx), void *ctx) {
    f->closing = 1;
    f->closed_cb = cb;
    f->closed_ctx = ctx;
    peer *p, *next;
    LIST_FOREACH_SAFE(p, &f->peers, link, next) conn_close(p->c, "the coordinator is done", 1);
    f->open_handles = 2;
    uv_close((uv_handle_t *)&f->listener, on_handle_closed);
    uv_close((uv_handle_t *)&f->tick, on_handle_closed);
}

void farm_free(farm *f) {
    if (!f) return;
    job *j, *next;
    TAILQ_FOREACH_SAFE(j, &f->jobs, link, next) farm_job_free(j);
    free(f->departed);
    connlimit_free(f->limits);
    free(f);
}

void farm_set_event_cb(farm *f, void (*cb)(void *ctx, const farm_event *e), void *ctx) {
    f->event_cb = cb;
    f->event_ctx = ctx;
}

void farm_get_totals(const farm *f, farm_totals *t) {
    memset(t, 0, sizeof *t);
    t->bytes_in = f->closed_bytes_in;
    t->bytes_out = f->closed_bytes_out;
    peer *p;
    LIST_FOREACH(p, &f->peers, link) {
        t->bytes_in += conn_bytes_in(p->c);
        t->bytes_out += conn_bytes_out(p->c);
    }
    job *j;
    TAILQ_FOREACH(j, &f->jobs, link) {
        t->queued += j->q_len;
        t->running_jobs += !j->finished;
    }
}
