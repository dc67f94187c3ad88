/* address.h - "HOST:PORT" strings as given on command lines. */
#ifndef TESSERA_ADDRESS_H
#define TESSERA_ADDRESS_H

#include <stddef.h>

/* Split "HOST:PORT", "[V6ADDR]:PORT" or ":PORT" (host "0.0.0.0") into host
 * (NUL-terminated, at most host_len bytes) and a port from 0 to 65535.
 * Returns 0, or -1 with the reason in err. */
int address_parse(const char *s, char *host, size_t host_len, int *port, char *err, size_t err_len);

/* Whether host (as address_parse gives it) is this machine's loopback:
 * "localhost", 127.0.0.0/8 or ::1. Links without a token are in clear and
 * allowed only there unless the user says --insecure. Can't fail. */
int address_is_loopback(const char *host);

/* host and port as address_parse reads them back: "HOST:PORT", or
 * "[HOST]:PORT" when host is an IPv6 address (holds a ':'), so that
 * "::1:7000" is never printed. Into out (truncated to len); can't fail. */
void address_format(const char *host, int port, char *out, size_t len);

#endif
