/* local_farm.c - one render on a farm run from this process (see
 * local_farm.h): listen, spawn the local workers, feed the farm the job,
 * report progress, and tear everything down when the last tile is stitched.
 *
 * Local workers run with --once, so they exit when the coordinator closes
 * their connection; a local worker that dies early is started again (up to
 * LOCAL_RESTARTS times per slot), and its tiles go back to the queue. */
#define _GNU_SOURCE
#include "local_farm.h"
#include "net/address.h"


#include "render/adaptive.h"

#include <limits.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <errno.h>
#include <sys/resource.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#include <uv.h>

#define LOCAL_RESTARTS 3
#define EXIT_GRACE_MS 10000 /* after the render, how long workers get to exit */

typedef struct local_run local_run;

typedef struct {
    uv_process_t proc;
    local_run *run;
    int slot;
} local_proc;

typedef struct {
    int alive, restarts;
    int pid; /* while alive: a forked worker (local_farm_options.forked), watched through SIGCHLD; else 0 */
} local_slot;

struct local_run {
    const local_farm_options *o;
    uv_loop_t loop;
    farm *f;
    local_slot *slots;
    int alive;
    char exe[PATH_MAX];
    char connect[300];
    uv_signal_t sigint, sigterm;
    uv_signal_t sigchld; /* forked workers' exits (spawned ones are libuv's) */
    int watching_forked;  /* sigchld started, not yet closed */
    uv_timer_t grace;
    int farm_closing; /* farm_close called (close_farm_when_alone) */
    int finished, failed, interrupted;
    char err[600];
    farm_report last;
    uint64_t total_samples;
    double start, last_shown;
    /* Adaptive sampling: one farm job per round, the next submitted from a
     * timer once the farm has finished calling back about the last. */
    const proto_job *job;
    const uint8_t *bundle;
    size_t bundle_len;
    float *rgb;
    adaptive *ad;
    float *sums;
    uint8_t *mask, *done;
    uint32_t round_id;
    trace_stats round_stats; /* of the rounds before the current one */
    int round_tiles;
    uv_timer_t round_timer;
    dashboard *web;   /* o->http: the render seen in a browser */
    double wall_start; /* epoch seconds, for the dashboard */
};

static double mono_now(const local_run *r) { return (double)uv_hrtime() / 1e9 - r->start; }

/* tessera-worker next to this executable, or $TESSERA_WORKER. */
static int find_worker_exe(char *out, size_t n, char *err, size_t err_len) {
    const char *env = getenv("TESSERA_WORKER");
    if (env && *env) {
        snprintf(out, n, "%s", env);
    } else {
        char self[PATH_MAX];
        ssize_t len = readlink("/proc/self/exe", self, sizeof self - 1);
        if (len <= 0) {
            snprintf(err, err_len, "cannot find this program's path to locate tessera-worker");
            return -1;
        }
        self[len] = '\0';
        char *slash = strrchr(self, '/');
        if (slash) *slash = '\0';
        if ((size_t)snprintf(out, n, "%.*s/tessera-worker", (int)(n - 16), self) >= n) return -1;
    }
    if (access(out, X_OK) != 0) {
        snprintf(err, err_len, "cannot run the worker program %s (build it with make, or set TESSERA_WORKER)", out);
        return -1;
    }
    return 0;
}

static void render_stop(local_run *r);
static void close_farm_when_alone(local_run *r);

static void on_proc_closed(uv_handle_t *h) { free(h->data); }

static int spawn_worker(local_run *r, int slot);

/* Local worker `slot` has exited with status, or was killed by signal:
 * start it again (up to LOCAL_RESTARTS times), or end the render when no
 * worker is left. */
