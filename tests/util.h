/* util.h - helpers shared by the tests: scene files from strings, images. */
#ifndef TESSERA_TEST_UTIL_H
#define TESSERA_TEST_UTIL_H

#include <stddef.h>

#include "render/render.h"
#include "render/scene.h"

/* Write text to a new file under a fresh temporary folder; returns its path
 * (static storage, overwritten by the next call). */
const char *util_write_temp(const char *name, const char *text);

/* A path for name under the tests' temporary folder, without creating the
 * file (static storage, overwritten by the next call). */
const char *util_temp_path(const char *name);

/* Load a scene from JSON text; on failure returns NULL with the error. */
scene *util_scene_from_text(const char *json, char *err, size_t err_len);

/* Corner k (0-2) of triangle prim's shading normals into *out: 1 when the
 * triangle has them (scene.h: in the range, not zero), else 0. */
int util_corner_normal(const scene *s, uint32_t prim, int k, vec3 *out);

/* The triangles with shading normals, and the distinct normals (by bits)
 * among their corners: what an indexed store would have kept. */
size_t util_smooth_triangles(const scene *s);
size_t util_distinct_corner_normals(const scene *s);

/* Render the whole frame single-threaded (or with opt) into a malloc'd float
 * buffer of width*height*3; NULL on failure. */
float *util_render(const scene *s, int threads, int tile, int passes, trace_stats *st);

/* Run a shell command, capture up to cap bytes of its stdout+stderr into out;
 * returns the exit status (or -1). */
int util_run(const char *cmd, char *out, size_t cap);

/* `tessera ARGS` (the binary under test) against the coordinator or job
 * service at addr (TESSERA_COORDINATOR); output in out, returns the exit
 * status as util_run. */
int util_cli(const char *addr, char *out, size_t cap, const char *args);

/* ---- processes (farm tests) ---- */

#include <sys/types.h>

/* Path of a program built next to $TESSERA_BIN ("tessera",
 * "tessera-worker"); static storage. */
const char *util_bin(const char *name);

/* Start argv (NULL-terminated) with stdout and stderr appended to log_path
 * and stdin from /dev/null. Returns the pid, or -1. */
pid_t util_spawn(const char *const *argv, const char *log_path);

/* util_spawn with extra environment variables ("NAME=VALUE", NULL-terminated)
 * set in the child only. */
pid_t util_spawn_env(const char *const *argv, const char *log_path, const char *const *env);

/* A worker process started with util_spawn_env and
 * {"TESSERA_TEST_HOLD_FILE=" hold, ...} keeps every finished tile (after
 * its first $TESSERA_TEST_HOLD_AFTER) while the file hold exists, and logs
 * this text when it starts keeping one (worker/pool.c, test_hold). Tests
 * create the file, wait for the text, act, then remove the file: events,
 * not the machine's speed, decide what is "mid-render". */
#define UTIL_HOLDING "test hold: keeping tile"

/* Create an empty file at path (0, or -1). */
int util_touch(const char *path);

/* Wait up to timeout_s for pid to exit. Returns its exit status (128 + the
 * signal if killed); on timeout kills it with SIGKILL and returns -1.
 * maxrss_kb, if not NULL, receives its peak resident memory. */
int util_wait(pid_t pid, double timeout_s, long *maxrss_kb);

/* Seconds on a clock that only goes forward (CLOCK_MONOTONIC). */
double util_now(void);

/* Wait up to timeout_s until the file at path contains text. Returns 0 or
 * -1 on timeout. */
int util_wait_for_text(const char *path, const char *text, double timeout_s);

/* Whether the file at path contains text (0/1); count how often. */
int util_file_count(const char *path, const char *text);

/* A TCP port on 127.0.0.1 that was free a moment ago, below the ephemeral
 * range and never the same twice in a run (util.c says why); -1 if none. */
int util_free_port(void);

/* A socket listening on 127.0.0.1 at a port the kernel picks (held open,
 * so no race), with this backlog; returns it with its port in *port, or
 * -1. */
int util_listen_loopback(int backlog, int *port);

/* Whole-file comparison: 1 when both exist and are byte-identical. */
int util_same_file(const char *a, const char *b);

/* From a job service's log: job 1's tiles resumed from its journal at the
 * restart ("job 1 resumed: N of 64"), and then at its end the tiles from
 * the journal and the ones rendered in that run ("job 1 done (N tiles from
 * the journal, M rendered"). Each stays -1 when its line is missing. */
void util_resume_counts(const char *log, int *resumed, int *from_journal, int *rendered);

/* Whether /usr/bin/qemu-x86_64 is there to emulate an older CPU. When it
 * is not, returns 0 and fails the calling test (`make` installs qemu-user,
 * so a missing emulator is a broken machine, not a test to pass unchecked),
 * or only prints a "skipped" line when TESSERA_TESTS_WITHOUT_QEMU is set. */
int util_have_qemu(void);

/* Run `TESSERA ARGS -o NATIVE` on this CPU, then the same program under
 * `qemu-x86_64 -cpu Nehalem-v1` (SSE4.2, no AVX or FMA) -o EMULATED (both
 * temporary files named after tag). Returns 0 when both ran and wrote the
 * same bytes, with the emulated run's output in out; else -1 with the
 * command and its output, or the difference, in out. */
int util_same_under_nehalem(const char *tessera, const char *args, const char *tag, char *out, size_t cap);

/* Sleep for the given seconds. */
void util_sleep(double s);

#endif
