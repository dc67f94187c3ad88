/* cli_util.c - progress bar and default file names for the CLI. */
#include "cli_util.h"

#include <stdio.h>
#include <string.h>

void cli_progress(int done, int total, double samples_per_s, int workers, double eta_s, int final) {
    enum { WIDTH = 30 };
    int filled = total > 0 ? done * WIDTH / total : 0;
    char bar[WIDTH + 1], who[32] = "";
    for (int i = 0; i < WIDTH; i++) bar[i] = i < filled ? '#' : '.';
    bar[WIDTH] = '\0';
    if (workers >= 0) snprintf(who, sizeof who, "  %d workers", workers);
    fprintf(stderr, "\r[%s] %d/%d tiles  %.2f Msamples/s%s  ETA %.0fs   ", bar, done, total, samples_per_s / 1e6, who,
            eta_s);
    if (final) fputc('\n', stderr);
    fflush(stderr);
}

void cli_default_output(const char *scene_path, char *out, size_t n) {
    const char *base = strrchr(scene_path, '/');
    base = base ? base + 1 : scene_path;
    const char *dot = strrchr(base, '.');
    snprintf(out, n, "%.*s.png", dot ? (int)(dot - base) : (int)strlen(base), base);
}
