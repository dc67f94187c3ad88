/* local_fork.c - local workers forked over the loaded scene (see
 * local_fork.h). */
#define _GNU_SOURCE
#include "local_fork.h"

#include <errno.h>
#include <fcntl.h>
#include <signal.h>
#include <stdio.h>
#include <string.h>
#include <sys/socket.h>
#include <unistd.h>

#include "net/address.h"
#include "worker/worker.h"

/* The child's start: a session of its own (a Ctrl-C at the terminal
 * reaches only the coordinator, which stops it, as for spawned workers),
 * default signal handling, stdin and stdout on /dev/null, and no file
 * descriptor of the parent's but stderr and its own fd, which becomes 3. */
static void child_detach(int fd) {
    setsid();
    const int reset[] = {SIGINT, SIGTERM, SIGHUP, SIGQUIT, SIGCHLD, SIGUSR1, SIGUSR2};
    for (size_t i = 0; i < sizeof reset / sizeof *reset; i++) signal(reset[i], SIG_DFL);
    signal(SIGPIPE, SIG_IGN); /* as tessera-worker: a vanished coordinator is an error to handle */
    sigset_t all;
    sigemptyset(&all);
    sigprocmask(SIG_SETMASK, &all, NULL);
    int null = open("/dev/null", O_RDWR);
    if (null >= 0) {
        dup2(null, STDIN_FILENO);
        dup2(null, STDOUT_FILENO);
        if (null > STDERR_FILENO) close(null);
    }
    if (fd != 3) dup2(fd, 3);
    close_range(4, ~0U, 0);
}

/* The address the farm sends, up to end of file; "" when it sent none. */
static void child_read_address(char *out, size_t cap) {
    size_t len = 0;
    for (;;) {
        ssize_t n = read(3, out + len, cap - 1 - len);
        if (n < 0 && errno == EINTR) continue;
        if (n <= 0 || (len += (size_t)n) == cap - 1) break;
    }
    out[len] = '\0';
    close(3);
}

/* The forked worker: wait for the address, then be tessera-worker with the
 * scene in hand. Never returns. */
static void child_run(const local_fork_options *o, int slot, scene *s, const char *hash, int fd) {
    child_detach(fd);
    char where[300], host[256], name[32], err[300];
    child_read_address(where, sizeof where);
    if (!where[0]) _exit(0); /* released: the render ended before it began */
    worker_config cfg = worker_config_default(); /* as a spawned tessera-worker --once would run */
    cfg.threads = o->threads, cfg.once = 1, cfg.verbose = o->verbose, cfg.quiet = o->quiet;
    cfg.preload_scene = s, cfg.preload_hash = hash;
    if (address_parse(where, host, sizeof host, &cfg.port, err, sizeof err)) {
        fprintf(stderr, "tessera-worker local-%d: the farm's address %s: %s\n", slot, where, err);
        _exit(2);
    }
    cfg.host = host;
    snprintf(name, sizeof name, "local-%d", slot);
    cfg.name = name;
    if (o->token_file && auth_key_load(o->token_file, &cfg.auth, err, sizeof err)) {
        fprintf(stderr, "tessera-worker local-%d: %s\n", slot, err);
        _exit(2);
    }
    /* _exit: the parent's exit handlers (and any library's) are not ours to run. */
    _exit(worker_run(&cfg));
}

int local_fork_workers(const local_fork_options *o, scene *s, const char *hash, local_farm_forked *out, char *err,
                       size_t err_len) {
    fflush(NULL); /* nothing buffered twice */
    for (int i = 0; i < o->workers; i++) {
        int sv[2];
        if (socketpair(AF_UNIX, SOCK_STREAM | SOCK_CLOEXEC, 0, sv) != 0) {
            snprintf(err, err_len, "cannot start local worker local-%d: socketpair: %s", i, strerror(errno));
            local_farm_release_forked(out, i);
            return -1;
        }
        pid_t pid = fork();
        if (pid < 0) {
            snprintf(err, err_len, "cannot start local worker local-%d: fork: %s", i, strerror(errno));
            close(sv[0]);
            close(sv[1]);
            local_farm_release_forked(out, i);
            return -1;
        }
        if (pid == 0) child_run(o, i, s, hash, sv[1]);
        close(sv[1]);
        out[i] = (local_farm_forked){.pid = pid, .fd = sv[0]};
    }
    return 0;
}
