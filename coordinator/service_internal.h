/* service_internal.h - the job service's state, shared by its two files and
 * no one else (the public interface is service.h):
 *   jobstore.c - the job store and journal: jobs on disk, tiles journaled as
 *                they land, restart from the journal;
 *   service.c  - the service: client requests (submit, status, workers,
 *                cancel, fetch), expiry, signals, start-up;
 *   admission.c - jobs admitted within --max-memory, or waiting for it.
 *
 * Data dir layout (every file written whole to a temporary name, synced and
 * renamed, except the tile journal, which is appended and synced in batches
 * off the loop thread, tjournal.h, and the event log, appended off the loop
 * without a sync, joblog.h):
 *   scenes/HASH     uploaded scene bundles, named by their BLAKE2b hash
 *   jobs/ID.json    a job: what to render and its state
 *   jobs/ID.tiles   finished tiles of a running job: records of
 *                   u32 magic, u32 tile, u32 float count, floats, u32 check
 *   jobs/ID.pfm     the finished image
 *   jobs/ID.log     the job's event log, "EPOCH TEXT" a line (tessera logs)
 * A tile counts as done only after its record is on disk, so after kill -9
 * and a restart every journalled tile is kept and only the others are
 * rendered again. Nothing a client sends names a path: scenes are stored by
 * hash, jobs by number. */
#ifndef TESSERA_SERVICE_INTERNAL_H
#define TESSERA_SERVICE_INTERNAL_H

#include <dirent.h>
#include <errno.h>
#include <fcntl.h>
#include <inttypes.h>
#include <signal.h>
#include <stdarg.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <time.h>
#include <unistd.h>
#include <uv.h>

#include "fileio.h"
#include "image/image.h"
#include "limit.h"
#include "list.h"
#include "log.h"
#include "net/conn.h"
#include "net/wire.h"
#include "render/scene.h"
#include "data_lock.h"
#include "journal.h"
#include "tjournal.h"
#include "loopstat.h"
#include "upload.h"
#include "joblog.h"
#include "fetch.h"
#include "membudget.h"
#include "service.h"

typedef enum { SJOB_RUNNING, SJOB_DONE, SJOB_FAILED, SJOB_CANCELLED } sjob_state;
static const char *const state_names[] = {"running", "done", "failed", "cancelled"};

/* A job of the service: what to render, its state, and while it runs its
 * frame and open tile journal. */
typedef struct sjob {
    struct service *svc;
    proto_job desc;
    char name[256]; /* the scene's file name, for people */
    char submitter[160]; /* "USER at ADDR" of the client that submitted it */
    joblog *log;         /* its events while kept in memory (joblog.h) */
    char owner[128]; /* the name of the client that submitted it ("" before tokens had classes) */
    int priority, tile_size, tile_count;
    sjob_state state;
    char error[512];
    float *rgb;         /* while running */
    uint8_t *journaled; /* tiles on disk before this run */
    int tiles_done, tiles_resumed;
    trace_stats stats;
    double first_tile; /* wall clock when this run handed out its first tile (0: queued so far) */
    double submitted, started, finished; /* wall clock, seconds */
    struct tjournal *journal; /* while running: tiles synced off the loop (tjournal.h) */
    uv_timer_t *save_timer;   /* rendered, waiting for space to save the image */
    /* Adaptive sampling (noise_threshold > 0): one farm job per round, with
     * its own farm id (farm_id; desc.id otherwise), the next submitted from
     * round_timer once the farm has finished calling back about the last.
     * Rounds are not journaled: a restart renders the job again from round
     * 0, which gives the same bytes. */
    double noise_threshold;
    int min_spp;
    uint32_t farm_id;
    struct adaptive *ad;
    float *sums;             /* the round's sums (ADAPTIVE_CHANNELS per pixel) */
    uint8_t *mask, *skip;    /* the round's pixels, and its tiles without any */
    conn_blob *scene;        /* the scene's frame, shared by every round (a reference) */
    trace_stats round_stats; /* of the rounds before the current one */
    uv_timer_t *round_timer;
    uint64_t need;            /* bytes it holds once admitted (membudget_job_bytes) */
    int waiting;              /* running but not admitted: waits for --max-memory (admission.c) */
    int admitting;            /* admitted, its scene being read off the loop (admission.c) */
    int saving;               /* rendered, its image being written off the loop (jobstore.c) */
    int restarting;           /* running when the coordinator stopped; resumed through admission (its
                               * scene read and journal replayed off the loop) at start-up */
    TAILQ_ENTRY(sjob) link; /* on the service's jobs, oldest first */
} sjob;

