/* paging.c - long listings sent as pages of at most PAGING_PAGE_BYTES of
 * JSON (paging.h). Linear in the listing: each element is printed once to
 * measure it, and pages are cut greedily. */
#include "paging.h"

#include <stdlib.h>
#include <string.h>

#include "net/protocol.h"
#include "net/wire.h"

static void send_error(conn *c, const char *reason) {
    size_t len;
    uint8_t *f = proto_frame_reason("error", reason, &len);
    if (f) conn_send(c, f, len);
}

/* A growing text buffer. */
typedef struct {
    char *p;
    size_t len, cap;
} text;

static int text_add(text *t, const char *s, size_t n) {
    if (t->len + n + 1 > t->cap) {
        size_t cap = t->cap ? t->cap : 65536;
        while (cap < t->len + n + 1) cap *= 2;
        char *p = realloc(t->p, cap);
        if (!p) return -1;
        t->p = p;
        t->cap = cap;
    }
    memcpy(t->p + t->len, s, n);
    t->len += n;
    t->p[t->len] = 0;
    return 0;
}

/* Send the page in t (the base's fields, then the elements so far) closed
 * with "]" and the more flag; t is reset to prefix for the next page. */
static int send_page(conn *c, text *t, int more, const char *prefix, size_t prefix_len) {
    const char *end = more ? "],\"more\":true}" : "],\"more\":false}";
    if (text_add(t, end, strlen(end))) return -1;
    size_t len;
    uint8_t *f = wire_frame_new(WIRE_KIND_JSON, t->len, &len);
    if (!f) return -1;
    memcpy(f + WIRE_HEADER_BYTES, t->p, t->len);
    t->len = 0;
    if (conn_send(c, f, len) || text_add(t, prefix, prefix_len)) return -1;
    return 0;
}

#define PAGING_WHOLE_ITEMS 64 /* an array this short is tried in one frame first */

int paging_send(conn *c, cJSON *msg, const char *key) {
    if (!msg) {
        send_error(c, "out of memory");
        return -1;
    }
    cJSON *arr = cJSON_GetObjectItemCaseSensitive(msg, key);
    int n = 0;
    for (const cJSON *i = arr ? arr->child : NULL; i && n <= PAGING_WHOLE_ITEMS; i = i->next) n++;
    if (n <= PAGING_WHOLE_ITEMS) { /* the common case: one frame, no "more" */
        size_t len;
        uint8_t *whole = wire_frame_json(msg, &len);
        if (whole) {
            cJSON_Delete(msg);
            return conn_send(c, whole, len);
        }
    }
    /* Pages, printed by hand so that each element is printed once: the
     * base's fields, then "key":[elements...],"more":bool}. */
    arr = cJSON_DetachItemFromObjectCaseSensitive(msg, key);
    char *base = cJSON_PrintUnformatted(msg), prefix[PAGING_PAGE_BYTES / 4];
    size_t base_len = base ? strlen(base) : 0;
    int rc = arr && base_len >= 2 && base_len + strlen(key) + 8 < sizeof prefix ? 0 : -1;
    size_t prefix_len = 0;
    if (rc == 0) { /* "{...}" -> "{...,"key":[" (or "{"key":[" for an empty base) */
        prefix_len = (size_t)snprintf(prefix, sizeof prefix, "%.*s%s\"%s\":[", (int)(base_len - 1), base,
                                      base_len > 2 ? "," : "", key);
    }
    free(base);
    text t = {0};
    if (rc == 0) rc = text_add(&t, prefix, prefix_len);
    int items = 0;
    for (const cJSON *item = arr ? arr->child : NULL; rc == 0 && item; item = item->next) {
        char *it = cJSON_PrintUnformatted(item);
        size_t il = it ? strlen(it) : 0;
        if (!it || prefix_len + il + 32 > PAGING_PAGE_BYTES) { /* out of memory, or too large even alone */
            free(it);
            rc = -1;
            break;
        }
        if (t.len + il + 32 > PAGING_PAGE_BYTES) {
            rc = send_page(c, &t, 1, prefix, prefix_len);
            items = 0;
        }
        if (rc == 0 && items > 0) rc = text_add(&t, ",", 1);
        if (rc == 0) rc = text_add(&t, it, il);
        items++;
        free(it);
    }
    if (rc == 0) rc = send_page(c, &t, 0, prefix, prefix_len);
    if (rc) send_error(c, "the answer is too large to send (an element over the frame limit) or memory ran out");
    free(t.p);
    cJSON_Delete(arr);
    cJSON_Delete(msg);
    return rc;
}
