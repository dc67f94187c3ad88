/* fuzz_http.c - libFuzzer target: what a browser (or anyone) can send to
 * the dashboard (coordinator/http.h). The bytes are fed to the request
 * parser in pieces whose sizes come from the input, within the dashboard's
 * limits; a complete request's fields then go through the cookie and form
 * readers the dashboard applies. Checks: the parser's answer is 0, 1 or a
 * refusal status, and every kept field is NUL-terminated in its buffer. */
#include <stdint.h>
#include <stdlib.h>
#include <string.h>

#include "coordinator/http.h"

int LLVMFuzzerTestOneInput(const uint8_t *data, size_t size) {
    if (size < 1) return 0;
    size_t piece = 1 + data[0] % 64;
    data++, size--;
    http_reqparser *r = malloc(sizeof *r);
    http_reqparser_init(r, 64 << 10, 64);
    int rc = 0;
    for (size_t off = 0; off < size && rc == 0; off += piece)
        rc = http_reqparser_feed(r, (const char *)data + off, size - off < piece ? size - off : piece);
    if (!(rc == 0 || rc == 1 || rc == 400 || rc == 413 || rc == 414 || rc == 431 || rc == 503)) abort();
    if (rc == 1) {
        const http_request *q = &r->rq;
        if (memchr(q->path, 0, sizeof q->path) == NULL || memchr(q->query, 0, sizeof q->query) == NULL ||
            memchr(q->cookie, 0, sizeof q->cookie) == NULL || memchr(q->host, 0, sizeof q->host) == NULL ||
            strlen(q->body) > q->body_len)
            abort();
        char out[128];
        http_cookie_get(q->cookie, "tessera_session", out, sizeof out);
        if (strlen(out) >= sizeof out) abort();
        http_form_get(q->body, "token", out, sizeof out);
    }
    http_reqparser_free(r);
    free(r);
    return 0;
}
