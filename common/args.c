/* args.c - checked number options (see args.h). */
#include "args.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>

long args_long(const char *prog, const char *opt, const char *s, long lo, long hi) {
    char *end;
    errno = 0;
    long v = strtol(s, &end, 10);
    if (errno || end == s || *end || v < lo || v > hi) {
        fprintf(stderr, "%s: %s: expected an integer from %ld to %ld, got \"%s\"\n", prog, opt, lo, hi, s);
        exit(2);
    }
    return v;
}

double args_double(const char *prog, const char *opt, const char *s, double lo, double hi) {
    char *end;
    double v = strtod(s, &end);
    if (end == s || *end || !(v >= lo && v <= hi)) {
        fprintf(stderr, "%s: %s: expected a number from %g to %g, got \"%s\"\n", prog, opt, lo, hi, s);
        exit(2);
    }
    return v;
}
