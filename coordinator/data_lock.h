/* data_lock.h - one coordinator per data dir: an exclusive flock(2) on
 * DATA_DIR/lock, held for the life of the process, with the holder's PID
 * written in the file so that a second coordinator can name it. */
#ifndef TESSERA_DATA_LOCK_H
#define TESSERA_DATA_LOCK_H

#include <stddef.h>

/* Lock dir (which must exist). Returns the lock's file descriptor, to keep
 * open until the process exits (the kernel releases the lock then, also
 * after kill -9), or -1 with the reason in err: "DIR: in use by another
 * tessera-coordinator (PID N, lock DIR/lock)", or the I/O error. */
int data_dir_lock(const char *dir, char *err, size_t err_len);

#endif
