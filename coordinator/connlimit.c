/* connlimit.c - connection caps per address and in total (connlimit.h):
 * counts in an open-addressing hash table keyed by the peer's address
 * (FNV-1a, linear probing, deletion by backward shift, doubled at 3/4
 * full), so an accept costs O(1) whatever the number of connections. */
#include "connlimit.h"

#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>

typedef struct {
    char ip[48]; /* "" when the slot is free */
    int open, workers;
} entry;

struct connlimit {
    connlimit_caps caps;
    entry *slots;
    size_t cap, used; /* cap a power of two */
    int total;
    int last_kind;
    double logged_at[3];
    unsigned long unlogged[3];
};

static uint64_t hash_ip(const char *s) {
    uint64_t h = 1469598103934665603ull;
    for (; *s; s++) h = (h ^ (uint8_t)*s) * 1099511628211ull;
    return h;
}

/* The slot of ip, or the free slot where it would go. */
static size_t find_slot(const connlimit *l, const char *ip) {
    size_t mask = l->cap - 1, i = (size_t)hash_ip(ip) & mask;
    while (l->slots[i].ip[0] && strcmp(l->slots[i].ip, ip) != 0) i = (i + 1) & mask;
    return i;
}

static int grow(connlimit *l) {
    entry *old = l->slots;
    size_t old_cap = l->cap;
    entry *s = calloc(old_cap * 2, sizeof *s);
    if (!s) return -1;
    l->slots = s;
    l->cap = old_cap * 2;
    for (size_t i = 0; i < old_cap; i++)
        if (old[i].ip[0]) l->slots[find_slot(l, old[i].ip)] = old[i];
    free(old);
    return 0;
}

connlimit *connlimit_new(const connlimit_caps *caps) {
    connlimit *l = calloc(1, sizeof *l);
    if (!l) return NULL;
    l->caps = *caps;
    l->cap = 64;
    l->slots = calloc(l->cap, sizeof *l->slots);
    if (!l->slots) {
        free(l);
        return NULL;
    }
    for (int k = 0; k < 3; k++) l->logged_at[k] = -1e9;
    return l;
}

void connlimit_free(connlimit *l) {
    if (!l) return;
    free(l->slots);
    free(l);
}

/* The entry of ip, made when missing; NULL when out of memory. */
static entry *entry_of(connlimit *l, const char *ip) {
    if ((l->used + 1) * 4 > l->cap * 3 && grow(l)) return NULL;
    entry *e = &l->slots[find_slot(l, ip)];
    if (!e->ip[0]) {
        snprintf(e->ip, sizeof e->ip, "%s", ip);
        l->used++;
    }
    return e;
}

/* Free the slot of e when it counts nothing, shifting later entries of its
 * probe run back so that every lookup still finds them. */
static void entry_drop_if_empty(connlimit *l, entry *e) {
    if (e->open > 0 || e->workers > 0) return;
    size_t mask = l->cap - 1, i = (size_t)(e - l->slots), j = i;
    l->slots[i].ip[0] = '\0';
    l->used--;
    for (;;) {
        j = (j + 1) & mask;
        if (!l->slots[j].ip[0]) return;
        size_t home = (size_t)hash_ip(l->slots[j].ip) & mask;
        /* j's entry may move to i when its home is not in (i, j] cyclically */
        if ((i <= j) ? (home <= i || home > j) : (home <= i && home > j)) {
            l->slots[i] = l->slots[j];
            l->slots[j].ip[0] = '\0';
            i = j;
        }
    }
}

