/* scene_bundle.h - a scene file and every file it references, in memory.
 *
 * A bundle is what travels to a worker: the scene's JSON text plus the
 * contents of its OBJ meshes, keyed by the name the scene uses for them. A
 * worker loads the scene from the bundle alone, so it needs no shared
 * filesystem, and the bundle's serialised bytes name it: their BLAKE2b hash
 * is the key under which workers cache the loaded scene.
 *
 * Serialised form (all integers little-endian):
 *   u32 entry count, then per entry: u32 name length, name bytes,
 *   u32 data length, data bytes.
 * Entry 0 is the scene itself (name = the scene's path for messages). */
#ifndef TESSERA_SCENE_BUNDLE_H
#define TESSERA_SCENE_BUNDLE_H

#include <stddef.h>
#include <stdint.h>

#include "limit.h"

#define SCENE_BUNDLE_MAX_BYTES LIMIT_BUNDLE_BYTES /* scene plus meshes */
#define SCENE_BUNDLE_MAX_FILES LIMIT_BUNDLE_FILES
#define SCENE_BUNDLE_HASH_HEX 65 /* 32-byte BLAKE2b as hex, plus NUL */

typedef struct {
    char *name;  /* as written in the scene ("meshes/bunny.obj") */
    char *data;  /* contents, NUL-terminated; NULL if it could not be read */
    size_t len;
    char *error; /* why data is NULL ("meshes/x.obj: No such file ..."), else NULL */
    int streamed; /* a model read from stdin or a pipe ("stdin.glb"): no file of that name */
} scene_bundle_file;

typedef struct {
    scene_bundle_file *files; /* files[0] is the scene JSON */
    size_t count;
} scene_bundle;

/* The folder a scene at path resolves relative names against, into out:
 * path's own folder ("." when it has none); the current folder for "-"
 * (stdin) and for the shell's <(...) (/dev/fd/N, /proc/self/fd/N), whose
 * folder means nothing. Can't fail (truncates to n). */
void scene_bundle_folder(const char *path, char *out, size_t n);

/* Read the scene at path and every mesh it names (relative names are
 * relative to scene_bundle_folder; path "-" reads the scene from stdin and
 * names it "<stdin>"; a pipe is read to its end, as stdin). Returns 0, or
 * -1 with "PATH: reason" in err when the scene file itself can't be read. A mesh that can't be read is
 * kept as an entry with data NULL and its error, so that scene loading
 * reports it against the field that names it. Free with scene_bundle_free. */
int scene_bundle_read(const char *path, scene_bundle *out, char *err, size_t err_len);

/* Serialise the readable entries to a malloc'd buffer (the caller frees).
 * Returns NULL when out of memory or over SCENE_BUNDLE_MAX_BYTES. */
uint8_t *scene_bundle_serialise(const scene_bundle *b, size_t *len);

/* Parse serialised bytes into *out (which then owns copies). Returns 0, or
 * -1 with the reason in err when the bytes are not a well-formed bundle. */
int scene_bundle_parse(const uint8_t *buf, size_t len, scene_bundle *out, char *err, size_t err_len);

/* The entry named name (not entry 0), or NULL. */
const scene_bundle_file *scene_bundle_find(const scene_bundle *b, const char *name);

/* BLAKE2b-256 of buf as lowercase hex into hex[SCENE_BUNDLE_HASH_HEX].
 * Can't fail. */
void scene_bundle_hash(const uint8_t *buf, size_t len, char hex[SCENE_BUNDLE_HASH_HEX]);

/* Free everything the bundle owns; the struct itself is the caller's. */
void scene_bundle_free(scene_bundle *b);

#endif
