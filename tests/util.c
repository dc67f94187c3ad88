/* util.c - helpers shared by the tests. */
#include "util.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/wait.h>

const char *util_write_temp(const char *name, const char *text) {
    static char dir[64], path[256];
    if (!dir[0]) {
        snprintf(dir, sizeof dir, "/tmp/tessera-test-XXXXXX");
        if (!mkdtemp(dir)) return NULL;
    }
    snprintf(path, sizeof path, "%s/%s", dir, name);
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