typedef struct service {
    service_options o;
    uv_loop_t loop;
    farm *f;
    uv_signal_t sigint, sigterm;
    uv_signal_t sighup;    /* re-reads the token files (on_sighup) */
    uv_timer_t expiry;
    uv_timer_t stat_timer; /* -v: the longest loop iteration every 10 s */
    loopstat stat;         /* loop stalls (loopstat.h); svc_longest_stall_ms */
    upload_queue uploads;  /* scenes being checked off the loop (upload.h) */
    uv_timer_t sweep;      /* closes idle and trickling clients every second */
    uv_timer_t admit;      /* admits waiting jobs once a job has released its memory */
    TAILQ_HEAD(client_list, client) clients;
    TAILQ_HEAD(sjob_list, sjob) jobs;
    uint32_t next_id;
    uint32_t next_round; /* farm ids of adaptive rounds: SVC_ROUND_IDS + n */
    int stopping;
    struct dashboard *web; /* --http, or NULL (service_web.c) */
    size_t fetch_chunk;    /* bytes per D frame of a fetched image (fetch.h) */
    uint64_t next_partial; /* names jobs/ID.partial-N.pfm, a partial fetch's image while it is made */
} service;

/* Farm ids of adaptive rounds start here, above any job number the service
 * hands out, so that a round's id never names a job. */
#define SVC_ROUND_IDS 0x80000000u

/* What a submit asks besides its scene, kept while the scene is checked. */
typedef struct {
    long priority, tile_size, min_spp;
    double noise_threshold; /* 0: every pixel takes spp samples */
    sampler_kind sampler;
    int no_nee, no_mis;
    char name[256];
    char user[64]; /* who the client says submits it ("" when not said) */
} submit_req;

/* A connected client (submit, status, ...). */
typedef struct client {
    service *svc;
    conn *c;
    char addr[64];
    char name[128];  /* from its hello (bound to its proof when there are tokens) */
    auth_class cls;  /* the credential it proved; AUTH_ADMIN without tokens */
    int keyed;       /* with tokens: key is the key it proved */
    unsigned char key[AUTH_KEY_BYTES]; /* to tell whether SIGHUP took it away */
    uint8_t *bundle; /* the last scene uploaded, inside bundle_mem */
    uint8_t *bundle_mem; /* owned: its frame's memory */
    size_t bundle_len;
    int validating;  /* a submit's scene is on the upload queue */
    int closed;      /* gone while validating: freed when the check ends */
    submit_req req;  /* that submit's other fields */
    fetch_stream *fetch; /* an image being sent (fetch.h), or NULL */
    uint64_t seen_bytes;           /* conn_bytes_in at the last sweep */
    double last_bytes, last_frame; /* monotonic seconds: last byte, last whole frame */
    uint64_t window_bytes;         /* bytes in the current 10 s window while mid-frame */
    double window_start;
    TAILQ_ENTRY(client) link;      /* on the service's clients while connected */
} client;

/* ---- shared between the files ---- */

/* DATA_DIR/jobs/ID.EXT into out. Can't fail (truncates). */
void store_job_path(const service *s, uint32_t id, const char *ext, char *out, size_t n);

/* Write jobs/ID.json atomically. Returns 0, or -1 with "PATH: reason". */
int store_save_job(sjob *j, char *err, size_t err_len);

/* The job with this id, or NULL. */
sjob *store_find_job(service *s, uint32_t id);

/* The job whose farm job (itself, or its current adaptive round) has this
 * farm id, or NULL. */
sjob *store_find_farm_job(service *s, uint32_t farm_id);

/* farm_job_cb of every service job (ctx: the sjob): progress, and at the end
 * the image saved, the journal closed and the state recorded. */
void store_on_job_event(void *ctx, const farm_report *r, int done);

/* Hand a job (new or resumed) to the farm, opening its tile journal;
 * framed (may be NULL): the bundle already framed for the farm
 * (farm_job_options.scene), shared instead of copied. */
int store_job_start(service *s, sjob *j, const uint8_t *bundle, size_t len, conn_blob *framed, char *err,
                    size_t err_len);

/* Cancel a running job on the farm (its current round, if adaptive).
 * Returns 0, or -1 when the farm has no such running job. */
int store_job_cancel(service *s, sjob *j);

/* A new job with the next id, linked into s->jobs, or NULL when out of
 * memory. */
sjob *store_job_new(service *s);

/* Keep j's log in jobs/ID.log too (joblog_persist): existing for a job
 * read back at a restart, else a new one's (the file emptied). Can't fail:
 * a file that cannot be opened is logged and the log stays in memory. */
void store_job_persist_log(service *s, sjob *j, int existing);

/* Take j out of s->jobs and free it (its files stay). */
void store_job_unlink_free(service *s, sjob *j);

