/* fileio.h - whole-file reads and atomic, durable writes, with error messages
 * that name the file. */
#ifndef TESSERA_FILEIO_H
#define TESSERA_FILEIO_H

#include <stddef.h>

/* Read the whole file at path into a NUL-terminated malloc'd buffer (the
 * caller frees it) and store its length, without the NUL, in *len. Refuses
 * files larger than max_len. On error returns NULL and writes
 * "PATH: reason" to err. */
char *file_read_all(const char *path, size_t max_len, size_t *len, char *err, size_t err_len);

/* Where file_read_with puts a file of len bytes: len writable bytes, or
 * NULL when out of memory. ctx is file_read_with's. */
typedef void *(*file_alloc_cb)(size_t len, void *ctx);

/* file_read_all into memory of the caller's: open path, refuse anything
 * but a regular file of at most max_len bytes, ask alloc for room for its
 * bytes and read them there (so that a caller who wants them behind a
 * header of its own does not copy them). What alloc returned is the
 * caller's, also on failure. Returns the file's length, or -1 with "PATH:
 * reason" in err. */
long long file_read_with(const char *path, size_t max_len, file_alloc_cb alloc, void *ctx, char *err, size_t err_len);

/* Replace the file at path with len bytes of data, atomically and durably:
 * written to a unique temporary file in the same folder (mode 0666 less the
 * umask), synced, renamed over path, and the folder synced, so that after a
 * crash path holds either the old contents or the new, never a mix, and a
 * successful return survives power loss. Returns 0, or -1 with "PATH: cannot
 * write: reason" in err (the temporary is removed). Used for images, the job
 * journal's records and the scene store. */
int file_write_atomic(const char *path, const void *data, size_t len, char *err, size_t err_len);

/* Whether file_write_atomic(path, ...) could create its temporary file
 * now: one is created in path's folder and removed at once, so a folder
 * that does not exist, is not writable or is on a read-only filesystem is
 * found before hours of work go into what would be written there (a full
 * disk is found only by the write itself). Returns 0, or -1 with "PATH:
 * cannot write: reason" in err. */
int file_check_writable(const char *path, char *err, size_t err_len);

/* Write all len bytes of buf to fd (retrying short writes and EINTR).
 * Returns 0 or an errno value. */
int file_write_all(int fd, const void *buf, size_t len);

#endif
