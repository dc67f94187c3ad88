/* data_lock.c - one coordinator per data dir (see data_lock.h).
 *
 * Two coordinators on one data dir would both hand out job numbers and
 * write the same journal files, and one's jobs would be lost (issue 18).
 * flock is released by the kernel when the holder dies, so a stale lock
 * file left by kill -9 never blocks a restart. */
#define _GNU_SOURCE
#include "data_lock.h"

#include <errno.h>
#include <fcntl.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/file.h>
#include <time.h>
#include <unistd.h>

/* The PID the holder wrote into fd's file, or 0 if it has not yet. */
static long holder_pid(int fd) {
    char buf[32];
    for (int tries = 0; tries < 100; tries++) { /* the holder writes it just after locking */
        ssize_t n = pread(fd, buf, sizeof buf - 1, 0);
        if (n > 0) {
            buf[n] = '\0';
            long pid = strtol(buf, NULL, 10);
            if (pid > 0) return pid;
        }
        struct timespec ts = {0, 10000000};
        nanosleep(&ts, NULL);
    }
    return 0;
}

int data_dir_lock(const char *dir, char *err, size_t err_len) {
    char path[4096];
    snprintf(path, sizeof path, "%s/lock", dir);
    int fd = open(path, O_RDWR | O_CREAT | O_CLOEXEC, 0644);
    if (fd < 0) {
        snprintf(err, err_len, "%.400s: cannot open the lock file: %s", path, strerror(errno));
        return -1;
    }
    if (flock(fd, LOCK_EX | LOCK_NB) != 0) {
        int e = errno;
        long pid = e == EWOULDBLOCK ? holder_pid(fd) : 0;
        if (e != EWOULDBLOCK)
            snprintf(err, err_len, "%.400s: cannot lock: %s", path, strerror(e));
        else if (pid > 0)
            snprintf(err, err_len, "%.400s: in use by another tessera-coordinator (PID %ld, lock %.400s)", dir, pid,
                     path);
        else
            snprintf(err, err_len, "%.400s: in use by another tessera-coordinator (lock %.400s)", dir, path);
        close(fd);
        return -1;
    }
    char text[32];
    int len = snprintf(text, sizeof text, "%ld\n", (long)getpid());
    if (ftruncate(fd, 0) != 0 || pwrite(fd, text, (size_t)len, 0) != len) {
        snprintf(err, err_len, "%.400s: cannot write the PID: %s", path, strerror(errno));
        close(fd);
        return -1;
    }
    return fd;
}
