/* util.h - helpers shared by the tests: scene files from strings, images. */
#ifndef TESSERA_TEST_UTIL_H
#define TESSERA_TEST_UTIL_H

#include <stddef.h>

#include "../common/render.h"
#include "../common/scene.h"

/* Write text to a new file under a fresh temporary folder; returns its path
 * (static storage, overwritten by the next call). */
const char *util_write_temp(const char *name, const char *text);

/* Load a scene from JSON text; on failure returns NULL with the error. */
scene *util_scene_from_text(const char *json, char *err, size_t err_len);

/* Render the whole frame single-threaded (or with opt) into a malloc'd float
 * buffer of width*height*3; NULL on failure. */
float *util_render(const scene *s, int threads, int tile, int passes, trace_stats *st);

/* Run a shell command, capture up to cap bytes of its stdout+stderr into out;
 * returns the exit status (or -1). */
int util_run(const char *cmd, char *out, size_t cap);

#endif
