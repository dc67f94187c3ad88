/* fileio.c - whole-file reads and atomic writes (fileio.h). */
#include "fileio.h"

#include <errno.h>
#include <fcntl.h>
#include <libgen.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include <unistd.h>

#include "memhint.h"
#include "par.h"

/* Read exactly n bytes from fd at offset off into buf. Returns 0, or an
 * errno value (EIO for a file that ended early). */
static int read_exactly(int fd, char *buf, size_t n, off_t off) {
    while (n > 0) {
        ssize_t r = pread(fd, buf, n, off);
        if (r < 0 && errno == EINTR) continue;
        if (r < 0) return errno;
        if (r == 0) return EIO;
        buf += r;
        off += r;
        n -= (size_t)r;
    }
    return 0;
}

/* A big file is read in ranges of at least READ_PART_MIN bytes, one per
 * core (par.h), each by its own pread: the copy out of the page cache into
 * fresh memory, and the kernel's clearing of that memory, run at one
 * core's speed (ico9's 217 MB OBJ: 0.14-0.17 s on one thread, 0.07-0.09 s
 * on two; a scratch program, 3 alternations, 2026-11-28). From 32 MiB to
 * 4 MiB in the thirty-first session, so that the 38-51 MB OBJs of the
 * benchmark's 2.0-2.6M scenes are read in two: ico8's in 84-123 against
 * 22-63 ms (6 alternations, each a fresh process; docs/meshes.md). The
 * bytes are the same either way. */
#define READ_PART_MIN ((size_t)4 << 20)

typedef struct {
    int fd;
    char *buf;
    int err[PAR_MAX_PARTS]; /* each range's read_exactly result */
} read_ranges;

static void read_range(void *ctx, size_t begin, size_t end, int part) {
    read_ranges *R = ctx;
    R->err[part] = read_exactly(R->fd, R->buf + begin, end - begin, (off_t)begin);
}

/* Read n bytes of fd from its start into buf. Returns 0 or the first
 * range's errno value (EIO: the file ended early). */
static int read_whole(int fd, char *buf, size_t n) {
    read_ranges R = {fd, buf, {0}};
    int parts = par_parts(n, READ_PART_MIN);
    par_run(n, parts, read_range, &R);
    for (int k = 0; k < parts; k++)
        if (R.err[k]) return R.err[k];
    return 0;
}

long long file_read_with(const char *path, size_t max_len, file_alloc_cb alloc, void *ctx, char *err, size_t err_len) {
    /* O_NONBLOCK: a FIFO is refused below instead of waiting for a writer
     * in open(); a regular file ignores the flag. */
    int fd = open(path, O_RDONLY | O_NONBLOCK | O_CLOEXEC);
    if (fd < 0) {
        snprintf(err, err_len, "%s: cannot open: %s", path, strerror(errno));
        return -1;
    }
    struct stat st;
    size_t n = 0;
    char *buf;
    int ok = 0, e;
    if (fstat(fd, &st) != 0 || !S_ISREG(st.st_mode))
        snprintf(err, err_len, "%s: not a regular file", path);
    else if ((unsigned long long)st.st_size > max_len)
        snprintf(err, err_len, "%s: file is %lld bytes, more than the limit of %zu", path, (long long)st.st_size,
                 max_len);
    else if (n = (size_t)st.st_size, !(buf = alloc(n, ctx)))
        snprintf(err, err_len, "%s: out of memory reading %zu bytes", path, n);
    else if ((e = read_whole(fd, buf, n)) != 0)
        snprintf(err, err_len, "%s: read error: %s", path, e == EIO ? "the file ended early" : strerror(e));
    else
        ok = 1;
    close(fd);
    return ok ? (long long)n : -1;
}

/* file_read_all's room: the length and a NUL. On huge pages only where
 * they are cheaper to fault in (memhint_fresh): a file's text is read
 * once, front to back, and on a VM that hands freed memory back to its
 * host fresh huge pages are slow to get (ico9's 217 MB OBJ read in
 * 0.42-0.51 s into huge pages against 0.10-0.14 s, a scan of it 0.016 s
 * either way: docs/meshes.md). */
static void *alloc_plain(size_t len, void *ctx) {
    char **out = ctx;
    *out = malloc(len + 1);
    memhint_fresh(*out, len + 1);
    return *out;
}

char *file_read_all(const char *path, size_t max_len, size_t *len, char *err, size_t err_len) {
    char *buf = NULL;
    long long n = file_read_with(path, max_len, alloc_plain, &buf, err, err_len);
    if (n < 0) {
        free(buf);
        return NULL;
    }
    buf[n] = '\0';
    *len = (size_t)n;
    return buf;
}

int file_write_all(int fd, const void *buf, size_t len) {
    const char *data = buf;
    while (len > 0) {
        ssize_t w = write(fd, data, len);
        if (w < 0 && errno == EINTR) continue;
        if (w < 0) return errno;
        if (w == 0) return EIO;
        data += w;
        len -= (size_t)w;
    }
    return 0;
}

/* fsync the folder holding path, so a rename in it is durable. Returns 0 or
 * an errno value. */
static int sync_parent(const char *path) {
    char *copy = strdup(path);
    if (!copy) return ENOMEM;
    int fd = open(dirname(copy), O_RDONLY | O_DIRECTORY);
    free(copy);
    if (fd < 0) return errno;
    int e = fsync(fd) != 0 && errno != EINVAL ? errno : 0; /* EINVAL: a filesystem that cannot sync folders */
    close(fd);
    return e;
}

/* Create file_write_atomic's temporary file for path: its name into *tmp
 * (malloc'd, the caller frees; NULL when out of memory) and its
 * descriptor, or -1 with errno set. */
static int open_temporary(const char *path, char **tmp) {
    size_t pl = strlen(path);
    *tmp = malloc(pl + 16);
    if (!*tmp) {
        errno = ENOMEM;
        return -1;
    }
    snprintf(*tmp, pl + 16, "%s.tmp.XXXXXX", path);
    return mkstemp(*tmp);
}

int file_check_writable(const char *path, char *err, size_t err_len) {
    char *tmp;
    int fd = open_temporary(path, &tmp), e = fd < 0 ? errno : 0;
    if (fd >= 0) {
        close(fd);
        unlink(tmp);
    }
    free(tmp);
    if (e) snprintf(err, err_len, "%s: cannot write: %s", path, strerror(e));
    return e ? -1 : 0;
}

int file_write_atomic(const char *path, const void *data, size_t len, char *err, size_t err_len) {
    char *tmp;
    int fd = open_temporary(path, &tmp), e = fd < 0 ? errno : 0;
    if (!tmp) {
        snprintf(err, err_len, "%s: cannot write: out of memory", path);
        return -1;
    }
    if (!e) {
        mode_t mask = umask(0); /* mkstemp makes 0600; give the usual 0666 & ~umask */
        umask(mask);
        if (fchmod(fd, 0666 & ~mask) != 0) e = errno;
    }
    if (!e) e = file_write_all(fd, data, len);
    if (!e && fsync(fd) != 0) e = errno;
    if (fd >= 0 && close(fd) != 0 && !e) e = errno;
    if (!e && rename(tmp, path) != 0) e = errno;
    if (!e) e = sync_parent(path);
    if (e) {
        if (fd >= 0) unlink(tmp);
        snprintf(err, err_len, "%s: cannot write: %s", path, strerror(e));
    }
    free(tmp);
    return e ? -1 : 0;
}
