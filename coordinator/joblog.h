/* joblog.h - a job's event log, kept in memory and bounded: tiles handed
 * out (and backups), done, put back in the queue, workers joining and
 * leaving while it runs, and the job's own milestones (submitted, priority
 * changed, cancelled, finished). `tessera logs JOB` prints it and the job
 * page of the dashboard shows it (GET /api/jobs/N/log): the same lines.
 *
 * At most JOBLOG_MAX lines are kept in memory; older ones are dropped and
 * counted. With joblog_persist the lines also go to a file in the data
 * dir (appended on libuv's thread pool), from which a log is read back
 * after a restart of the coordinator, on first use: a job's log outlives
 * the process. */
#ifndef TESSERA_JOBLOG_H
#define TESSERA_JOBLOG_H

#include <cjson/cJSON.h>
#include <stdint.h>
#include <uv.h>

#include "farm.h"
#include "net/protocol.h"

#define JOBLOG_MAX PROTOCOL_LOG_LINES_MAX /* lines kept per job */
#define JOBLOG_LINE 120  /* bytes per line, NUL included (longer lines are cut) */
#define JOBLOG_FILE_MAX (4u << 20) /* bytes of a log's file; later lines stay in memory only */

typedef struct joblog joblog;

/* An empty log (its memory grows with its lines, up to JOBLOG_MAX).
 * Returns NULL when out of memory. */
joblog *joblog_new(void);

/* Free l (NULL is fine). Lines not yet in its file are written first
 * (at once, or when the write in flight ends: the loop must run until its
 * requests are done, as uv_loop_close requires anyway). */
void joblog_free(joblog *l);

/* Append l's lines from now on to the file at path too, one line "EPOCH
 * TEXT\n" each, written on loop's thread pool a batch at a time (no sync:
 * a crash may lose the last lines, never the job's work). Not existing: a
 * new job, an old file is removed. No file is held open between batches. existing: the
 * file may hold the lines of an earlier run (a restart), which
 * joblog_to_json then reads back on first use, the lines added since
 * included. Up to JOBLOG_FILE_MAX bytes are written; past that, lines are
 * kept in memory only. Returns 0, or -1 with "PATH: reason" in err (the
 * log then stays in memory only). */
int joblog_persist(joblog *l, uv_loop_t *loop, const char *path, int existing, char *err, size_t err_len);

/* Append a line stamped with wall (epoch seconds). l may be NULL (nothing
 * is kept). Can't fail: out of memory, the line is counted as dropped. */
void joblog_add(joblog *l, double wall, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Append the line that tells a farm event. */
void joblog_add_event(joblog *l, double wall, const farm_event *e);

/* Lines kept now, and lines dropped so far (the oldest, beyond JOBLOG_MAX). */
int joblog_count(const joblog *l);
uint64_t joblog_dropped(const joblog *l);

/* Add the log to o: "dropped": N and "lines": [{"t": epoch, "text": ...}],
 * oldest first, at most the last max lines (max <= 0: all). After a
 * restart (joblog_persist with existing) the first call reads the file
 * back (at most JOBLOG_FILE_MAX bytes, on the calling thread). Returns 0,
 * or -1 when out of memory. */
int joblog_to_json(joblog *l, cJSON *o, int max);

#endif
