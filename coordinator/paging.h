/* paging.h - answers too long for one JSON frame (WIRE_JSON_MAX), sent as
 * pages: a listing (status of every kept job, workers) becomes several
 * messages of the same type, each with part of the array and "more": true
 * on all but the last (docs/protocol.md). A client merges the arrays. */
#ifndef TESSERA_PAGING_H
#define TESSERA_PAGING_H

#include <cjson/cJSON.h>

#include "net/conn.h"

/* The largest JSON text of one page: WIRE_JSON_MAX less room for the
 * "more" flag and rounding. */
#define PAGING_PAGE_BYTES (60u << 10)

/* Send msg on c: whole when it fits one frame, else as pages splitting the
 * array under key (each page: msg's other fields, part of the array,
 * "more"). Takes msg (frees it). Returns 0, or -1 when out of memory or a
 * single element is too large for a frame (an "error" naming the fault is
 * sent instead). */
int paging_send(conn *c, cJSON *msg, const char *key);

#endif
