/* mesh_normals.c - corner normals from face normals with an angle threshold
 * (mesh_normals.h). Vertex -> faces adjacency in compressed rows, then per
 * corner a sum over the vertex's faces, in face order (deterministic). */
#include "mesh_normals.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

/* Unnormalised face normal of triangle t (length = twice its area). */
static void face_normal(const obj_mesh *m, size_t t, double n[3]) {
    const double *a = m->positions + 3 * m->indices[3 * t], *b = m->positions + 3 * m->indices[3 * t + 1],
                 *c = m->positions + 3 * m->indices[3 * t + 2];
    double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
    n[0] = e1[1] * e2[2] - e1[2] * e2[1];
    n[1] = e1[2] * e2[0] - e1[0] * e2[2];
    n[2] = e1[0] * e2[1] - e1[1] * e2[0];
}

static double dot3(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }

int mesh_normals_from_faces(obj_mesh *m, double max_angle_deg) {
    size_t T = m->triangle_count, V = m->vertex_count;
    double cos_max = cos(max_angle_deg * 3.14159265358979323846 / 180.0);
    double *fn = malloc(3 * sizeof(double) * (T ? T : 1));
    size_t *start = calloc(V + 1, sizeof *start);
    uint32_t *faces = malloc(sizeof(uint32_t) * 3 * (T ? T : 1));
    float *normals = malloc(3 * sizeof(float) * 3 * (T ? T : 1));
    uint32_t *nidx = malloc(sizeof(uint32_t) * 3 * (T ? T : 1));
    size_t *fill = calloc(V + 1, sizeof *fill);
    if (!fn || !start || !faces || !normals || !nidx || !fill) {
        free(fn), free(start), free(faces), free(normals), free(nidx), free(fill);
        return -1;
    }
    for (size_t t = 0; t < T; t++) {
        face_normal(m, t, fn + 3 * t);
        for (int k = 0; k < 3; k++) start[m->indices[3 * t + k] + 1]++;
    }
    for (size_t v = 0; v < V; v++) start[v + 1] += start[v];
    for (size_t t = 0; t < T; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->indices[3 * t + k];
            faces[start[v] + fill[v]++] = (uint32_t)t;
        }
    for (size_t t = 0; t < T; t++) {
        const double *n = fn + 3 * t;
        double ln = sqrt(dot3(n, n));
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->indices[3 * t + k];
            double sum[3] = {n[0], n[1], n[2]};
            size_t valence = start[v + 1] - start[v];
            for (size_t i = start[v]; valence <= MESH_NORMALS_MAX_VALENCE && ln > 0 && i < start[v + 1]; i++) {
                const double *g = fn + 3 * faces[i];
                double lg = sqrt(dot3(g, g));
                if (faces[i] == t || !(lg > 0) || dot3(n, g) < cos_max * ln * lg) continue;
                for (int a = 0; a < 3; a++) sum[a] += g[a];
            }
            double ls = sqrt(dot3(sum, sum));
            float *out = normals + 3 * (3 * t + (size_t)k);
            for (int a = 0; a < 3; a++) out[a] = ls > 0 ? (float)(sum[a] / ls) : 0.0f;
            nidx[3 * t + (size_t)k] = (uint32_t)(3 * t + (size_t)k);
        }
    }
    free(fn);
    free(start);
    free(faces);
    free(fill);
    m->normals = normals;
    m->normal_count = 3 * T;
    m->normal_indices = nidx;
    return 0;
}
