/* cli_util.h - small pieces the command-line front ends share. */
#ifndef TESSERA_CLI_UTIL_H
#define TESSERA_CLI_UTIL_H

#include <stddef.h>

/* Draw "\r[####....] done/total tiles  R Msamples/s  [W workers]  ETA Ns"
 * on stderr; workers < 0 leaves that part out; final ends the line. Can't
 * fail. */
void cli_progress(int done, int total, double samples_per_s, int workers, double eta_s, int final);

/* Progress for people, wherever stderr goes: on a terminal the bar above,
 * redrawn; otherwise (a log file, a pipe, a batch system) one plain line
 *   "progress: 12/64 tiles (18%), 2.31 Msamples/s, 4 workers, ETA 5s"
 * every `every` seconds and one at the end. every is 5, or
 * $TESSERA_PROGRESS_SECONDS when set (tests use a short one). */
typedef struct {
    int tty;
    double every, last; /* plain lines: interval, and when the last went out */
} cli_progress_state;

/* Set p up for stderr as it is now. Can't fail. */
void cli_progress_init(cli_progress_state *p);

/* Show progress as p says (see above); final ends it. Can't fail. */
void cli_progress_show(cli_progress_state *p, int done, int total, double samples_per_s, int workers, double eta_s,
                       int final);

/* The default output for a scene: its base name with .png, in the current
 * folder ("scenes/box.json" -> "box.png"; "-", stdin: "stdin.png"). Can't
 * fail. */
void cli_default_output(const char *scene_path, char *out, size_t n);

/* Scene "-" with stdin a terminal: say that the scene is read from it and
 * how to end it, so the wait is not mistaken for a hang. Can't fail. */
void cli_note_terminal_scene(const char *scene_path);

#endif
