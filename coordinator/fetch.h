/* fetch.h - a job's image sent to a client in chunks, of any size (a
 * finished one, or what a running or cancelled one has done so far):
 * the file (jobs/ID.pfm) is read and hashed on libuv's thread pool one
 * chunk at a time, and the next chunk is read only once the connection's
 * write queue has drained below one chunk, so the loop never blocks on the
 * disk and never holds more than two chunks of the image, however large.
 *
 * On the wire (docs/protocol.md, "fetch"): a JSON `image` message (job,
 * format "pfm", bytes), then `D` frames of the file's bytes in order, then
 * `image_end` (job, bytes, blake2b: the BLAKE2b-256 of the bytes in hex).
 * A read error midway sends `error` instead of `image_end`. */
#ifndef TESSERA_FETCH_H
#define TESSERA_FETCH_H

#include <stddef.h>
#include <stdint.h>
#include <uv.h>

#include "net/conn.h"

#define FETCH_CHUNK_DEFAULT ((size_t)1 << 20)

typedef struct fetch_stream fetch_stream;

/* The chunk size: FETCH_CHUNK_DEFAULT, or $TESSERA_FETCH_CHUNK bytes (16 to
 * 64 MiB; for tests, to make a small image take many chunks). */
size_t fetch_chunk_size(void);

/* Start sending the file at path (a finished image) for job on c, in chunks
 * of chunk bytes. *slot is set to the stream and back to NULL when it ends
 * (sent, failed or detached); the caller keeps the slot alive until then
 * or calls fetch_detach. Returns 0, or -1 when out of memory (nothing sent). */
int fetch_start(uv_loop_t *loop, conn *c, uint32_t job, const char *path, size_t chunk, fetch_stream **slot);

/* What a partial fetch is made of: a running or cancelled job's tile
 * journal (journal.h) and its geometry, and its state's name for the
 * "partial" message. The strings are copied. */
typedef struct {
    const char *journal;
    const char *state;
    int width, height, tile_size, tile_count;
} fetch_partial_spec;

/* fetch_start for what a job has done so far: on the thread pool, the
 * journal's tiles are written into a new PFM at tmp (black where missing;
 * journal_write_partial_pfm), which is unlinked once opened; on the loop, a
 * "partial" message (job, state, tiles_done, tiles_total, tile_size,
 * missing: ranges of tile numbers) goes before the image, streamed as
 * fetch_start's. If the PFM cannot be made, an `error` is sent. Returns 0,
 * or -1 when out of memory (nothing sent). */
int fetch_start_partial(uv_loop_t *loop, conn *c, uint32_t job, const fetch_partial_spec *p, const char *tmp,
                        size_t chunk, fetch_stream **slot);

/* The connection is going away: stop sending (a read in flight finishes on
 * the pool and is then dropped). Clears *slot. Can't fail. */
void fetch_detach(fetch_stream **slot);

#endif
