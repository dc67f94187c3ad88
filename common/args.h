/* args.h - the command lines' options, described by a table and checked the
 * same way everywhere: a usage error is one line naming the program, the
 * option and what is wrong (with a "did you mean" for a near miss), then
 * "see PROG --help", and exits with status 2. */
#ifndef TESSERA_ARGS_H
#define TESSERA_ARGS_H

/* Parse s as an integer within [lo, hi]; on anything else print
 * "PROG: OPT: expected an integer from LO to HI, got "S"" and exit(2). */
long args_long(const char *prog, const char *opt, const char *s, long lo, long hi);

/* The same for a number within [lo, hi] (NaN is refused). */
double args_double(const char *prog, const char *opt, const char *s, double lo, double hi);

#include <stddef.h>
#include <stdint.h>
#include <stdio.h>

typedef enum {
    ARG_FLAG,   /* no value: *(int *)dest = 1 */
    ARG_INT,    /* *(int *)dest, within [lo, hi] */
    ARG_LONG,   /* *(long *)dest, within [lo, hi] */
    ARG_U64,    /* *(uint64_t *)dest, a decimal integer from 0 to 2^64 - 1 */
    ARG_DOUBLE, /* *(double *)dest, within [lo, hi] */
    ARG_FLOAT,  /* *(float *)dest, within [lo, hi] */
    ARG_STRING, /* *(const char **)dest = the argument itself */
    ARG_CHOICE, /* *(int *)dest = index of the value in choices */
    ARG_CUSTOM  /* parse(value, dest, err, err_len) decides */
} arg_kind;

/* One option. A table ends with an entry whose name is NULL. */
typedef struct {
    const char *name;  /* long name without the dashes: "spp" */
    char short_name;   /* 'o' for -o, or 0 */
    arg_kind kind;
    void *dest;
    double lo, hi;     /* ARG_INT, ARG_LONG, ARG_DOUBLE, ARG_FLOAT */
    int *given;        /* set to 1 when the option is given, or NULL */
    const char *const *choices; /* ARG_CHOICE: the names, NULL-terminated */
    /* ARG_CUSTOM: 0, or -1 with what is wrong in err (no option name). */
    int (*parse)(const char *value, void *dest, char *err, size_t err_len);
} arg_spec;

/* Parse argv[1..argc-1] against specs (getopt_long style: --name VALUE,
 * --name=VALUE, -o VALUE, "--" ends options). -h and --help call
 * help(stdout) and exit(0). Positional arguments are stored in order into
 * positional (at most max_positional of them). Returns their number; any
 * usage error (unknown option, missing or bad value, too many positionals)
 * prints "PROG: --OPT: what is wrong" and "see PROG --help" and exit(2). */
int args_parse(const char *prog, int argc, char **argv, const arg_spec *specs, void (*help)(FILE *out),
               const char **positional, int max_positional);

/* Print "PROG: message" and "see PROG --help" on stderr and exit(2). */
void args_usage_error(const char *prog, const char *fmt, ...) __attribute__((format(printf, 2, 3), noreturn));

/* The name among names (NULL-terminated) within two edits of word, or NULL:
 * the "did you mean" of unknown commands, options and fields. */
const char *args_closest(const char *word, const char *const *names);

#endif