static void worker_gone(local_run *r, int slot, int64_t status, int signal) {
    r->slots[slot].alive = 0;
    r->slots[slot].pid = 0;
    r->alive--;
    if (r->finished) {
        close_farm_when_alone(r);
        return;
    }
    if (signal)
        fprintf(stderr, "tessera: local worker local-%d was killed by signal %d\n", slot, signal);
    else
        fprintf(stderr, "tessera: local worker local-%d exited with status %lld\n", slot, (long long)status);
    if (r->slots[slot].restarts < LOCAL_RESTARTS) {
        r->slots[slot].restarts++;
        fprintf(stderr, "tessera: starting local-%d again (restart %d of %d)\n", slot, r->slots[slot].restarts,
                LOCAL_RESTARTS);
        if (spawn_worker(r, slot) == 0) return;
    }
    if (r->alive == 0 && !r->o->listening) {
        snprintf(r->err, sizeof r->err, "every local worker failed (the last: %s %lld); see the messages above",
                 signal ? "signal" : "status", signal ? (long long)signal : (long long)status);
        r->failed = 1;
        render_stop(r);
    }
}

static void on_worker_exit(uv_process_t *p, int64_t status, int signal) {
    local_proc *lp = p->data;
    local_run *r = lp->run;
    int slot = lp->slot;
    lp->proc.data = lp;
    uv_close((uv_handle_t *)p, on_proc_closed);
    worker_gone(r, slot, status, signal);
}

/* Reap the forked workers that have exited (SIGCHLD, and once when the
 * watch starts: one may have gone before). */
static void reap_forked(local_run *r) {
    for (int i = 0; i < r->o->workers; i++) {
        int st, pid = r->slots[i].pid;
        if (!pid || waitpid(pid, &st, WNOHANG) != pid) continue;
        worker_gone(r, i, WIFEXITED(st) ? WEXITSTATUS(st) : 0, WIFSIGNALED(st) ? WTERMSIG(st) : 0);
    }
}

static void on_sigchld(uv_signal_t *h, int signum) {
    (void)signum;
    reap_forked(h->data);
}

/* Signal every forked worker still running. */
static void signal_forked(local_run *r, int signum) {
    for (int i = 0; i < r->o->workers; i++)
        if (r->slots[i].pid) kill(r->slots[i].pid, signum);
}

/* Take over the caller's forked workers: watch their exits, and tell each
 * where to dial (then close its fd, so that it reads to the end). */
static void adopt_forked(local_run *r) {
    const local_farm_options *o = r->o;
    uv_signal_init(&r->loop, &r->sigchld);
    r->sigchld.data = r;
    uv_signal_start(&r->sigchld, on_sigchld, SIGCHLD);
    r->watching_forked = 1;
    for (int i = 0; i < o->workers; i++) {
        r->slots[i].pid = o->forked[i].pid;
        r->slots[i].alive = 1;
        r->alive++;
        size_t len = strlen(r->connect), off = 0;
        while (off < len) { /* a few bytes into an empty socket: never blocks for long */
            ssize_t n = write(o->forked[i].fd, r->connect + off, len - off);
            if (n < 0 && errno == EINTR) continue;
            if (n <= 0) break; /* it has gone already: its exit is reaped below */
            off += (size_t)n;
        }
        close(o->forked[i].fd);
    }
    reap_forked(r);
}

void local_farm_release_forked(const local_farm_forked *forked, int n) {
    for (int i = 0; i < n; i++) close(forked[i].fd);
    for (int i = 0; i < n; i++)
        while (waitpid(forked[i].pid, NULL, 0) < 0 && errno == EINTR) {
        }
}

/* The render failed before the farm took the forked workers over. */
static void release_forked(const local_farm_options *o) {
    if (o->forked) local_farm_release_forked(o->forked, o->workers);
}

/* Stop watching forked workers once none is left; once. */
static void unwatch_forked(local_run *r) {
    if (!r->watching_forked) return;
    r->watching_forked = 0;
    uv_close((uv_handle_t *)&r->sigchld, NULL);
}

