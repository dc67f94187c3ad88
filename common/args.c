/* args.c - table-driven options and checked numbers (see args.h). */
#include "args.h"

#include <errno.h>
#include <stdio.h>
#include <stdarg.h>
#include <stdlib.h>
#include <string.h>

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

void args_usage_error(const char *prog, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    fprintf(stderr, "%s: ", prog);
    vfprintf(stderr, fmt, ap);
    va_end(ap);
    fprintf(stderr, "\nsee %s --help\n", prog);
    exit(2);
}

/* Levenshtein distance of a and b, capped at 3 (all the caller needs). */
static int edits(const char *a, const char *b) {
    size_t la = strlen(a), lb = strlen(b);
    if (la > 64 || lb > 64) return 3;
    int row[65];
    for (size_t j = 0; j <= lb; j++) row[j] = (int)j;
    for (size_t i = 1; i <= la; i++) {
        int diag = row[0];
        row[0] = (int)i;
        for (size_t j = 1; j <= lb; j++) {
            int up = row[j], best = diag + (a[i - 1] != b[j - 1]);
            if (up + 1 < best) best = up + 1;
            if (row[j - 1] + 1 < best) best = row[j - 1] + 1;
            diag = up;
            row[j] = best;
        }
    }
    return row[lb] < 3 ? row[lb] : 3;
}

const char *args_closest(const char *word, const char *const *names) {
    const char *best = NULL;
    int best_d = 3;
    for (int i = 0; names[i]; i++) {
        int d = edits(word, names[i]);
        if (d < best_d) best_d = d, best = names[i];
    }
    return best;
}

/* The spec named by a long name (len bytes of it) or a short letter. */
static const arg_spec *find_spec(const arg_spec *specs, const char *name, size_t len, char letter) {
    for (const arg_spec *s = specs; s->name; s++)
        if (letter ? s->short_name == letter : strlen(s->name) == len && strncmp(s->name, name, len) == 0)
            return s;
    return NULL;
}

/* "unknown option --x" with the nearest name, then exit(2). */
static void unknown_option(const char *prog, const arg_spec *specs, const char *arg, size_t len) {
    const char *names[256];
    char want[128];
    int n = 0;
    for (const arg_spec *s = specs; s->name && n < 255; s++) names[n++] = s->name;
    names[n++] = "help";
    names[n] = NULL;
    snprintf(want, sizeof want, "%.*s", (int)(len < 100 ? len : 100), arg);
    const char *near = args_closest(want, names);
    if (near) args_usage_error(prog, "unknown option --%s (did you mean --%s?)", want, near);
    args_usage_error(prog, "unknown option --%s", want);
}

/* Store value into s's destination, or exit(2) naming --name. */
static void store(const char *prog, const arg_spec *s, const char *value) {
    char opt[80], err[300] = "";
    snprintf(opt, sizeof opt, "--%s", s->name);
    char *end;
    switch (s->kind) {
    case ARG_FLAG: *(int *)s->dest = 1; break;
    case ARG_INT: *(int *)s->dest = (int)args_long(prog, opt, value, (long)s->lo, (long)s->hi); break;
    case ARG_LONG: *(long *)s->dest = args_long(prog, opt, value, (long)s->lo, (long)s->hi); break;
    case ARG_DOUBLE: *(double *)s->dest = args_double(prog, opt, value, s->lo, s->hi); break;
    case ARG_FLOAT: *(float *)s->dest = (float)args_double(prog, opt, value, s->lo, s->hi); break;
    case ARG_STRING: *(const char **)s->dest = value; break;
    case ARG_U64:
        errno = 0;
        *(uint64_t *)s->dest = strtoull(value, &end, 10);
        if (errno || end == value || *end || value[0] == '-' || value[0] == '+' || value[0] == ' ')
            args_usage_error(prog, "%s: expected an integer from 0 to 18446744073709551615, got \"%s\"", opt, value);
        break;
    case ARG_CHOICE:
        for (int i = 0; s->choices[i]; i++)
            if (strcmp(value, s->choices[i]) == 0) {
                *(int *)s->dest = i;
                goto done;
            }
        for (int i = 0; s->choices[i]; i++) {
            size_t l = strlen(err);
            snprintf(err + l, sizeof err - l, "%s%s", i ? ", " : "", s->choices[i]);
        }
        args_usage_error(prog, "%s: unknown \"%s\" (known: %s)", opt, value, err);
    case ARG_CUSTOM:
        if (s->parse(value, s->dest, err, sizeof err)) args_usage_error(prog, "%s: %s", opt, err);
        break;
    }
done:
    if (s->given) *s->given = 1;
}

int args_parse(const char *prog, int argc, char **argv, const arg_spec *specs, void (*help)(FILE *out),
               const char **positional, int max_positional) {
    int n = 0, options = 1;
    for (const arg_spec *s = specs; s->name; s++) /* a table naming an option twice is a bug */
        for (const arg_spec *t = s + 1; t->name; t++)
            if (strcmp(s->name, t->name) == 0 || (s->short_name && s->short_name == t->short_name)) {
                fprintf(stderr, "%s: internal error: option --%s is in the table twice\n", prog, s->name);
                abort();
            }
    for (int i = 1; i < argc; i++) {
        const char *a = argv[i], *value = NULL;
        const arg_spec *s;
        if (!options || a[0] != '-' || a[1] == '\0') { /* "-" is a positional: stdin */
            if (n == max_positional) args_usage_error(prog, "unexpected argument \"%s\"", a);
            positional[n++] = a;
            continue;
        }
        if (strcmp(a, "--") == 0) {
            options = 0;
            continue;
        }
        if (strcmp(a, "-h") == 0 || strcmp(a, "--help") == 0) {
            help(stdout);
            exit(0);
        }
        if (a[1] == '-') {
            const char *eq = strchr(a + 2, '=');
            size_t len = eq ? (size_t)(eq - (a + 2)) : strlen(a + 2);
            if (!(s = find_spec(specs, a + 2, len, 0))) unknown_option(prog, specs, a + 2, len);
            if (eq) value = eq + 1;
        } else {
            if (!(s = find_spec(specs, NULL, 0, a[1]))) args_usage_error(prog, "unknown option %s", a);
            if (a[2]) value = a + 2;
        }
        if (s->kind == ARG_FLAG) {
            if (value) args_usage_error(prog, "--%s takes no value", s->name);
        } else if (!value) {
            if (i + 1 >= argc) args_usage_error(prog, "--%s needs a value", s->name);
            value = argv[++i];
        }
        store(prog, s, value);
    }
    return n;
}
