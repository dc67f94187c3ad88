/* obj.h - a reader for the geometry part of Wavefront OBJ files.
 *
 * Reads `v`, `vn`, `vt` and `f` records (polygons are fan-triangulated, the
 * v/vt/vn, v//vn, v/vt and negative-index forms are accepted, every index is
 * checked). Groups, materials and everything else are skipped. */
#ifndef TESSERA_OBJ_H
#define TESSERA_OBJ_H

#include <stddef.h>
#include <stdint.h>

#define OBJ_NONE UINT32_MAX /* a corner without a normal or texture coordinate */

typedef struct {
    double *positions;  /* 3 per vertex */
    size_t vertex_count;
    uint32_t *indices;  /* 3 per triangle, into positions */
    size_t triangle_count;
    float *normals;     /* `vn`: 3 per normal, as written (not normalised); NULL if none */
    size_t normal_count;
    float *uvs;         /* `vt`: 2 per texture coordinate (u, v); NULL if none */
    size_t uv_count;
    uint32_t *normal_indices; /* 3 per triangle into normals, OBJ_NONE for a face without; NULL if no face has any */
    uint32_t *uv_indices;     /* likewise into uvs */
} obj_mesh;

/* Parse the OBJ text in buf (len bytes, need not be NUL-terminated). On
 * success fills *out and returns 0; the caller frees it with obj_mesh_free.
 * On error returns -1 and writes "NAME:LINE: what is wrong" to err, where
 * NAME is `name` (usually the file's path). */
int obj_parse(const char *buf, size_t len, const char *name, obj_mesh *out, char *err, size_t err_len);

/* Parse buf in `parts` spans cut at line ends, in parallel (what obj_parse
 * does with a big text on a machine with cores to spare): on success the
 * same mesh as obj_parse's, bit for bit. Returns -1 (and *out empty) for
 * any text obj_parse refuses, and for some it accepts (a face written
 * oddly, e.g. with a vertical tab between corners), without a message:
 * obj_parse then parses it in one pass. parts: 1 to 8. */
int obj_parse_spans(const char *buf, size_t len, const char *name, int parts, obj_mesh *out);

/* Read and parse an OBJ file; same contract as obj_parse, plus errors for
 * files that can't be read. */
int obj_load(const char *path, obj_mesh *out, char *err, size_t err_len);

/* Free what obj_parse allocated; the struct itself is the caller's. */
void obj_mesh_free(obj_mesh *m);

#endif
