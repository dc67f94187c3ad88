/* intersect.h - rays, and the exact ray/primitive tests.
 *
 * Triangles use the watertight test of Woop, Benthin and Wald (JCGT 2013): a
 * ray through a shared edge or vertex hits at least one of the triangles
 * meeting there, so no light leaks through a mesh's seams. Spheres use the
 * numerically careful quadratic of Haines et al. (Ray Tracing Gems, ch. 7).
 *
 * A ray spawned from a surface carries the id of that primitive in `skip`: a
 * flat triangle cannot be hit again by a ray leaving it, and a ray leaving a
 * sphere can only hit its far side. Together with the offsets of offset.h this
 * removes self-intersection without any scene-dependent epsilon. */
#ifndef TESSERA_INTERSECT_H
#define TESSERA_INTERSECT_H

#include <stdint.h>

#include "scene.h"
#include "vec.h"

#define PRIM_NONE UINT32_MAX

typedef struct {
    vec3 o, d;     /* origin and unit direction */
    uint32_t skip; /* primitive the ray leaves, or PRIM_NONE */
} ray;

/* Per-ray constants of the watertight test and the BVH slab test. */
typedef struct {
    vec3 o, d, inv_d;
    int kx, ky, kz;
    float sx, sy, sz;
    uint32_t skip;
} ray_prep;

typedef struct {
    float t;
    uint32_t prim; /* triangle index, or sphere_base + sphere index */
    float b1, b2;  /* barycentrics of v1 and v2 (triangles) */
    /* Where the intersector read the hit triangle's corners, or NULL:
     * corner k's axis a is corners[(3 k + a) * corner_stride], the same
     * floats as scene.triangles[prim] (the wide BVH's leaf lane, which the
     * walk has just read: shading then need not fetch the triangle's
     * record from memory, hit_corners). */
    const float *corners;
    uint32_t corner_stride;
} hit;

/* The corners of the triangle h hit: from h->corners when the intersector
 * gave them, else from the scene's record (the same floats either way). */
static inline void hit_corners(const scene *s, const hit *h, vec3 *v0, vec3 *v1, vec3 *v2) {
    if (!h->corners) {
        const triangle *t = &s->triangles[h->prim];
        *v0 = t->v0, *v1 = t->v1, *v2 = t->v2;
        return;
    }
    const float *c = h->corners;
    size_t k = h->corner_stride;
    *v0 = vec3_make(c[0], c[k], c[2 * k]);
    *v1 = vec3_make(c[3 * k], c[4 * k], c[5 * k]);
    *v2 = vec3_make(c[6 * k], c[7 * k], c[8 * k]);
}

/* 1/d, but a huge finite value for d = 0, so that the slab test computes
 * 0 * huge = 0 rather than 0 * inf = NaN for a ray in a box's plane. */
static inline float safe_inverse(float d) { return d != 0.0f ? 1.0f / d : copysignf(3.0e38f, d); }

/* The constants of the watertight test only (all but inv_d, which only the
 * BVH's slab test reads): what the flat intersector needs. Always inlined:
 * in a build whose walk header had grown (four walks in turn, an
 * experiment), GCC called it out of line from the AVX2 paired walk, a
 * generic SSE function from AVX code, and 18% of a render's CPU (ico5,
 * Zen 3) sat on its entry and on the instruction after its return; the
 * paired walk went from 4% faster than unpaired walks to 16% slower
 * (docs/meshes.md). On main's walk it makes no difference. */
static inline __attribute__((always_inline)) void ray_prepare_shear(const ray *r, ray_prep *p) {
    p->o = r->o;
    p->d = r->d;
    p->skip = r->skip;
    float ax = fabsf(r->d.x), ay = fabsf(r->d.y), az = fabsf(r->d.z);
    p->kz = (ax > ay) ? (ax > az ? 0 : 2) : (ay > az ? 1 : 2);
    p->kx = p->kz == 2 ? 0 : p->kz + 1;
    p->ky = p->kx == 2 ? 0 : p->kx + 1;
    if (vec3_comp(r->d, p->kz) < 0.0f) {
        int t = p->kx;
        p->kx = p->ky;
        p->ky = t;
    }
    float dz = vec3_comp(r->d, p->kz);
    p->sx = vec3_comp(r->d, p->kx) / dz;
    p->sy = vec3_comp(r->d, p->ky) / dz;
    p->sz = 1.0f / dz;
}

