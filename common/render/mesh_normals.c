/* mesh_normals.c - corner normals from face normals with an angle threshold
 * (mesh_normals.h). Vertex -> faces adjacency in compressed rows, then per
 * corner a sum over the vertex's faces, in face order (deterministic). The
 * face normals and the corners are computed in ranges of triangles on
 * every core (par.h): each triangle's own entries, the same numbers. */
#include "mesh_normals.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "par.h"

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

/* The work of one mesh_normals_from_faces call, shared by its ranges. */
typedef struct {
    const obj_mesh *m;
    double cos_max;
    double *fn;          /* 3 per triangle: face normals */
    const size_t *start; /* vertex v's faces are faces[start[v] .. start[v + 1]) */
    const uint32_t *faces;
    float *normals; /* 3 per corner */
    uint32_t *nidx;
} smooth_job;

/* Face normals of triangles [b, e). */
static void face_normals(void *ctx, size_t b, size_t e, int part) {
    smooth_job *J = ctx;
    (void)part;
    for (size_t t = b; t < e; t++) face_normal(J->m, t, J->fn + 3 * t);
}

/* Corner normals of triangles [b, e): each corner's face normal plus those
 * of the vertex's other faces within the angle, normalised. */
static void corner_normals(void *ctx, size_t b, size_t e, int part) {
    const smooth_job *J = ctx;
    const obj_mesh *m = J->m;
    const size_t *start = J->start;
    double cos_max = J->cos_max;
    (void)part;
    for (size_t t = b; t < e; t++) {
        const double *n = J->fn + 3 * t;
        double ln = sqrt(dot3(n, n));
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->indices[3 * t + k];
            double sum[3] = {n[0], n[1], n[2]};
            size_t valence = start[v + 1] - start[v];
            for (size_t i = start[v]; valence <= MESH_NORMALS_MAX_VALENCE && ln > 0 && i < start[v + 1]; i++) {
                const double *g = J->fn + 3 * J->faces[i];
                double lg = sqrt(dot3(g, g));
                if (J->faces[i] == t || !(lg > 0) || dot3(n, g) < cos_max * ln * lg) continue;
                for (int a = 0; a < 3; a++) sum[a] += g[a];
            }
            double ls = sqrt(dot3(sum, sum));
            float *out = J->normals + 3 * (3 * t + (size_t)k);
            for (int a = 0; a < 3; a++) out[a] = ls > 0 ? (float)(sum[a] / ls) : 0.0f;
            J->nidx[3 * t + (size_t)k] = (uint32_t)(3 * t + (size_t)k);
        }
    }
}

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
    smooth_job J = {m, cos_max, fn, start, faces, normals, nidx};
    int parts = par_parts(T, 1 << 14);
    par_run(T, parts, face_normals, &J);
    for (size_t t = 0; t < T; t++)
        for (int k = 0; k < 3; k++) start[m->indices[3 * t + k] + 1]++;
    for (size_t v = 0; v < V; v++) start[v + 1] += start[v];
    for (size_t t = 0; t < T; t++)
        for (int k = 0; k < 3; k++) {
            uint32_t v = m->indices[3 * t + k];
            faces[start[v] + fill[v]++] = (uint32_t)t;
        }
    par_run(T, parts, corner_normals, &J);
    free(fn);
    free(start);
    free(faces);
    free(fill);
    m->normals = normals;
    m->normal_count = 3 * T;
    m->normal_indices = nidx;
    return 0;
}