int connlimit_admit(connlimit *l, const char *ip, char *why, size_t why_len) {
    if (l->caps.max_total > 0 && l->total >= l->caps.max_total) {
        l->last_kind = 0;
        snprintf(why, why_len, "the coordinator has %d connections open (--max-connections %d)", l->total,
                 l->caps.max_total);
        return -1;
    }
    entry *e = entry_of(l, ip);
    if (!e) {
        l->last_kind = 0;
        snprintf(why, why_len, "out of memory for connection counts");
        return -1;
    }
    if (l->caps.max_open > 0 && e->open >= l->caps.max_open) {
        l->last_kind = 1;
        snprintf(why, why_len, "%s has %d connections open before or without a worker hello (--max-per-address %d)",
                 ip, e->open, l->caps.max_open);
        entry_drop_if_empty(l, e);
        return -1;
    }
    e->open++;
    l->total++;
    return 0;
}

int connlimit_promote(connlimit *l, const char *ip, char *why, size_t why_len) {
    entry *e = &l->slots[find_slot(l, ip)];
    if (!e->ip[0]) return 0; /* not counted (cannot happen): nothing to move */
    if (l->caps.max_workers > 0 && e->workers >= l->caps.max_workers) {
        l->last_kind = 2;
        snprintf(why, why_len, "%s has %d worker%s connected (--max-workers-per-address %d)", ip, e->workers,
                 e->workers == 1 ? "" : "s", l->caps.max_workers);
        return -1;
    }
    e->open--;
    e->workers++;
    return 0;
}

void connlimit_release(connlimit *l, const char *ip, connlimit_class cls) {
    entry *e = &l->slots[find_slot(l, ip)];
    if (!e->ip[0]) return;
    if (cls == CONNLIMIT_WORKER && e->workers > 0) e->workers--;
    else if (cls == CONNLIMIT_OPEN && e->open > 0) e->open--;
    else return;
    l->total--;
    entry_drop_if_empty(l, e);
}

int connlimit_total(const connlimit *l) { return l->total; }

int connlimit_last_kind(const connlimit *l) { return l->last_kind; }

int connlimit_should_log(connlimit *l, int kind, double now, unsigned long *unlogged) {
    if (kind < 0 || kind > 2) kind = 0;
    if (now - l->logged_at[kind] < CONNLIMIT_LOG_S) {
        l->unlogged[kind]++;
        return 0;
    }
    *unlogged = l->unlogged[kind];
    l->unlogged[kind] = 0;
    l->logged_at[kind] = now;
    return 1;
}

long connlimit_defaults(connlimit_caps *caps, int reserve) {
    struct rlimit rl;
    long soft = 1024;
    if (getrlimit(RLIMIT_NOFILE, &rl) == 0) {
        rlim_t want = (rlim_t)(10000 + reserve);
        if (rl.rlim_cur != RLIM_INFINITY && rl.rlim_cur < want) {
            rlim_t to = rl.rlim_max == RLIM_INFINITY || rl.rlim_max > want ? want : rl.rlim_max;
            struct rlimit raised = {to, rl.rlim_max};
            if (to > rl.rlim_cur && setrlimit(RLIMIT_NOFILE, &raised) == 0) rl.rlim_cur = to;
        }
        soft = rl.rlim_cur == RLIM_INFINITY || rl.rlim_cur > 1000000 ? 1000000 : (long)rl.rlim_cur;
    }
    if (caps->max_total <= 0) {
        long t = soft - reserve;
        caps->max_total = (int)(t > 10000 ? 10000 : t < 16 ? 16 : t);
    }
    if (caps->max_open <= 0) {
        int o = caps->max_total / 8;
        caps->max_open = o < 16 ? 16 : o > 1024 ? 1024 : o;
    }
    if (caps->max_workers <= 0) caps->max_workers = caps->max_total / 2 > 1 ? caps->max_total / 2 : 1;
    return soft;
}

void connlimit_ip_of(const char *addr_port, char *out, size_t len) {
    const char *colon = strrchr(addr_port, ':');
    int n = colon ? (int)(colon - addr_port) : (int)strlen(addr_port);
    if (n >= 2 && addr_port[0] == '[' && addr_port[n - 1] == ']') { /* "[V6]:PORT" */
        addr_port++;
        n -= 2;
    }
    snprintf(out, len, "%.*s", n, addr_port);
}
