/* icosphere.c - write a unit icosphere as a Wavefront OBJ, for the mesh
 * benchmarks (bench/meshes.sh) and the mesh tests.
 *
 * The icosahedron's 20 faces are split into 4 at each level, the new edge
 * midpoints pushed out onto the unit sphere: level L has 20 * 4^L triangles
 * (5: 20,480; 7: 327,680; 8: 1,310,720; 9: 5,242,880), wound counter-
 * clockwise seen from outside, sharing vertices (so the mesh is closed).
 * With --normals, each vertex also gets its exact normal (`vn`), and faces
 * name them (v//vn).
 *
 * usage: icosphere LEVEL [--normals] > sphere.obj */
#include <math.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct {
    double *v;          /* 3 per vertex */
    size_t nv, cap_v;
    uint32_t *f;        /* 3 per face */
    size_t nf;
    uint64_t *keys;     /* edge midpoint cache: key (a << 32 | b, a < b) + 1, 0 = empty */
    uint32_t *vals;
    size_t hash_cap;
} mesh;

static void *xrealloc(void *p, size_t n) {
    p = realloc(p, n);
    if (!p) {
        fprintf(stderr, "icosphere: out of memory\n");
        exit(1);
    }
    return p;
}

static uint32_t add_vertex(mesh *m, double x, double y, double z) {
    if (m->nv == m->cap_v) {
        m->cap_v = m->cap_v ? 2 * m->cap_v : 64;
        m->v = xrealloc(m->v, m->cap_v * 3 * sizeof(double));
    }
    double l = sqrt(x * x + y * y + z * z);
    m->v[3 * m->nv] = x / l;
    m->v[3 * m->nv + 1] = y / l;
    m->v[3 * m->nv + 2] = z / l;
    return (uint32_t)m->nv++;
}

/* The vertex halfway along edge (a, b) on the sphere, made once per edge. */
static uint32_t midpoint(mesh *m, uint32_t a, uint32_t b) {
    if (a > b) {
        uint32_t t = a;
        a = b;
        b = t;
    }
    uint64_t key = ((uint64_t)a << 32 | b) + 1;
    size_t i = (size_t)((key * 0x9E3779B97F4A7C15ull) >> 20) & (m->hash_cap - 1);
    while (m->keys[i] && m->keys[i] != key) i = (i + 1) & (m->hash_cap - 1);
    if (m->keys[i]) return m->vals[i];
    m->keys[i] = key;
    double *p = m->v + 3 * a, *q = m->v + 3 * b;
    return m->vals[i] = add_vertex(m, p[0] + q[0], p[1] + q[1], p[2] + q[2]);
}

int main(int argc, char **argv) {
    int level = argc > 1 ? atoi(argv[1]) : -1, normals = argc > 2 && strcmp(argv[2], "--normals") == 0;
    if (level < 0 || level > 10) {
        fprintf(stderr, "usage: icosphere LEVEL(0..10) [--normals] > sphere.obj\n");
        return 2;
    }
    mesh m = {0};
    double t = (1.0 + sqrt(5.0)) / 2.0;
    static const int ico_v[12][3] = {{-1, 1, 0}, {1, 1, 0}, {-1, -1, 0}, {1, -1, 0}, {0, -1, 1}, {0, 1, 1},
                                     {0, -1, -1}, {0, 1, -1}, {1, 0, -1}, {1, 0, 1}, {-1, 0, -1}, {-1, 0, 1}};
    static const uint32_t ico_f[20][3] = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11},
                                          {1, 5, 9},  {5, 11, 4}, {11, 10, 2}, {10, 7, 6}, {7, 1, 8},
                                          {3, 9, 4},  {3, 4, 2},  {3, 2, 6},   {3, 6, 8},  {3, 8, 9},
                                          {4, 9, 5},  {2, 4, 11}, {6, 2, 10},  {8, 6, 7},  {9, 8, 1}};
    for (int i = 0; i < 12; i++) { /* (a, b, c) uses b for the golden ratio coordinate */
        double c[3];
        for (int k = 0; k < 3; k++) c[k] = ico_v[i][k] == 0 ? 0 : ico_v[i][k];
        if (i < 4) c[1] *= t;
        else if (i < 8) c[2] *= t;
        else c[0] *= t;
        add_vertex(&m, c[0], c[1], c[2]);
    }
    m.nf = 20;
    m.f = xrealloc(NULL, sizeof ico_f);
    memcpy(m.f, ico_f, sizeof ico_f);
    for (int l = 0; l < level; l++) {
        size_t edges = m.nf * 3 / 2;
        m.hash_cap = 1;
        while (m.hash_cap < 2 * edges) m.hash_cap *= 2;
        m.keys = xrealloc(NULL, m.hash_cap * sizeof *m.keys);
        m.vals = xrealloc(NULL, m.hash_cap * sizeof *m.vals);
        memset(m.keys, 0, m.hash_cap * sizeof *m.keys);
        uint32_t *nf = xrealloc(NULL, m.nf * 4 * 3 * sizeof(uint32_t));
        for (size_t i = 0; i < m.nf; i++) {
            uint32_t a = m.f[3 * i], b = m.f[3 * i + 1], c = m.f[3 * i + 2];
            uint32_t ab = midpoint(&m, a, b), bc = midpoint(&m, b, c), ca = midpoint(&m, c, a);
            uint32_t q[4][3] = {{a, ab, ca}, {b, bc, ab}, {c, ca, bc}, {ab, bc, ca}};
            memcpy(nf + 12 * i, q, sizeof q);
        }
        free(m.f);
        free(m.keys);
        free(m.vals);
        m.f = nf;
        m.nf *= 4;
    }
    static char buf[1 << 20];
    setvbuf(stdout, buf, _IOFBF, sizeof buf);
    printf("# icosphere level %d: %zu vertices, %zu triangles\n", level, m.nv, m.nf);
    for (size_t i = 0; i < m.nv; i++) printf("v %.7f %.7f %.7f\n", m.v[3 * i], m.v[3 * i + 1], m.v[3 * i + 2]);
    if (normals)
        for (size_t i = 0; i < m.nv; i++)
            printf("vn %.6f %.6f %.6f\n", m.v[3 * i], m.v[3 * i + 1], m.v[3 * i + 2]);
    for (size_t i = 0; i < m.nf; i++) {
        uint32_t *f = m.f + 3 * i;
        if (normals)
            printf("f %u//%u %u//%u %u//%u\n", f[0] + 1, f[0] + 1, f[1] + 1, f[1] + 1, f[2] + 1, f[2] + 1);
        else
            printf("f %u %u %u\n", f[0] + 1, f[1] + 1, f[2] + 1);
    }
    free(m.v);
    free(m.f);
    return fflush(stdout) == 0 ? 0 : 1;
}
