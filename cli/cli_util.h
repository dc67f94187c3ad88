/* cli_util.h - small pieces the command-line front ends share. */
#ifndef TESSERA_CLI_UTIL_H
#define TESSERA_CLI_UTIL_H

#include <stddef.h>

/* Draw "\r[####....] done/total tiles  R Msamples/s  [W workers]  ETA Ns"
 * on stderr; workers < 0 leaves that part out; final ends the line. Can't
 * fail. */
void cli_progress(int done, int total, double samples_per_s, int workers, double eta_s, int final);

/* The default output for a scene: its base name with .png, in the current
 * folder ("scenes/box.json" -> "box.png"). Can't fail. */
void cli_default_output(const char *scene_path, char *out, size_t n);

#endif
