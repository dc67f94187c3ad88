/* journal_partial.h - what a running or cancelled job has so far, read
 * from its tile journal (jobs/ID.tiles, format in service.c and
 * docs/protocol.md), for `tessera fetch JOB --partial`. */
#ifndef TESSERA_JOURNAL_PARTIAL_H
#define TESSERA_JOURNAL_PARTIAL_H

#include <stddef.h>
#include <stdint.h>

#include "image/image.h"

/* Read the journal at path of a width x height job cut into tile_count
 * tiles of tile_size pixels (render_split_tiles) into img, allocated here
 * black (free with image_free), and done[tile_count] (1 for each tile
 * found). Reading stops at the first torn or corrupt record and never
 * changes the file; a missing journal is an empty one. Returns the number
 * of tiles done, or -1 with "PATH: reason" in err (out of memory). */
int journal_read_partial(const char *path, int width, int height, int tile_size, int tile_count, image *img,
                         uint8_t *done, char *err, size_t err_len);

/* The tiles not done, as ranges ("3, 7-12, 40-63"), in out (truncated with
 * "..." when it does not fit). */
void journal_missing_ranges(const uint8_t *done, int tile_count, char *out, size_t out_len);

#endif
