/* membudget.c - memory budgets and sizes (membudget.h). */
#include "membudget.h"

#include <ctype.h>
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <strings.h>
#include <unistd.h>

/* The number in a one-line file (a cgroup limit), or 0 when missing or
 * "max". */
static uint64_t read_limit(const char *path) {
    FILE *f = fopen(path, "r");
    char buf[64] = "";
    if (!f) return 0;
    if (!fgets(buf, sizeof buf, f)) buf[0] = 0;
    fclose(f);
    if (!isdigit((unsigned char)buf[0])) return 0;
    unsigned long long v = strtoull(buf, NULL, 10);
    return v >= (1ull << 60) ? 0 : (uint64_t)v; /* v1's "no limit" is a huge number */
}

uint64_t membudget_default(char *how, size_t how_len) {
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    uint64_t ram = pages > 0 && page > 0 ? (uint64_t)pages * (uint64_t)page : 0;
    uint64_t cg = read_limit("/sys/fs/cgroup/memory.max");
    if (!cg) cg = read_limit("/sys/fs/cgroup/memory/memory.limit_in_bytes");
    uint64_t base = ram;
    const char *what = "RAM";
    if (cg && (!ram || cg < ram)) {
        base = cg;
        what = "the cgroup's memory limit";
    }
    if (!base) {
        snprintf(how, how_len, "1 GiB: neither RAM nor a cgroup limit could be read");
        return (uint64_t)1 << 30;
    }
    char b[32];
    membudget_format(base, b, sizeof b);
    snprintf(how, how_len, "3/4 of %s of %s", b, what);
    return base / 4 * 3;
}

uint64_t membudget_job_bytes(int width, int height, int tiles, uint64_t scene_bytes) {
    return 2 * (uint64_t)width * (uint64_t)height * 3 * sizeof(float) + (uint64_t)tiles * MEMBUDGET_TILE_BYTES +
           scene_bytes;
}

void membudget_format(uint64_t bytes, char *out, size_t len) {
    static const char *const units[] = {"KiB", "MiB", "GiB", "TiB"};
    if (bytes < 1024) {
        snprintf(out, len, "%llu bytes", (unsigned long long)bytes);
        return;
    }
    double v = (double)bytes / 1024.0;
    int u = 0;
    while (v >= 1024.0 && u < 3) {
        v /= 1024.0;
        u++;
    }
    snprintf(out, len, "%.1f %s", v, units[u]);
}

int membudget_parse(const char *value, void *dest, char *err, size_t err_len) {
    char *end;
    double v = strtod(value, &end);
    double unit = 1048576.0;
    if (*end) {
        static const char units[] = "KMGT";
        const char *u = strchr(units, toupper((unsigned char)*end)), *rest = end + 1;
        if (!u || (*rest && strcasecmp(rest, "B") != 0 && strcasecmp(rest, "iB") != 0)) {
            snprintf(err, err_len, "expected a size such as 12G, 512M or 2048 (MiB), got \"%.40s\"", value);
            return -1;
        }
        unit = ldexp(1.0, 10 * (int)(u - units + 1));
    }
    double bytes = v * unit;
    if (end == value || !isfinite(v) || bytes < 1048576.0 || bytes > ldexp(1.0, 60)) {
        snprintf(err, err_len, "expected a size from 1M to 1024P such as 12G, got \"%.40s\"", value);
        return -1;
    }
    *(uint64_t *)dest = (uint64_t)bytes;
    return 0;
}
