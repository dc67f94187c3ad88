/* model_files.h - the files a model (glTF, GLB, OBJ + MTL) is made of.
 *
 * Used on both sides of the wire: the client gathers every file a model
 * references into the scene bundle (scene_bundle.c), the importer
 * (import.c) finds them there again under the same names. A referenced file
 * is named relative to the scene's folder, like a mesh: its URI or path
 * joined to the folder of the file that references it, percent-decoded
 * (glTF URIs), with "." and "dir/.." segments removed. */
#ifndef TESSERA_MODEL_FILES_H
#define TESSERA_MODEL_FILES_H

#include <stddef.h>

#include "scene_bundle.h"

typedef enum { MODEL_NONE, MODEL_GLTF, MODEL_GLB, MODEL_OBJ, MODEL_MTL } model_kind;

/* What a file name says it is, by its extension (case-insensitive). */
model_kind model_kind_of(const char *name);

/* Join rel (a glTF URI or an OBJ/MTL path) to the folder of base, into out.
 * Returns 0, or -1 when the result does not fit, is absolute, or climbs
 * above the scene's folder is fine (kept as "../x"). */
int model_join(const char *base, const char *rel, int percent_decode, char *out, size_t out_len);

/* Call cb(ctx, name) for each file the model file `name` (contents data,
 * len) references: glTF buffers and images that are not data: URIs, OBJ
 * mtllib files, MTL map_Kd textures. Malformed input references nothing
 * (the importer reports it). Returns the first non-zero cb result, else 0. */
int model_references(const char *name, const char *data, size_t len, int (*cb)(void *ctx, const char *name),
                     void *ctx);

/* The JSON text of the scene that `tessera render model.glb` renders: the
 * model imported whole ({"import": {"file": BASENAME}}, and "camera": camera
 * when not NULL). malloc'd, or NULL when out of memory. */
char *model_scene_json(const char *path, const char *camera, size_t *len);

/* If entry 0 of b is such a scene, select camera `camera` in it. Returns 0,
 * or -1 with a reason in err (not a model scene, out of memory). */
int model_bundle_select_camera(scene_bundle *b, const char *camera, char *err, size_t err_len);

/* Extract the JSON chunk of a binary glTF and, when present, its BIN chunk.
 * Returns 0, or -1 with "NAME: reason" in err (bad magic, version, or a
 * header or chunk length that does not match the file: truncated). */
int model_glb_chunks(const char *name, const char *data, size_t len, const char **json, size_t *json_len,
                     const char **bin, size_t *bin_len, char *err, size_t err_len);

#endif
