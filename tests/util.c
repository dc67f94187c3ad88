/* util.c - helpers shared by the tests. */
#include "util.h"

#include "harness.h"
#include "render/shading_normal.h"

#include <arpa/inet.h>
#include <fcntl.h>
#include <netinet/in.h>
#include <signal.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/socket.h>
#include <sys/stat.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>

const char *util_temp_path(const char *name) {
    static char dir[64], path[256];
    if (!dir[0]) {
        snprintf(dir, sizeof dir, "/tmp/tessera-test-XXXXXX");
        if (!mkdtemp(dir)) return NULL;
    }
    snprintf(path, sizeof path, "%s/%s", dir, name);
    return path;
}

const char *util_write_temp(const char *name, const char *text) {
    const char *path = util_temp_path(name);
    if (!path) return NULL;
    FILE *f = fopen(path, "w");
    if (!f) return NULL;
    fputs(text, f);
    fclose(f);
    return path;
}

scene *util_scene_from_text(const char *json, char *err, size_t err_len) {
    const char *p = util_write_temp("scene.json", json);
    return p ? scene_load(p, NULL, err, err_len) : NULL;
}

float *util_render(const scene *s, int threads, int tile, int passes, trace_stats *st) {
    float *rgb = malloc(sizeof(float) * 3 * (size_t)s->settings.width * (size_t)s->settings.height);
    render_options ro = {.threads = threads, .tile_size = tile, .passes = passes};
    if (rgb && render_frame(s, &ro, rgb, st) != 0) {
        free(rgb);
        return NULL;
    }
    return rgb;
}

int util_run(const char *cmd, char *out, size_t cap) {
    char full[4096];
    snprintf(full, sizeof full, "%s 2>&1", cmd);
    FILE *p = popen(full, "r");
    if (!p) return -1;
    size_t n = fread(out, 1, cap - 1, p);
    out[n] = '\0';
    int st = pclose(p);
    return WIFEXITED(st) ? WEXITSTATUS(st) : -1;
}

int util_cli(const char *addr, char *out, size_t cap, const char *args) {
    char cmd[4096];
    snprintf(cmd, sizeof cmd, "TESSERA_COORDINATOR=%s %s %s", addr, harness_tessera(), args);
    return util_run(cmd, out, cap);
}

const char *util_bin(const char *name) {
    static char path[4096];
    const char *t = getenv("TESSERA_BIN");
    if (!t) t = "build/release/bin/tessera";
    const char *slash = strrchr(t, '/');
    int dir = slash ? (int)(slash - t) : 1;
    snprintf(path, sizeof path, "%.*s/%s", dir, slash ? t : ".", name);
    return path;
}

pid_t util_spawn(const char *const *argv, const char *log_path) { return util_spawn_env(argv, log_path, NULL); }

pid_t util_spawn_env(const char *const *argv, const char *log_path, const char *const *env) {
    fflush(NULL);
    pid_t pid = fork();
    if (pid != 0) return pid;
    for (int i = 0; env && env[i]; i++) putenv((char *)env[i]);
    int in = open("/dev/null", O_RDONLY);
    int out = open(log_path, O_WRONLY | O_CREAT | O_APPEND, 0644);
    if (in < 0 || out < 0) _exit(127);
    dup2(in, 0);
    dup2(out, 1);
    dup2(out, 2);
    execv(argv[0], (char *const *)argv);
    _exit(127);
}

int util_touch(const char *path) {
    FILE *f = fopen(path, "w");
    return f && fclose(f) == 0 ? 0 : -1;
}

void util_sleep(double s) {
    struct timespec ts = {(time_t)s, (long)((s - (double)(time_t)s) * 1e9)};
    nanosleep(&ts, NULL);
}

