/* log.h - the one logger of the coordinator, the farm and the workers.
 *
 * A line is "2026-11-23T09:28:29.123Z WHO LEVEL: message": an ISO-8601 UTC
 * timestamp with milliseconds, who wrote it ("tessera-coordinator",
 * "tessera-worker w1"), the level, and the message with every control
 * character escaped (\n, \t, \xNN), so that text from a peer (job names,
 * worker names, paths) can neither forge a log line nor repaint the
 * operator's terminal. Lines are written whole with one fputs and flushed.
 *
 * Command-line errors meant for the person at the terminal ("tessera: x.json:
 * ...") are not log lines and do not come through here. */
#ifndef TESSERA_LOG_H
#define TESSERA_LOG_H

#include <stdarg.h>
#include <stddef.h>
#include <stdio.h>

typedef enum { LOG_ERROR, LOG_WARN, LOG_INFO, LOG_DEBUG } log_level;

/* Write one line to out (stderr when NULL) as described above. Lines above
 * the level set by log_set_level are dropped. Can't fail (a failed write is
 * ignored: there is nowhere left to report it). */
void log_line(FILE *out, log_level level, const char *who, const char *fmt, ...)
    __attribute__((format(printf, 4, 5)));
void log_vline(FILE *out, log_level level, const char *who, const char *fmt, va_list ap);

/* The most verbose level written (default LOG_INFO). */
void log_set_level(log_level max);

/* Copy in to out (cap bytes, always NUL-terminated when cap > 0), escaping
 * control characters and DEL as \n, \r, \t or \xNN and backslashes as \\.
 * Returns the length written. For text from peers printed anywhere else
 * (tables of `tessera status`, `tessera workers`). */
size_t log_escape(const char *in, char *out, size_t cap);

/* The ISO-8601 UTC time of now with milliseconds, "2026-11-23T09:28:29.123Z",
 * into out (at least 25 bytes). Can't fail. */
void log_timestamp(char *out, size_t cap);

#endif