static int spawn_worker(local_run *r, int slot) {
    local_proc *lp = calloc(1, sizeof *lp);
    if (!lp) return -1;
    lp->run = r;
    lp->slot = slot;
    lp->proc.data = lp;
    char threads[16], name[32];
    snprintf(threads, sizeof threads, "%d", r->o->threads_per_worker);
    snprintf(name, sizeof name, "local-%d", slot);
    /* Quiet but for errors; with -v, verbose: each worker then says which
     * intersector it built for the scene, with its load time. */
    char *args[] = {r->exe, "--connect", r->connect, "--threads", threads, "--name", name, "--once",
                    r->o->verbose ? "--verbose" : "--quiet", NULL, NULL, NULL};
    if (r->o->token_file) {
        args[9] = "--token-file";
        args[10] = (char *)r->o->token_file;
    }
    uv_stdio_container_t stdio[3] = {{.flags = UV_IGNORE}, {.flags = UV_IGNORE},
                                     {.flags = UV_INHERIT_FD, .data.fd = STDERR_FILENO}};
    /* Detached (a session of their own): a Ctrl-C at the terminal reaches
     * only this process, which then stops them (render_stop), rather than
     * racing it and being restarted. */
    uv_process_options_t po = {.exit_cb = on_worker_exit, .file = r->exe, .args = args,
                               .stdio_count = 3, .stdio = stdio, .flags = UV_PROCESS_DETACHED};
    int rc = uv_spawn(&r->loop, &lp->proc, &po);
    if (rc) {
        fprintf(stderr, "tessera: cannot start %s: %s\n", r->exe, uv_strerror(rc));
        uv_close((uv_handle_t *)&lp->proc, on_proc_closed);
        return -1;
    }
    r->slots[slot].alive = 1;
    r->alive++;
    return 0;
}

static void show_progress(local_run *r, const farm_report *rep, int final) {
    double el = mono_now(r);
    double rate = el > 0 ? (double)rep->stats.samples / el : 0;
    double eta = rate > 0 ? (double)(r->total_samples - rep->stats.samples) / rate : 0;
    r->o->progress(r->o->progress_ctx, rep->tiles_done, rep->tiles_total, rate, rep->workers, eta, final);
}

/* Kill what remains after the grace period. */
static void kill_walk(uv_handle_t *h, void *arg) {
    (void)arg;
    if (h->type == UV_PROCESS && !uv_is_closing(h)) uv_process_kill((uv_process_t *)h, SIGKILL);
}

static void on_grace_timer(uv_timer_t *t) {
    fprintf(stderr, "tessera: local workers still running %d s after the render; killing them\n",
            EXIT_GRACE_MS / 1000);
    uv_walk(t->loop, kill_walk, NULL);
    signal_forked(t->data, SIGKILL);
    uv_close((uv_handle_t *)t, NULL);
}

static void on_farm_closed(void *ctx) { (void)ctx; }

/* SIGTERM every local worker still running. */
static void term_walk(uv_handle_t *h, void *arg) {
    (void)arg;
    if (h->type == UV_PROCESS && !uv_is_closing(h)) uv_process_kill((uv_process_t *)h, SIGTERM);
}

/* Close the farm once the render is over and no local worker is left;
 * once. */
static void close_farm_when_alone(local_run *r) {
    if (!r->finished || r->alive > 0 || r->farm_closing) return;
    r->farm_closing = 1;
    unwatch_forked(r);
    if (!uv_is_closing((uv_handle_t *)&r->grace)) uv_close((uv_handle_t *)&r->grace, NULL);
    farm_close(r->f, on_farm_closed, r);
}

/* The render is over (done, failed or interrupted): tell the local workers
 * to go, close our own handles, and the farm once they are gone. The port
 * stays open until then: a worker that had not joined yet (a render of a
 * few tiles can end first) then leaves on SIGTERM without a word, instead
 * of finding the port closed and saying it cannot reach the coordinator
 * (3 of 6 renders of 8x8 pixels did). */
