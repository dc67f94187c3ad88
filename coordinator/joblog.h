/* joblog.h - a job's event log, kept in memory and bounded: tiles handed
 * out (and backups), done, put back in the queue, workers joining and
 * leaving while it runs, and the job's own milestones (submitted, priority
 * changed, cancelled, finished). `tessera logs JOB` prints it and the job
 * page of the dashboard shows it (GET /api/jobs/N/log): the same lines.
 *
 * At most JOBLOG_MAX lines are kept; older ones are dropped and counted.
 * The log lives as long as the job is kept in memory (not across a
 * restart of the coordinator). */
#ifndef TESSERA_JOBLOG_H
#define TESSERA_JOBLOG_H

#include <cjson/cJSON.h>
#include <stdint.h>

#include "farm.h"
#include "net/protocol.h"

#define JOBLOG_MAX PROTOCOL_LOG_LINES_MAX /* lines kept per job */
#define JOBLOG_LINE 120  /* bytes per line, NUL included (longer lines are cut) */

typedef struct joblog joblog;

/* An empty log (its memory grows with its lines, up to JOBLOG_MAX).
 * Returns NULL when out of memory. */
joblog *joblog_new(void);

/* Free l (NULL is fine). */
void joblog_free(joblog *l);

/* Append a line stamped with wall (epoch seconds). l may be NULL (nothing
 * is kept). Can't fail: out of memory, the line is counted as dropped. */
void joblog_add(joblog *l, double wall, const char *fmt, ...) __attribute__((format(printf, 3, 4)));

/* Append the line that tells a farm event. */
void joblog_add_event(joblog *l, double wall, const farm_event *e);

/* Lines kept now, and lines dropped so far (the oldest, beyond JOBLOG_MAX). */
int joblog_count(const joblog *l);
uint64_t joblog_dropped(const joblog *l);

/* Add the log to o: "dropped": N and "lines": [{"t": epoch, "text": ...}],
 * oldest first, at most the last max lines (max <= 0: all). Returns 0, or
 * -1 when out of memory. */
int joblog_to_json(const joblog *l, cJSON *o, int max);

#endif
