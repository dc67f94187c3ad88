/* obj.h - a reader for the geometry part of Wavefront OBJ files.
 *
 * Reads `v` and `f` records (polygons are fan-triangulated, the v/vt/vn,
 * v//vn and negative-index forms are accepted; texture coordinates, normals,
 * groups and materials are ignored). Everything else is skipped. */
#ifndef TESSERA_OBJ_H
#define TESSERA_OBJ_H

#include <stddef.h>
#include <stdint.h>

typedef struct {
    double *positions;  /* 3 per vertex */
    size_t vertex_count;
    uint32_t *indices;  /* 3 per triangle, into positions */
    size_t triangle_count;
} obj_mesh;

/* Parse the OBJ text in buf (len bytes, need not be NUL-terminated). On
 * success fills *out and returns 0; the caller frees it with obj_mesh_free.
 * On error returns -1 and writes "NAME:LINE: what is wrong" to err, where
 * NAME is `name` (usually the file's path). */
int obj_parse(const char *buf, size_t len, const char *name, obj_mesh *out, char *err, size_t err_len);

/* Read and parse an OBJ file; same contract as obj_parse, plus errors for
 * files that can't be read. */
int obj_load(const char *path, obj_mesh *out, char *err, size_t err_len);

/* Free what obj_parse allocated; the struct itself is the caller's. */
void obj_mesh_free(obj_mesh *m);

#endif
