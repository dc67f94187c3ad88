/* tjournal.h - a job's tile journal written off the loop thread, with
 * group commit: records are appended to a buffer on the loop; one batch at
 * a time is written and fdatasync'd on libuv's thread pool
 * (uv_queue_work); records that land while a batch is being synced go
 * together in the next one. A tile counts only once its batch is durable:
 * the callback names the batch's tiles with the outcome. A failed batch is
 * cut off the file again (ftruncate to the last durable length), so the
 * file holds only whole, synced records (the format is journal.h's).
 * Out of space (ENOSPC, EDQUOT) is not a failure: the batch is kept, not
 * counted, and written when space returns; other errors fail its tiles. */
#ifndef TESSERA_TJOURNAL_H
#define TESSERA_TJOURNAL_H

#include <stddef.h>
#include <stdint.h>
#include <uv.h>

typedef struct tjournal tjournal;

/* A batch ended: tiles[0..n) are durable (error 0) or not (error: errno). */
typedef void (*tjournal_cb)(void *ctx, const uint32_t *tiles, int n, int error);

/* The journal ran out of space (error: ENOSPC or EDQUOT) and holds its
 * records in memory, retrying every TJOURNAL_RETRY_MS; or (error 0) space
 * came back and they were written. Called once per change. */
typedef void (*tjournal_pause_cb)(void *ctx, int error);

#define TJOURNAL_RETRY_MS 1000

/* Open (create, append to) the journal at path; on_pause may be NULL.
 * Returns NULL with "PATH: reason" in err. */
tjournal *tjournal_open(uv_loop_t *loop, const char *path, tjournal_cb cb, tjournal_pause_cb on_pause, void *ctx,
                        char *err, size_t err_len);

/* Queue the record of tile (len bytes, copied) and start a batch when none
 * is being written. Returns 0, or -1 when out of memory. */
int tjournal_append(tjournal *jr, uint32_t tile, const uint8_t *rec, size_t len);

/* Batches written so far and the most tiles in one (for the log). */
void tjournal_stats(const tjournal *jr, uint64_t *batches, int *largest);

/* No more callbacks; the file is closed and jr freed once the batch being
 * written (if any) ends. Queued records not yet written are dropped (their
 * tiles never counted). NULL is ignored. */
void tjournal_close(tjournal *jr);

#endif
