/* journal.h - a job's tile journal (jobs/ID.tiles, docs/protocol.md): the
 * record check, and reading the records back, for the restart of a running
 * job (jobstore.c) and for `tessera fetch JOB --partial` (fetch.c).
 *
 * A record: u32 magic "TILE", u32 tile, u32 float count n, n floats, u32
 * check (FNV-1a of the floats' bytes seeded by the tile number), all
 * little-endian. Records are appended and synced before a tile counts. */
#ifndef TESSERA_JOURNAL_H
#define TESSERA_JOURNAL_H

#include <stddef.h>
#include <stdint.h>

#include "image/image.h"
#include "render/film.h"

#define JOURNAL_MAGIC 0x454c4954u /* "TILE" */
#define JOURNAL_RECORD_OVERHEAD 16 /* bytes of a record besides its floats */

/* The check of a record of n floats of tile. Can't fail. */
uint32_t journal_record_check(uint32_t tile, const float *px, size_t n);

/* Replay the records in data[0..len) of a job cut into rects[tile_count]
 * into the 3-channel film f, setting done[tile] for each tile found.
 * Stops at the first torn or corrupt record. Returns the length of the
 * good prefix (len when all is good); *found counts the tiles that were not
 * yet done. */
size_t journal_replay(const uint8_t *data, size_t len, const tile_rect *rects, int tile_count, film *f,
                      uint8_t *done, int *found);

/* Write what the journal at path holds of a width x height job cut into
 * tile_count tiles of tile_size pixels (render_split_tiles) as a new PFM
 * file out (created, mode 0600; the tiles not found are black), and
 * done[tile_count] (1 for each tile found). The journal is read record by
 * record (the coordinator may cut it short meanwhile) and never changed;
 * reading stops at its first torn or corrupt record; a missing journal is
 * an empty one. Memory: one record and one tile row.
 * Returns the number of tiles done, or -1 with "PATH: reason" in err (out
 * is then removed). */
int journal_write_partial_pfm(const char *path, const char *out, int width, int height, int tile_size,
                              int tile_count, uint8_t *done, char *err, size_t err_len);

/* The tiles not done, as ranges ("3, 7-12, 40-63"), in out (truncated with
 * "..." when it does not fit). */
void journal_missing_ranges(const uint8_t *done, int tile_count, char *out, size_t out_len);

#endif