static void render_stop(local_run *r) {
    if (r->finished) return;
    r->finished = 1;
    if (r->web) dashboard_close(r->web, NULL, NULL);
    r->web = NULL;
    farm_wind_down(r->f); /* their leaving is not news */
    uv_walk(&r->loop, term_walk, NULL);
    signal_forked(r, SIGTERM);
    uv_close((uv_handle_t *)&r->sigint, NULL);
    uv_close((uv_handle_t *)&r->sigterm, NULL);
    uv_close((uv_handle_t *)&r->round_timer, NULL);
    if (r->alive > 0) uv_timer_start(&r->grace, on_grace_timer, EXIT_GRACE_MS, 0);
    close_farm_when_alone(r);
}

static void on_job(void *ctx, const farm_report *rep, int done);

/* Hand the farm the next adaptive round, or finish the render when there is
 * none. Returns 0, or -1 when out of memory (then the render has failed). */
static int submit_round(local_run *r) {
    uint32_t first, count;
    const proto_job *job = r->job;
    if (adaptive_next_round(r->ad, &first, &count, r->mask) == 0) {
        adaptive_result(r->ad, r->rgb, r->o->samples);
        render_stop(r);
        return 0;
    }
    int ts = r->o->tile_size;
    int marked = render_mark_idle_tiles(job->width, job->height, ts, r->mask, r->done);
    proto_job round = *job;
    round.id = ++r->round_id;
    farm_job_options fo = {.tile_size = ts, .done = r->done, .mask = r->mask, .first = first, .count = count};
    if (marked || farm_submit(r->f, &round, r->bundle, r->bundle_len, &fo, r->sums, on_job, r)) {
        snprintf(r->err, sizeof r->err, "out of memory for adaptive round %u", r->round_id);
        r->failed = 1;
        render_stop(r);
        return -1;
    }
    return 0;
}

static void on_round_timer(uv_timer_t *t) {
    local_run *r = t->data;
    if (r->finished) return;
    farm_forget(r->f, r->round_id);
    submit_round(r);
}

static void on_job(void *ctx, const farm_report *rep, int done) {
    local_run *r = ctx;
    r->last = *rep;
    if (r->ad) { /* figures of the whole render, not just this round */
        trace_stats_add(&r->last.stats, &r->round_stats);
        r->last.tiles_done += r->round_tiles;
        r->last.tiles_total += r->round_tiles;
    }
    if (r->ad && done && !rep->failed && !rep->cancelled) {
        adaptive_add_round(r->ad, r->sums);
        trace_stats_add(&r->round_stats, &rep->stats);
        r->round_tiles += rep->tiles_total;
        uv_timer_start(&r->round_timer, on_round_timer, 0, 0);
        return;
    }
    rep = &r->last;
    double now = mono_now(r);
    if (r->o->progress && (done || now - r->last_shown >= 0.1)) {
        show_progress(r, rep, done);
        r->last_shown = now;
    }
    if (!done) return;
    if (rep->failed) {
        snprintf(r->err, sizeof r->err, "%s", rep->error);
        r->failed = 1;
    }
    render_stop(r);
}

static void on_signal(uv_signal_t *s, int signum) {
    local_run *r = s->data;
    snprintf(r->err, sizeof r->err, "interrupted by %s", signum == SIGINT ? "SIGINT" : "SIGTERM");
    r->failed = 1;
    r->interrupted = signum;
    render_stop(r);
}

static double cpu_seconds(void) {
    struct rusage ru;
    getrusage(RUSAGE_SELF, &ru);
    return (double)ru.ru_utime.tv_sec + 1e-6 * (double)ru.ru_utime.tv_usec + (double)ru.ru_stime.tv_sec +
           1e-6 * (double)ru.ru_stime.tv_usec;
}

/* Set up the adaptive rounds' state of r (when a noise threshold is set).
 * Returns 0, or -1 when out of memory. */
static int adaptive_setup(local_run *r) {
    const local_farm_options *o = r->o;
    const proto_job *job = r->job;
    if (o->noise_threshold <= 0) return 0;
    size_t px = (size_t)job->width * (size_t)job->height;
    r->ad = adaptive_new(job->width, job->height, job->spp, o->min_spp, o->noise_threshold);
    r->sums = calloc(px * ADAPTIVE_CHANNELS, sizeof(float));
    r->mask = malloc(px);
    r->done = malloc((size_t)render_split_tiles(job->width, job->height, o->tile_size, NULL, 0));
    return r->ad && r->sums && r->mask && r->done ? 0 : -1;
}

