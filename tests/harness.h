/* harness.h - a minimal test runner: tests register themselves, CHECK
 * records failures with file and line, the runner prints one line per test
 * and a final "N passed, N failed". */
#ifndef TESSERA_TEST_HARNESS_H
#define TESSERA_TEST_HARNESS_H

#include <stdio.h>

typedef void (*test_fn)(void);
void harness_register(const char *name, test_fn fn);
void harness_fail(const char *file, int line, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

#define TEST(name)                                                                       \
    static void name(void);                                                              \
    __attribute__((constructor)) static void register_##name(void) { harness_register(#name, name); } \
    static void name(void)

#define CHECK(cond, ...)                                      \
    do {                                                      \
        if (!(cond)) harness_fail(__FILE__, __LINE__, __VA_ARGS__); \
    } while (0)

/* Path of the tessera binary under test ($TESSERA_BIN). */
const char *harness_tessera(void);

/* How much longer timing limits may be for the binary under test: 10 for
 * the sanitizer builds (a path under build/asan/ or build/tsan/), whose
 * CPU costs are several times the release build's, else 1. */
double harness_slack(void);

#endif