static inline void ray_prepare(const ray *r, ray_prep *p) {
    ray_prepare_shear(r, p);
    p->inv_d = vec3_make(safe_inverse(r->d.x), safe_inverse(r->d.y), safe_inverse(r->d.z));
}

/* Watertight ray/triangle test. Returns 1 and sets *t, *b1, *b2 for a hit
 * with 0 < t < tmax, else 0. */
static inline int triangle_intersect(const ray_prep *r, const triangle *tri, float tmax, float *t_out,
                                     float *b1_out, float *b2_out) {
    vec3 A = vec3_sub(tri->v0, r->o), B = vec3_sub(tri->v1, r->o), C = vec3_sub(tri->v2, r->o);
    float Az = vec3_comp(A, r->kz), Bz = vec3_comp(B, r->kz), Cz = vec3_comp(C, r->kz);
    float Ax = vec3_comp(A, r->kx) - r->sx * Az, Ay = vec3_comp(A, r->ky) - r->sy * Az;
    float Bx = vec3_comp(B, r->kx) - r->sx * Bz, By = vec3_comp(B, r->ky) - r->sy * Bz;
    float Cx = vec3_comp(C, r->kx) - r->sx * Cz, Cy = vec3_comp(C, r->ky) - r->sy * Cz;
    float U = Cx * By - Cy * Bx, V = Ax * Cy - Ay * Cx, W = Bx * Ay - By * Ax;
    if (U == 0.0f || V == 0.0f || W == 0.0f) { /* on an edge: decide in double */
        U = (float)((double)Cx * By - (double)Cy * Bx);
        V = (float)((double)Ax * Cy - (double)Ay * Cx);
        W = (float)((double)Bx * Ay - (double)By * Ax);
    }
    if ((U < 0.0f || V < 0.0f || W < 0.0f) && (U > 0.0f || V > 0.0f || W > 0.0f)) return 0;
    float det = U + V + W;
    if (det == 0.0f) return 0;
    float T = U * r->sz * Az + V * r->sz * Bz + W * r->sz * Cz;
    if (det < 0.0f) {
        T = -T;
        det = -det;
        U = -U;
        V = -V;
        W = -W;
    }
    if (T <= 0.0f || T >= tmax * det) return 0;
    float inv = 1.0f / det;
    *t_out = T * inv;
    *b1_out = V * inv;
    *b2_out = W * inv;
    return 1;
}

/* The culling distance handed to a tree walk once the best hit is at t:
 * t (1 + 2^-12), so a candidate at t (a tie, decided by index) or nearer is
 * never culled by the walk's rounding (the BVH, the wide BVH and Embree's
 * walk all cull by it). */
static inline float accel_cull_distance(float t) { return t * (1.0f + 1.0f / 4096.0f) + 1e-30f; }

/* The order in which hits win, whatever order they are found in: smaller t,
 * then (an exact tie) the smaller primitive index. Every intersector that
 * uses it returns the same hit for a ray (accel_embree.h). */
static inline int hit_before(float t, uint32_t prim, const hit *best) {
    return t < best->t || (t == best->t && prim < best->prim);
}

/* Ray/sphere test. `leaving` is set when the ray starts on this sphere: then
 * only the far root can be real. Returns 1 and sets *t for 0 < t < tmax. */
static inline int sphere_intersect(const ray_prep *r, const sphere *s, int leaving, float tmax, float *t_out) {
    vec3 f = vec3_sub(r->o, s->center);
    float b = -vec3_dot(f, r->d);
    vec3 l = vec3_add(f, vec3_scale(r->d, b)); /* centre to the ray's closest point */
    float disc = s->radius * s->radius - vec3_dot(l, l);
    if (disc < 0.0f) return 0;
    float c = vec3_dot(f, f) - s->radius * s->radius;
    float q = b + copysignf(sqrtf(disc), b);
    float t0 = q != 0.0f ? c / q : 0.0f, t1 = q;
    if (t0 > t1) {
        float tmp = t0;
        t0 = t1;
        t1 = tmp;
    }
    float t = (!leaving && t0 > 0.0f) ? t0 : t1;
    if (leaving && vec3_dot(r->d, f) > 0.0f) return 0; /* heading out of a convex shape */
    if (!(t > 0.0f) || t >= tmax) return 0;
    *t_out = t;
    return 1;
}

#endif
