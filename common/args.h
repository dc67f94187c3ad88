/* args.h - number options of the command lines, checked the same way
 * everywhere: a usage error names the program, the option and the range,
 * and exits with status 2. */
#ifndef TESSERA_ARGS_H
#define TESSERA_ARGS_H

/* Parse s as an integer within [lo, hi]; on anything else print
 * "PROG: OPT: expected an integer from LO to HI, got "S"" and exit(2). */
long args_long(const char *prog, const char *opt, const char *s, long lo, long hi);

/* The same for a number within [lo, hi] (NaN is refused). */
double args_double(const char *prog, const char *opt, const char *s, double lo, double hi);

#endif
