/* harness.c - test registry and runner; `run-tests [--filter SUBSTRING]`. */
#include "harness.h"

#include <stdarg.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

/* Registration runs before main (constructors); a test past the table
 * would otherwise be dropped without a word, so that is a fatal error. */
#define MAX_TESTS 1024

static struct {
    const char *name;
    test_fn fn;
} tests[MAX_TESTS];
static int test_count, current_failures;

void harness_register(const char *name, test_fn fn) {
    if (test_count == MAX_TESTS) {
        fprintf(stderr, "run-tests: more than %d tests (%s is one too many): raise MAX_TESTS in tests/harness.c\n",
                MAX_TESTS, name);
        exit(2);
    }
    tests[test_count].name = name;
    tests[test_count].fn = fn;
    test_count++;
}

void harness_fail(const char *file, int line, const char *fmt, ...) {
    va_list ap;
    fprintf(stderr, "    %s:%d: ", file, line);
    va_start(ap, fmt);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fputc('\n', stderr);
    current_failures++;
}

const char *harness_tessera(void) {
    const char *p = getenv("TESSERA_BIN");
    return p ? p : "build/release/bin/tessera";
}

double harness_slack(void) {
    const char *b = harness_tessera();
    return strstr(b, "/asan/") || strstr(b, "/tsan/") ? 10.0 : 1.0;
}

int main(int argc, char **argv) {
    const char *filter = (argc == 3 && strcmp(argv[1], "--filter") == 0) ? argv[2] : NULL;
    int passed = 0, failed = 0;
    for (int i = 0; i < test_count; i++) {
        if (filter && !strstr(tests[i].name, filter)) continue;
        struct timespec t0, t1;
        clock_gettime(CLOCK_MONOTONIC, &t0);
        current_failures = 0;
        tests[i].fn();
        clock_gettime(CLOCK_MONOTONIC, &t1);
        double s = (double)(t1.tv_sec - t0.tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0.tv_nsec);
        printf("%s %s (%.2fs)\n", current_failures ? "FAIL" : "ok  ", tests[i].name, s);
        fflush(stdout);
        if (current_failures) failed++;
        else passed++;
    }
    printf("%d passed, %d failed\n", passed, failed);
    return failed ? 1 : 0;
}
