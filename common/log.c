/* log.c - timestamped, escaped log lines (log.h). */
#include "log.h"

#include <string.h>
#include <time.h>

static log_level max_level = LOG_INFO;

static const char *const level_names[] = {"error", "warning", "info", "debug"};

void log_set_level(log_level max) { max_level = max; }

void log_timestamp(char *out, size_t cap) {
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    struct tm tm;
    gmtime_r(&ts.tv_sec, &tm);
    char day[32];
    strftime(day, sizeof day, "%Y-%m-%dT%H:%M:%S", &tm);
    snprintf(out, cap, "%s.%03ldZ", day, ts.tv_nsec / 1000000L);
}

size_t log_escape(const char *in, char *out, size_t cap) {
    size_t n = 0;
    if (cap == 0) return 0;
    for (const unsigned char *p = (const unsigned char *)in; *p; p++) {
        char esc[5];
        const char *piece = esc;
        if (*p == '\n') piece = "\\n";
        else if (*p == '\r') piece = "\\r";
        else if (*p == '\t') piece = "\\t";
        else if (*p == '\\') piece = "\\\\";
        else if (*p < 0x20 || *p == 0x7f) snprintf(esc, sizeof esc, "\\x%02x", *p);
        else esc[0] = (char)*p, esc[1] = '\0';
        size_t len = strlen(piece);
        if (n + len >= cap) break;
        memcpy(out + n, piece, len);
        n += len;
    }
    out[n] = '\0';
    return n;
}

void log_vline(FILE *out, log_level level, const char *who, const char *fmt, va_list ap) {
    if (level > max_level) return;
    char msg[2048], safe[4096], stamp[40], line[4300];
    vsnprintf(msg, sizeof msg, fmt, ap);
    log_escape(msg, safe, sizeof safe);
    log_timestamp(stamp, sizeof stamp);
    snprintf(line, sizeof line, "%s %s %s: %s\n", stamp, who, level_names[level], safe);
    if (!out) out = stderr;
    fputs(line, out);
    fflush(out);
}

void log_line(FILE *out, log_level level, const char *who, const char *fmt, ...) {
    va_list ap;
    va_start(ap, fmt);
    log_vline(out, level, who, fmt, ap);
    va_end(ap);
}
