/* test_log.c - the one logger: ISO-8601 timestamps, levels, escaped text. */
#include <regex.h>
#include <stdio.h>
#include <string.h>

#include "harness.h"
#include "log.h"

/* The line log_line writes to a temporary file. */
static void logged(char *out, size_t cap, log_level level, const char *who, const char *msg) {
    FILE *f = tmpfile();
    log_line(f, level, who, "%s", msg);
    rewind(f);
    size_t n = fread(out, 1, cap - 1, f);
    out[n] = '\0';
    fclose(f);
}

TEST(log_line_has_iso8601_time_who_level_and_message) {
    char line[512];
    logged(line, sizeof line, LOG_INFO, "tessera-worker w1", "joined the farm");
    regex_t re;
    regcomp(&re, "^[0-9]{4}-[0-9]{2}-[0-9]{2}T[0-9]{2}:[0-9]{2}:[0-9]{2}\\.[0-9]{3}Z tessera-worker w1 info: "
                 "joined the farm\n$", REG_EXTENDED);
    CHECK(regexec(&re, line, 0, NULL, 0) == 0, "unexpected log line: \"%s\"", line);
    regfree(&re);
}

TEST(log_escapes_control_characters_so_peers_cannot_forge_lines) {
    char line[512];
    logged(line, sizeof line, LOG_WARN, "tessera-coordinator", "job \"a\nb\" \x1b[2J tab\there \\ end");
    CHECK(strstr(line, " warning: job \"a\\nb\" \\x1b[2J tab\\there \\\\ end\n"), "not escaped: \"%s\"", line);
    CHECK(strchr(line, '\n') == line + strlen(line) - 1, "more than one line: \"%s\"", line);
    CHECK(!strchr(line, '\x1b'), "an escape character reached the log");
}

TEST(log_level_filters_and_escape_truncates_safely) {
    char line[512] = "";
    log_set_level(LOG_WARN);
    logged(line, sizeof line, LOG_INFO, "x", "dropped");
    log_set_level(LOG_INFO);
    CHECK(line[0] == '\0', "an info line passed a warning-level filter: %s", line);
    char small[6];
    size_t n = log_escape("a\nbcdef", small, sizeof small);
    CHECK(n == 5 && strcmp(small, "a\\nbc") == 0, "escape into 6 bytes gave \"%s\" (%zu)", small, n);
    n = log_escape("\x01", small, 4); /* "\x01" needs 4 bytes + NUL: dropped whole, never cut in half */
    CHECK(n == 0 && small[0] == '\0', "a cut escape sequence: \"%s\"", small);
}
