/* cli_util.c - progress bar and default file names for the CLI. */
#include "cli_util.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>
#include <unistd.h>

void cli_progress(int done, int total, double samples_per_s, int workers, double eta_s, int final) {
    enum { WIDTH = 30 };
    int filled = total > 0 ? done * WIDTH / total : 0;
    char bar[WIDTH + 1], who[32] = "";
    for (int i = 0; i < WIDTH; i++) bar[i] = i < filled ? '#' : '.';
    bar[WIDTH] = '\0';
    if (workers >= 0) snprintf(who, sizeof who, "  %d worker%s", workers, workers == 1 ? "" : "s");
    fprintf(stderr, "\r[%s] %d/%d tiles  %.2f Msamples/s%s  ETA %.0fs   ", bar, done, total, samples_per_s / 1e6, who,
            eta_s);
    if (final) fputc('\n', stderr);
    fflush(stderr);
}

static double mono_seconds(void) {
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + 1e-9 * (double)ts.tv_nsec;
}

void cli_progress_init(cli_progress_state *p) {
    const char *env = getenv("TESSERA_PROGRESS_SECONDS");
    double every = env && *env ? atof(env) : 0;
    p->tty = isatty(STDERR_FILENO);
    p->every = every > 0 ? every : 5;
    p->last = mono_seconds();
}

void cli_progress_show(cli_progress_state *p, int done, int total, double samples_per_s, int workers, double eta_s,
                       int final) {
    if (p->tty) return cli_progress(done, total, samples_per_s, workers, eta_s, final);
    double now = mono_seconds();
    if (!final && now - p->last < p->every) return;
    p->last = now;
    char who[32] = "";
    if (workers >= 0) snprintf(who, sizeof who, ", %d worker%s", workers, workers == 1 ? "" : "s");
    fprintf(stderr, "progress: %d/%d tiles (%d%%), %.2f Msamples/s%s, ETA %.0fs\n", done, total,
            total > 0 ? (int)(100.0 * done / total) : 0, samples_per_s / 1e6, who, eta_s);
    fflush(stderr);
}

void cli_default_output(const char *scene_path, char *out, size_t n) {
    if (strcmp(scene_path, "-") == 0) scene_path = "stdin";
    const char *base = strrchr(scene_path, '/');
    base = base ? base + 1 : scene_path;
    const char *dot = strrchr(base, '.');
    snprintf(out, n, "%.*s.png", dot ? (int)(dot - base) : (int)strlen(base), base);
}

void cli_note_terminal_scene(const char *scene_path) {
    if (strcmp(scene_path, "-") == 0 && isatty(STDIN_FILENO))
        fprintf(stderr, "tessera: reading the scene from the terminal; end it with Ctrl-D\n");
}