/* The loop's handles other than the farm's: signals, the grace and round
 * timers. Can't fail. */
static void handles_init(local_run *r) {
    uv_timer_init(&r->loop, &r->round_timer);
    r->round_timer.data = r;
    uv_signal_init(&r->loop, &r->sigint);
    uv_signal_init(&r->loop, &r->sigterm);
    r->sigint.data = r->sigterm.data = r;
    uv_signal_start(&r->sigint, on_signal, SIGINT);
    uv_signal_start(&r->sigterm, on_signal, SIGTERM);
    uv_timer_init(&r->loop, &r->grace);
    r->grace.data = r;
}

/* Where local workers dial: the farm's address, with a wildcard listen
 * address replaced by loopback. */
static void set_connect_address(local_run *r) {
    const char *host = r->o->farm.host;
    if (strcmp(host, "0.0.0.0") == 0) host = "127.0.0.1";
    if (strcmp(host, "::") == 0) host = "::1";
    address_format(host, farm_port(r->f), r->connect, sizeof r->connect);
}

/* Spawn the workers and hand the farm its first job (or adaptive round);
 * any failure stops the render with r->err set. */
static void start_render(local_run *r, int adaptive_ok) {
    const local_farm_options *o = r->o;
    if (o->forked) adopt_forked(r);
    else
        for (int i = 0; i < o->workers; i++) spawn_worker(r, i);
    const char *why = NULL;
    if (o->workers > 0 && r->alive == 0 && !o->listening) why = "could not start any local worker";
    else if (!adaptive_ok) why = "out of memory for adaptive sampling";
    else if (r->ad) {
        r->round_id = r->job->id - 1;
        submit_round(r);
    } else if (farm_submit(r->f, r->job, r->bundle, r->bundle_len,
                           &(farm_job_options){.tile_size = o->tile_size}, r->rgb, on_job, r))
        why = "out of memory for the job";
    if (why) {
        snprintf(r->err, sizeof r->err, "%s", why);
        r->failed = 1;
        render_stop(r);
    }
}

/* Fill the caller's report from the last farm report. */
static void report_fill(const local_run *r, local_farm_report *rep, double cpu0) {
    rep->stats = r->last.stats;
    rep->coordinator_cpu_s = cpu_seconds() - cpu0;
    rep->bytes_in = r->last.bytes_in;
    rep->bytes_out = r->last.bytes_out;
    rep->tiles = r->last.tiles_total;
    rep->duplicates = r->last.duplicates;
    rep->requeued = r->last.requeued;
    rep->backups = r->last.backups;
    rep->interrupted = r->interrupted;
}

/* Free r and everything it owns (the loop is already closed). */
static void run_free(local_run *r) {
    adaptive_free(r->ad);
    free(r->sums);
    free(r->mask);
    free(r->done);
    free(r->slots);
    free(r);
}

/* ---- the dashboard's view of this render (dashboard_source) ---- */

static void web_jobs(void *ctx, cJSON *arr) {
    local_run *r = ctx;
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    cJSON *o = cJSON_CreateObject();
    cJSON_AddNumberToObject(o, "id", r->job->id);
    cJSON_AddStringToObject(o, "name", "tessera render");
    cJSON_AddStringToObject(o, "state", r->failed ? "failed" : r->finished ? "done" : "running");
    cJSON_AddNumberToObject(o, "tiles_done", r->last.tiles_done);
    cJSON_AddNumberToObject(o, "tiles_total", r->last.tiles_total);
    cJSON_AddNumberToObject(o, "samples", (double)r->last.stats.samples);
    cJSON_AddNumberToObject(o, "priority", 0);
    cJSON_AddNumberToObject(o, "width", r->job->width);
    cJSON_AddNumberToObject(o, "height", r->job->height);
    cJSON_AddNumberToObject(o, "spp", r->job->spp);
    cJSON_AddNumberToObject(o, "submitted", r->wall_start);
    cJSON_AddNumberToObject(o, "started", r->wall_start);
    cJSON_AddNumberToObject(o, "finished", 0);
    cJSON_AddNumberToObject(o, "now", (double)ts.tv_sec + ts.tv_nsec / 1e9);
    cJSON_AddItemToArray(arr, o);
}

