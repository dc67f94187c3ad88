/* paging.c - long listings sent as pages of at most PAGING_PAGE_BYTES of
 * JSON (paging.h). Linear in the listing: each element is printed once to
 * measure it, and pages are cut greedily. */
#include "paging.h"

#include <stdlib.h>
#include <string.h>

#include "net/protocol.h"
#include "net/wire.h"

static int send_json(conn *c, const cJSON *m) {
    size_t len;
    uint8_t *f = wire_frame_json(m, &len);
    return f ? conn_send(c, f, len) : -1;
}

static void send_error(conn *c, const char *reason) {
    size_t len;
    uint8_t *f = proto_frame_reason("error", reason, &len);
    if (f) conn_send(c, f, len);
}

/* Printed length of an element, or 0 when out of memory. */
static size_t printed_len(const cJSON *item) {
    char *t = cJSON_PrintUnformatted(item);
    size_t n = t ? strlen(t) : 0;
    free(t);
    return n;
}

/* A page: a copy of base (without the array) with array and more. */
static int send_page(conn *c, const cJSON *base, const char *key, cJSON *array, int more) {
    cJSON *p = cJSON_Duplicate(base, 1);
    if (!p) {
        cJSON_Delete(array);
        return -1;
    }
    cJSON_AddItemToObject(p, key, array);
    cJSON_AddBoolToObject(p, "more", more);
    int rc = send_json(c, p);
    cJSON_Delete(p);
    return rc;
}

int paging_send(conn *c, cJSON *msg, const char *key) {
    if (!msg) {
        send_error(c, "out of memory");
        return -1;
    }
    size_t len;
    uint8_t *whole = wire_frame_json(msg, &len);
    if (whole) { /* the common case: one frame, no "more" */
        cJSON_Delete(msg);
        return conn_send(c, whole, len);
    }
    cJSON *arr = cJSON_DetachItemFromObjectCaseSensitive(msg, key);
    size_t base_len = printed_len(msg), used = 0;
    int rc = arr && base_len && base_len + 64 < PAGING_PAGE_BYTES ? 0 : -1;
    cJSON *page = rc == 0 ? cJSON_CreateArray() : NULL;
    while (rc == 0 && page && arr->child) {
        cJSON *item = cJSON_DetachItemFromArray(arr, 0);
        size_t n = printed_len(item) + 1; /* and its comma */
        if (n + base_len + 64 > PAGING_PAGE_BYTES) { /* cannot fit even alone */
            cJSON_Delete(item);
            rc = -1;
            break;
        }
        if (used + n + base_len + 64 > PAGING_PAGE_BYTES) {
            rc = send_page(c, msg, key, page, 1);
            page = cJSON_CreateArray();
            used = 0;
        }
        if (page) cJSON_AddItemToArray(page, item);
        else cJSON_Delete(item);
        used += n;
    }
    if (rc == 0 && !page) rc = -1;
    if (rc == 0) rc = send_page(c, msg, key, page, 0);
    else cJSON_Delete(page);
    if (rc) send_error(c, "the answer is too large to send (an element over the frame limit) or memory ran out");
    cJSON_Delete(arr);
    cJSON_Delete(msg);
    return rc;
}
