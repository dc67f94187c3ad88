/* test_connlimit.c - the coordinator's connection counts (coordinator/
 * connlimit.h) on their own: many addresses (the table grows and probe
 * runs collide), refusals per class and in total, and removal in any
 * order leaving every other count intact. */
#include <stdio.h>
#include <string.h>

#include "coordinator/connlimit.h"
#include "harness.h"

static void ip_of(int i, char *out, size_t n) { snprintf(out, n, "10.%d.%d.%d", i / 65536, (i / 256) % 256, i % 256); }

TEST(connlimit_counts_per_address_survive_growth_and_removal) {
    enum { ADDRS = 3000 };
    connlimit_caps caps = {.max_total = 0, .max_open = 3, .max_workers = 2};
    connlimit *l = connlimit_new(&caps);
    char ip[32], why[300];
    int admitted = 0, refused = 0;
    for (int i = 0; i < ADDRS; i++) {
        ip_of(i, ip, sizeof ip);
        for (int k = 0; k < 4; k++) {
            int rc = connlimit_admit(l, ip, why, sizeof why);
            admitted += rc == 0;
            refused += rc != 0 && strstr(why, ip) && strstr(why, "--max-per-address 3") && connlimit_last_kind(l) == 1;
        }
        CHECK(connlimit_promote(l, ip, why, sizeof why) == 0, "%s: first promote refused: %s", ip, why);
    }
    CHECK(admitted == 3 * ADDRS && refused == ADDRS, "%d admitted, %d refused naming the cap (want %d and %d)", admitted,
          refused, 3 * ADDRS, ADDRS);
    CHECK(connlimit_total(l) == 3 * ADDRS, "total %d (want %d)", connlimit_total(l), 3 * ADDRS);
    /* Release every other address whole, in a scrambled order: the rest keep their counts. */
    for (int j = 0; j < ADDRS; j++) {
        int i = (int)(((long)j * 7919) % ADDRS);
        if (i % 2) continue;
        ip_of(i, ip, sizeof ip);
        connlimit_release(l, ip, CONNLIMIT_WORKER);
        connlimit_release(l, ip, CONNLIMIT_OPEN);
        connlimit_release(l, ip, CONNLIMIT_OPEN);
    }
    int bad = 0;
    for (int i = 0; i < ADDRS; i++) {
        ip_of(i, ip, sizeof ip);
        /* Kept ones (2 open, 1 worker) take one more open and then refuse;
         * emptied ones take connections again. */
        int rc = connlimit_admit(l, ip, why, sizeof why);
        int rc2 = i % 2 ? connlimit_admit(l, ip, why, sizeof why) : -1;
        bad += rc != 0 || (i % 2 && rc2 == 0);
        if (rc == 0) connlimit_release(l, ip, CONNLIMIT_OPEN);
    }
    CHECK(bad == 0, "%d addresses lost or kept their counts wrongly after removals", bad);
    CHECK(connlimit_total(l) == 3 * (ADDRS / 2), "total %d after releasing half (want %d)", connlimit_total(l),
          3 * (ADDRS / 2));
    connlimit_free(l);
}

TEST(connlimit_total_and_worker_caps_refuse_naming_the_option) {
    connlimit_caps caps = {.max_total = 4, .max_open = 10, .max_workers = 1};
    connlimit *l = connlimit_new(&caps);
    char why[300];
    for (int i = 0; i < 4; i++) CHECK(connlimit_admit(l, "127.0.0.1", why, sizeof why) == 0, "admit %d: %s", i, why);
    CHECK(connlimit_admit(l, "127.0.0.2", why, sizeof why) != 0 && strstr(why, "--max-connections 4") &&
              connlimit_last_kind(l) == 0, "the total cap: %s", why);
    CHECK(connlimit_promote(l, "127.0.0.1", why, sizeof why) == 0, "first worker: %s", why);
    CHECK(connlimit_promote(l, "127.0.0.1", why, sizeof why) != 0 && strstr(why, "--max-workers-per-address 1") &&
              connlimit_last_kind(l) == 2, "the worker cap: %s", why);
    unsigned long more = 9;
    CHECK(connlimit_should_log(l, 0, 100.0, &more) == 1 && more == 0, "the first refusal is logged");
    CHECK(connlimit_should_log(l, 0, 101.0, &more) == 0 && connlimit_should_log(l, 0, 105.0, &more) == 0,
          "refusals within %.0f s are counted, not logged", CONNLIMIT_LOG_S);
    CHECK(connlimit_should_log(l, 0, 111.0, &more) == 1 && more == 2, "the next line counts the 2 unlogged (got %lu)",
          more);
    CHECK(connlimit_should_log(l, 1, 111.5, &more) == 1, "each cap has its own line");
    connlimit_free(l);
}