static int web_frame(void *ctx, uint32_t id, float **rgb, int *w, int *h) {
    local_run *r = ctx;
    if (id != r->job->id || r->ad) return -1; /* adaptive rounds fill rgb only at the end */
    *rgb = r->rgb;
    *w = r->job->width;
    *h = r->job->height;
    return 0;
}

int local_farm_render(const local_farm_options *o, const proto_job *job, const uint8_t *bundle, size_t bundle_len,
                      float *rgb, local_farm_report *rep, char *err, size_t err_len) {
    local_run *r = calloc(1, sizeof *r);
    if (!r || (o->workers > 0 && !(r->slots = calloc((size_t)o->workers, sizeof *r->slots)))) {
        free(r);
        release_forked(o);
        snprintf(err, err_len, "out of memory");
        return -1;
    }
    *r = (local_run){.slots = r->slots, .o = o, .job = job, .bundle = bundle, .bundle_len = bundle_len, .rgb = rgb};
    memset(rep, 0, sizeof *rep);
    if (o->workers > 0 && find_worker_exe(r->exe, sizeof r->exe, err, err_len)) {
        release_forked(o);
        run_free(r);
        return -1;
    }
    double cpu0 = cpu_seconds();
    uv_loop_init(&r->loop);
    if (!(r->f = farm_new(&r->loop, &o->farm, err, err_len))) {
        release_forked(o);
        uv_loop_close(&r->loop);
        run_free(r);
        return -1;
    }
    set_connect_address(r);
    if (o->http) {
        dashboard_options wo = *o->http;
        wo.auth = &o->farm.auth;
        dashboard_source src = {.jobs = web_jobs, .frame = web_frame, .ctx = r};
        struct timespec ts;
        clock_gettime(CLOCK_REALTIME, &ts);
        r->wall_start = (double)ts.tv_sec + ts.tv_nsec / 1e9;
        if (!(r->web = dashboard_new(&r->loop, r->f, &wo, &src, err, err_len))) {
            release_forked(o);
            farm_close(r->f, on_farm_closed, r);
            uv_run(&r->loop, UV_RUN_DEFAULT);
            farm_free(r->f);
            uv_loop_close(&r->loop);
            run_free(r);
            return -1;
        }
        char where[300];
        address_format(wo.host ? wo.host : "127.0.0.1", dashboard_port(r->web), where, sizeof where);
        fprintf(stderr, "tessera: watch the render at %s://%s/job/%u\n", dashboard_scheme(r->web), where, r->job->id);
        fflush(stderr);
    }
    if (o->listening) {
        char where[300];
        address_format(o->farm.host, farm_port(r->f), where, sizeof where);
        fprintf(stderr, "tessera: coordinator listening on %s\n", where);
        fflush(stderr);
    }
    r->start = (double)uv_hrtime() / 1e9;
    r->total_samples = (uint64_t)job->width * (uint64_t)job->height * (uint64_t)job->spp;
    int adaptive_ok = adaptive_setup(r) == 0;
    handles_init(r);
    start_render(r, adaptive_ok);
    uv_run(&r->loop, UV_RUN_DEFAULT);
    if (o->verbose) farm_print_workers(r->f, stderr);
    farm_free(r->f);
    int rc = uv_loop_close(&r->loop);
    if (rc) fprintf(stderr, "tessera: event loop closed with handles open: %s\n", uv_strerror(rc));
    report_fill(r, rep, cpu0);
    int failed = r->failed;
    if (failed) snprintf(err, err_len, "%s", r->err);
    run_free(r);
    return failed ? -1 : 0;
}
