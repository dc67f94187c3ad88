/* address.c - parsing "HOST:PORT". */
#include "address.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>

int address_parse(const char *s, char *host, size_t host_len, int *port, char *err, size_t err_len) {
    const char *colon = strrchr(s, ':');
    if (!colon) {
        snprintf(err, err_len, "\"%s\": expected HOST:PORT", s);
        return -1;
    }
    const char *h = s;
    size_t hl = (size_t)(colon - s);
    if (hl >= 2 && h[0] == '[' && h[hl - 1] == ']') {
        h++;
        hl -= 2;
    }
    if (hl == 0) {
        h = "0.0.0.0";
        hl = strlen(h);
    }
    char *end;
    long p = strtol(colon + 1, &end, 10);
    if (end == colon + 1 || *end || p < 0 || p > 65535) {
        snprintf(err, err_len, "\"%s\": port must be a number from 0 to 65535", s);
        return -1;
    }
    if (hl >= host_len) {
        snprintf(err, err_len, "\"%s\": host name too long", s);
        return -1;
    }
    memcpy(host, h, hl);
    host[hl] = '\0';
    *port = (int)p;
    return 0;
}

int address_is_loopback(const char *host) {
    return strcmp(host, "localhost") == 0 || strncmp(host, "127.", 4) == 0 || strcmp(host, "::1") == 0;
}

void address_format(const char *host, int port, char *out, size_t len) {
    snprintf(out, len, strchr(host, ':') ? "[%s]:%d" : "%s:%d", host, port);
}