/* Change a queued or running job's priority: saved in its job file, told
 * to the farm, logged with who (e.g. "the dashboard"). Returns 0, or -1
 * with the reason in err (unknown job, out of range, finished, cannot save). */
int store_set_priority(service *s, uint32_t id, long priority, const char *who, char *err, size_t err_len);

/* How many jobs are running (queued or rendering). */
int store_running_jobs(const service *s);

/* Start a job that has no frame yet (resumed, or admitted after waiting):
 * its scene read from scenes/HASH, its frame made, its journal replayed,
 * handed to the farm. Returns 0, or -1 with the job failed and saved. */
int store_job_resume(service *s, sjob *j);

/* What a job resumed after a restart starts from: its frame and done
 * tiles replayed from its journal (a torn or corrupt tail
 * cut off the file). store_resume_prepare touches no service or job state,
 * so admission runs it on the thread pool with the scene's read: a long
 * journal is not replayed on the loop. */
typedef struct {
    float *rgb;
    uint8_t *journaled;
    int tiles_resumed;
    size_t journal_len, journal_good; /* good < len: a tail was cut off */
    int truncate_errno;               /* the cut failed with it (0: fine) */
    char journal[4096];               /* the journal's path */
} store_resume;

/* Fill r for a job of width x height cut in tiles of tile_size
 * (tile_count of them) whose journal is at journal. Returns 0, or -1 when
 * out of memory (r then holds nothing to free). On any thread. */
int store_resume_prepare(const char *journal, int width, int height, int tile_size, int tile_count, store_resume *r);

/* Free what r still holds (store_job_resume_with takes the frame and the
 * done tiles). Can be called again. */
void store_resume_free(store_resume *r);

/* store_job_resume with the scene already read and the journal replayed:
 * bundle (len bytes; NULL when reading failed, read_err saying why), if not
 * NULL the same bytes framed for the farm (a reference is taken), and r
 * (NULL or r->rgb NULL: out of memory), whose frame and done tiles j takes.
 * The caller keeps and frees bundle, framed and r. */
int store_job_resume_with(service *s, sjob *j, const uint8_t *bundle, size_t len, conn_blob *framed,
                          const char *read_err, store_resume *r);

/* The path of j's scene in the data dir: scenes/HASH. */
void store_scene_path(const service *s, const sjob *j, char *path, size_t path_len);

/* ---- admission.c ---- */

/* Bytes held by admitted jobs (those with a frame), and how many (jobs may
 * be NULL). */
uint64_t svc_memory_in_use(const service *s, int *jobs);

/* Whether j (its need set) may be admitted now: 0; 1 when it must wait
 * (why: the note for status); -1 when it never fits (why: the refusal,
 * with the figures). */
int svc_admit_check(const service *s, const sjob *j, char *why, size_t why_len);

/* Admit every waiting job that fits now, oldest first. */
void svc_admit_waiting(service *s);

/* A job released its frame: admit waiting jobs from the loop's next turn
 * (not from inside the farm's or the store's callback that freed it).
 * Nothing once the service stops. Can't fail. */
void svc_memory_released(service *s);

/* Whether j may be cancelled now: 0, or -1 with the reason (no newline)
 * into why: it is over already, or rendered and its image being written
 * (or waiting for disk space to be). why may be NULL with len 0. */
int svc_cancel_refused(const sjob *j, char *why, size_t len);

/* Cancel a running job: a waiting one at once, else through the farm.
 * Nothing when svc_cancel_refused refuses it. */
void svc_cancel_job(service *s, sjob *j);

/* Resume every job in the data dir, oldest first. */
void store_load_jobs(service *s);

/* Expire finished jobs (--keep-hours), keep at most --keep-jobs, remove
 * scenes no job names (retention.c). Returns 1 when more is left to do. */
int retention_sweep(service *s);

/* A log line (log.h) from the service. */
void svc_log(const char *fmt, ...) __attribute__((format(printf, 1, 2)));

/* Start the dashboard when --http was given (service_web.c). Returns 0,
 * or -1 with the reason in err. */
int service_web_start(service *s, char *err, size_t err_len);

/* The farm's event callback (farm_set_event_cb) of the service: each
 * event goes to its job's log (a worker joining or leaving: to every
 * running job's) and on to the dashboard when there is one. */
void service_on_farm_event(void *ctx, const farm_event *e);

/* Stop it (when started). Can't fail. */
void service_web_stop(service *s);
/* The longest busy iteration of the service's loop so far, in ms (for the
 * status answer and a dashboard). */
double svc_longest_stall_ms(const service *s);

/* Monotonic seconds (for timeouts). */
double svc_mono_now(void);

/* Wall-clock seconds since the epoch. */
double svc_wall_now(void);

#endif
