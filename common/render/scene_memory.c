/* scene_memory.c - the memory estimate of scene_memory.h: faces counted in
 * the OBJ text, instances counted in the scene text, available memory from
 * /proc/meminfo and the cgroup (v2) limit. */
#include "scene_memory.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

/* Triangles the `f` lines of an OBJ text make (corners - 2 each). */
static uint64_t count_obj_triangles(const char *s, size_t len) {
    uint64_t tris = 0;
    const char *end = s + len;
    while (s < end) {
        while (s < end && (*s == ' ' || *s == '\t')) s++;
        if (end - s > 1 && s[0] == 'f' && (s[1] == ' ' || s[1] == '\t')) {
            int corners = 0, in_token = 0;
            for (s += 1; s < end && *s != '\n' && *s != '#'; s++) {
                int blank = *s == ' ' || *s == '\t' || *s == '\r';
                if (!blank && !in_token) corners++;
                in_token = !blank;
            }
            if (corners > 2) tris += (uint64_t)corners - 2;
        }
        const char *nl = memchr(s, '\n', (size_t)(end - s));
        s = nl ? nl + 1 : end;
    }
    return tris;
}

/* How often the scene text names "name" (in quotes): the mesh's instances. */
static uint64_t count_uses(const char *scene_text, const char *name) {
    size_t n = strlen(name);
    uint64_t uses = 0;
    for (const char *p = scene_text; (p = strstr(p, name)) != NULL; p += n)
        if (p > scene_text && p[-1] == '"' && p[n] == '"') uses++;
    return uses ? uses : 1;
}

uint64_t scene_memory_estimate(const scene_bundle *b, uint64_t *triangles) {
    uint64_t bytes = 0, tris = 0;
    for (size_t i = 0; i < b->count; i++) {
        bytes += b->files[i].len;
        if (i == 0 || !b->files[i].data) continue;
        uint64_t uses = b->files[0].data ? count_uses(b->files[0].data, b->files[i].name) : 1;
        tris += uses * count_obj_triangles(b->files[i].data, b->files[i].len);
    }
    if (triangles) *triangles = tris;
    return bytes + tris * SCENE_MEMORY_BYTES_PER_TRIANGLE;
}

/* A number from a file holding one ("max" reads as UINT64_MAX). */
static uint64_t read_number_file(const char *path) {
    FILE *f = fopen(path, "r");
    if (!f) return UINT64_MAX;
    char buf[64] = "";
    uint64_t v = UINT64_MAX;
    if (fgets(buf, sizeof buf, f) && strncmp(buf, "max", 3) != 0) v = strtoull(buf, NULL, 10);
    fclose(f);
    return v;
}

uint64_t scene_memory_available(void) {
    const char *forced = getenv("TESSERA_MEMORY_AVAILABLE_MB");
    if (forced && *forced) return strtoull(forced, NULL, 10) << 20;
    uint64_t avail = UINT64_MAX;
    FILE *f = fopen("/proc/meminfo", "r");
    char line[256];
    while (f && fgets(line, sizeof line, f)) {
        unsigned long long kb;
        if (sscanf(line, "MemAvailable: %llu kB", &kb) == 1) avail = (uint64_t)kb << 10;
    }
    if (f) fclose(f);
    uint64_t max = read_number_file("/sys/fs/cgroup/memory.max"), cur = read_number_file("/sys/fs/cgroup/memory.current");
    if (max != UINT64_MAX && cur != UINT64_MAX) {
        uint64_t room = max > cur ? max - cur : 0;
        if (room < avail) avail = room;
    }
    return avail;
}

int scene_memory_check(const scene_bundle *b, char *err, size_t err_len) {
    uint64_t tris, need = scene_memory_estimate(b, &tris), have = scene_memory_available();
    if (have == UINT64_MAX || need <= have) return 0;
    snprintf(err, err_len,
             "%s: this worker cannot hold the scene: loading %llu triangles needs about %llu MiB, only %llu MiB "
             "available here",
             b->count ? b->files[0].name : "scene", (unsigned long long)tris, (unsigned long long)(need >> 20),
             (unsigned long long)(have >> 20));
    return -1;
}