double util_now(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

int util_wait(pid_t pid, double timeout_s, long *maxrss_kb) {
    double end = util_now() + timeout_s;
    int st;
    struct rusage ru;
    for (;;) {
        pid_t r = wait4(pid, &st, WNOHANG, &ru);
        if (r == pid) break;
        if (r < 0) return -1;
        if (util_now() > end) {
            kill(pid, SIGKILL);
            waitpid(pid, &st, 0);
            return -1;
        }
        util_sleep(0.01);
    }
    if (maxrss_kb) *maxrss_kb = ru.ru_maxrss;
    return WIFEXITED(st) ? WEXITSTATUS(st) : 128 + WTERMSIG(st);
}

int util_file_count(const char *path, const char *text) {
    FILE *f = fopen(path, "rb");
    if (!f) return 0;
    static char buf[1 << 20];
    size_t n = fread(buf, 1, sizeof buf - 1, f);
    fclose(f);
    buf[n] = '\0';
    int count = 0;
    for (const char *p = buf; (p = strstr(p, text)) != NULL; p += strlen(text)) count++;
    return count;
}

int util_wait_for_text(const char *path, const char *text, double timeout_s) {
    double end = util_now() + timeout_s;
    while (!util_file_count(path, text)) {
        if (util_now() > end) return -1;
        util_sleep(0.01);
    }
    return 0;
}

/* Ports are handed out below the kernel's ephemeral range (read from
 * /proc; 32768 up by default), each at most once per run: a port found
 * free by binding to 0 there could be taken before the test's server
 * bound it, by the next call (the same number again) or by any outgoing
 * connection's source port (2026-12-03: a coordinator failed with
 * "address already in use" in make test). Start offset by the pid, so two
 * runs at once rarely probe the same ports. */
int util_free_port(void) {
    static int next;
    int lo = 32768;
    FILE *f = fopen("/proc/sys/net/ipv4/ip_local_port_range", "r");
    if (f) {
        if (fscanf(f, "%d", &lo) != 1) lo = 32768;
        fclose(f);
    }
    int first = lo > 12000 ? lo - 10000 : 1024, span = lo - first;
    if (!next) next = first + (int)(getpid() % (span / 2));
    for (int tries = 0; tries < span; tries++) {
        int port = next++;
        if (next >= lo) next = first;
        int fd = socket(AF_INET, SOCK_STREAM, 0);
        struct sockaddr_in a = {.sin_family = AF_INET, .sin_port = htons((uint16_t)port),
                                .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
        int ok = fd >= 0 && bind(fd, (struct sockaddr *)&a, sizeof a) == 0;
        if (fd >= 0) close(fd);
        if (ok) return port;
    }
    return -1;
}

int util_listen_loopback(int backlog, int *port) {
    int fd = socket(AF_INET, SOCK_STREAM, 0);
    struct sockaddr_in a = {.sin_family = AF_INET, .sin_addr.s_addr = htonl(INADDR_LOOPBACK)};
    socklen_t len = sizeof a;
    if (fd < 0 || bind(fd, (struct sockaddr *)&a, sizeof a) != 0 || listen(fd, backlog) != 0 ||
        getsockname(fd, (struct sockaddr *)&a, &len) != 0) {
        if (fd >= 0) close(fd);
        return -1;
    }
    *port = ntohs(a.sin_port);
    return fd;
}

int util_same_file(const char *a, const char *b) {
    FILE *fa = fopen(a, "rb"), *fb = fopen(b, "rb");
    int same = fa && fb;
    while (same) {
        int ca = fgetc(fa), cb = fgetc(fb);
        if (ca != cb) same = 0;
        if (ca == EOF || cb == EOF) break;
    }
    if (fa) fclose(fa);
    if (fb) fclose(fb);
    return same;
}

int util_have_qemu(void) {
    struct stat sb;
    if (stat("/usr/bin/qemu-x86_64", &sb) == 0) return 1;
    if (getenv("TESSERA_TESTS_WITHOUT_QEMU"))
        fprintf(stderr, "  (skipped: no /usr/bin/qemu-x86_64, and TESSERA_TESTS_WITHOUT_QEMU is set)\n");
    else
        harness_fail(__FILE__, __LINE__, "no /usr/bin/qemu-x86_64 (Debian's qemu-user, which make installs) "
                                         "to run the build as a Nehalem");
    return 0;
}

int util_same_under_nehalem(const char *tessera, const char *args, const char *tag, char *out, size_t cap) {
    char name[128], native[512], emulated[512], cmd[4096];
    snprintf(name, sizeof name, "%s-native.pfm", tag);
    snprintf(native, sizeof native, "%s", util_temp_path(name));
    snprintf(name, sizeof name, "%s-nehalem.pfm", tag);
    snprintf(emulated, sizeof emulated, "%s", util_temp_path(name));
    snprintf(cmd, sizeof cmd, "%s %s -o %s", tessera, args, native);
    if (util_run(cmd, out, cap) != 0) return -1;
    snprintf(cmd, sizeof cmd, "/usr/bin/qemu-x86_64 -cpu Nehalem-v1 %s %s -o %s", tessera, args, emulated);
    int rc = util_run(cmd, out, cap);
    if (rc != 0) return -1;
    if (util_same_file(native, emulated)) return 0;
    snprintf(out, cap, "%s under qemu (Nehalem) differs from the native image %s", emulated, native);
    return -1;
}

void util_resume_counts(const char *log, int *resumed, int *from_journal, int *rendered) {
    *resumed = *from_journal = *rendered = -1;
    FILE *f = fopen(log, "r");
    char line[512];
    while (f && fgets(line, sizeof line, f)) {
        const char *msg = strstr(line, "job 1 ");
        if (!msg) continue;
        sscanf(msg, "job 1 resumed: %d of 64", resumed);
        sscanf(msg, "job 1 done (%d tiles from the journal, %d rendered", from_journal, rendered);
    }
    if (f) fclose(f);
}

int util_corner_normal(const scene *s, uint32_t prim, int k, vec3 *out) {
    const vec3 *c = shading_corner_normals(s, prim);
    if (!c || (vec3_is_zero(c[0]) && vec3_is_zero(c[1]) && vec3_is_zero(c[2]))) return 0;
    *out = c[k];
    return 1;
}

size_t util_smooth_triangles(const scene *s) {
    size_t n = 0;
    vec3 v;
    for (uint32_t t = 0; t < s->triangle_count; t++) n += util_corner_normal(s, t, 0, &v);
    return n;
}

static int cmp_vec3_bits(const void *a, const void *b) { return memcmp(a, b, sizeof(vec3)); }

size_t util_distinct_corner_normals(const scene *s) {
    size_t n = 0, cap = 3 * (size_t)s->triangle_count;
    vec3 *all = malloc((cap ? cap : 1) * sizeof *all);
    if (!all) return 0;
    for (uint32_t t = 0; t < s->triangle_count; t++)
        for (int k = 0; k < 3; k++)
            if (util_corner_normal(s, t, k, &all[n])) n++;
    qsort(all, n, sizeof *all, cmp_vec3_bits);
    size_t distinct = 0;
    for (size_t i = 0; i < n; i++) distinct += i == 0 || memcmp(&all[i], &all[i - 1], sizeof *all) != 0;
    free(all);
    return distinct;
}
