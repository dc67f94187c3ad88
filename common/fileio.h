/* fileio.h - whole-file reads with error messages that name the file. */
#ifndef TESSERA_FILEIO_H
#define TESSERA_FILEIO_H

#include <stddef.h>

/* Read the whole file at path into a NUL-terminated malloc'd buffer (the
 * caller frees it) and store its length, without the NUL, in *len. Refuses
 * files larger than max_len. On error returns NULL and writes
 * "PATH: reason" to err. */
char *file_read_all(const char *path, size_t max_len, size_t *len, char *err, size_t err_len);

#endif
