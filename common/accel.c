/* accel.c - the two intersectors behind accel.h, and the choice between them.
 *
 * The flat intersector runs the watertight test of intersect.h on eight
 * triangles at once with GCC/Clang vector extensions, which compile to SSE
 * on any x86-64 (or NEON on ARM) without machine-specific flags. Each lane
 * performs exactly the IEEE operations of the scalar triangle_intersect(),
 * in the same order, so the result is the one the scalar loop over the
 * triangles in index order would give; the rare lanes that need the scalar
 * test's double-precision edge fallback are handed to that very function. */
#include "accel.h"

#include <stdlib.h>
#include <string.h>
#ifdef __SSE2__
#include <emmintrin.h>
#endif

#define LANES ACCEL_FLAT_LANES


typedef float vfloat __attribute__((vector_size(LANES * sizeof(float))));
typedef int32_t vint __attribute__((vector_size(LANES * sizeof(int32_t))));

/* Triangle vertices as structure of arrays: v[vertex][axis][i], padded with
 * lanes that are masked off to a multiple of LANES. */
typedef struct {
    float *v[3][3];
    uint32_t count, padded;
} flat_triangles;

struct accel {
    accel_kind kind;
    bvh *tree;           /* ACCEL_BVH */
    flat_triangles flat; /* ACCEL_FLAT */
};

static accel_kind choose_kind(const scene *s, accel_kind want) {
    if (want != ACCEL_AUTO) return want;
    return s->triangle_count <= ACCEL_FLAT_MAX_TRIANGLES && s->sphere_count <= ACCEL_FLAT_MAX_SPHERES ? ACCEL_FLAT
                                                                                                     : ACCEL_BVH;
}

/* Lay out s's triangles for the flat intersector. Returns 0, or -1 when out
 * of memory (what was allocated is freed by accel_free). */
static int flat_build(flat_triangles *f, const scene *s) {
    f->count = s->triangle_count;
    f->padded = (s->triangle_count + LANES - 1) / LANES * LANES;
    size_t bytes = (size_t)(f->padded ? f->padded : LANES) * sizeof(float);
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++) {
            f->v[k][a] = aligned_alloc(sizeof(vfloat), bytes);
            if (!f->v[k][a]) return -1;
            memset(f->v[k][a], 0, bytes);
        }
    for (uint32_t i = 0; i < f->count; i++) {
        const triangle *t = &s->triangles[i];
        const vec3 *vs[3] = {&t->v0, &t->v1, &t->v2};
        for (int k = 0; k < 3; k++) {
            f->v[k][0][i] = vs[k]->x;
            f->v[k][1][i] = vs[k]->y;
            f->v[k][2][i] = vs[k]->z;
        }
    }
    return 0;
}

accel *accel_build(const scene *s, accel_kind kind) {
    accel *a = calloc(1, sizeof *a);
    if (!a) return NULL;
    a->kind = choose_kind(s, kind);
    int ok = a->kind == ACCEL_BVH ? (a->tree = bvh_build(s)) != NULL : flat_build(&a->flat, s) == 0;
    if (!ok) {
        accel_free(a);
        return NULL;
    }
    return a;
}

void accel_free(accel *a) {
    if (!a) return;
    bvh_free(a->tree);
    for (int k = 0; k < 3; k++)
        for (int ax = 0; ax < 3; ax++) free(a->flat.v[k][ax]);
    free(a);
}

accel_kind accel_get_kind(const accel *a) { return a->kind; }

int accel_get_bvh_stats(const accel *a, bvh_stats *out) {
    if (!a->tree) return -1;
    bvh_get_stats(a->tree, out);
    return 0;
}

static inline vfloat vload(const float *p) {
    vfloat v;
    memcpy(&v, p, sizeof v);
    return v;
}

_Static_assert(LANES == 4, "vsplat and the lane ids below are written out for 4 lanes");

static inline vfloat vsplat(float x) { return (vfloat){x, x, x, x}; }

/* Whether any lane of a mask is set. */
static inline int vany(vint m) {
#ifdef __SSE2__
    return _mm_movemask_ps((__m128)m) != 0;
#else
    int32_t any = 0;
    for (int k = 0; k < LANES; k++) any |= m[k];
    return any != 0;
#endif
}

/* Lane results of the watertight test for one group of triangles, after the
 * sign flip that makes det positive. */
typedef struct {
    vfloat T, det, V, W;
    vint ok;   /* inside, det != 0, 0 < T < tmax * det (tmax at the group's start) */
    vint edge; /* some edge function was exactly 0: the scalar test decides */
} flat_group;

/* The vector half of triangle_intersect() (intersect.h) for triangles
 * [base, base + LANES), term for term. */
static inline void flat_test_group(const flat_triangles *f, const ray_prep *r, uint32_t base, float tmax,
                                   flat_group *g) {
    const int kx = r->kx, ky = r->ky, kz = r->kz;
    const float o[3] = {r->o.x, r->o.y, r->o.z};
    vfloat sx = vsplat(r->sx), sy = vsplat(r->sy), sz = vsplat(r->sz);
    vfloat Az = vload(f->v[0][kz] + base) - vsplat(o[kz]);
    vfloat Bz = vload(f->v[1][kz] + base) - vsplat(o[kz]);
    vfloat Cz = vload(f->v[2][kz] + base) - vsplat(o[kz]);
    vfloat Ax = (vload(f->v[0][kx] + base) - vsplat(o[kx])) - sx * Az;
    vfloat Ay = (vload(f->v[0][ky] + base) - vsplat(o[ky])) - sy * Az;
    vfloat Bx = (vload(f->v[1][kx] + base) - vsplat(o[kx])) - sx * Bz;
    vfloat By = (vload(f->v[1][ky] + base) - vsplat(o[ky])) - sy * Bz;
    vfloat Cx = (vload(f->v[2][kx] + base) - vsplat(o[kx])) - sx * Cz;
    vfloat Cy = (vload(f->v[2][ky] + base) - vsplat(o[ky])) - sy * Cz;
    vfloat U = Cx * By - Cy * Bx, V = Ax * Cy - Ay * Cx, W = Bx * Ay - By * Ax;
    vfloat zero = vsplat(0.0f);
    vint lane_ids = (vint){0, 1, 2, 3} + (int32_t)base;
    vint real = (lane_ids < (int32_t)f->count) & (lane_ids != (int32_t)r->skip);
    g->edge = real & ((U == zero) | (V == zero) | (W == zero));
    /* Outside unless U, V, W share a sign. With no zero among them (zeros
     * are edge lanes, decided by the scalar test), a float's sign bit is
     * its sign, so: do the sign bits differ? */
    vint outside = (((vint)U ^ (vint)V) | ((vint)U ^ (vint)W)) >> 31;
    vfloat det = U + V + W;
    vfloat T = U * sz * Az + V * sz * Bz + W * sz * Cz;
    /* Negate T, det, V, W where det < 0: flipping the sign bit is exact. */
    vint flip = (det < zero) & (int32_t)0x80000000u;
    g->T = (vfloat)((vint)T ^ flip);
    g->det = (vfloat)((vint)det ^ flip);
    g->V = (vfloat)((vint)V ^ flip);
    g->W = (vfloat)((vint)W ^ flip);
    g->ok = real & ~g->edge & ~outside & (det != zero) & (g->T > zero) & (g->T < vsplat(tmax) * g->det);
}

/* The scalar tail for lane k of a group, with the current closest distance
 * h->t: the same acceptance test and arithmetic as triangle_intersect(). */
static inline int flat_take_lane(const flat_group *g, const scene *s, const ray_prep *r, uint32_t id, int k,
                                 hit *h) {
    float t, b1, b2;
    if (g->edge[k]) {
        if (!triangle_intersect(r, &s->triangles[id], h->t, &t, &b1, &b2)) return 0;
    } else {
        if (!g->ok[k] || g->T[k] >= h->t * g->det[k]) return 0;
        float inv = 1.0f / g->det[k];
        t = g->T[k] * inv;
        b1 = g->V[k] * inv;
        b2 = g->W[k] * inv;
    }
    h->t = t;
    h->prim = id;
    h->b1 = b1;
    h->b2 = b2;
    return 1;
}

/* Every triangle, then every sphere; with any_hit, stop at the first hit. */
static int flat_traverse(const accel *a, const scene *s, const ray *ray_in, float tmax, hit *h, int any_hit) {
    const flat_triangles *f = &a->flat;
    ray_prep r;
    ray_prepare(ray_in, &r);
    h->t = tmax;
    int found = 0;
    for (uint32_t base = 0; base < f->padded; base += LANES) {
        flat_group g;
        flat_test_group(f, &r, base, h->t, &g);
        if (!vany(g.ok | g.edge)) continue;
        for (int k = 0; k < LANES; k++)
            if ((g.ok[k] | g.edge[k]) && flat_take_lane(&g, s, &r, base + (uint32_t)k, k, h)) {
                found = 1;
                if (any_hit) return 1;
            }
    }
    for (uint32_t i = 0; i < s->sphere_count; i++) {
        uint32_t id = scene_sphere_base(s) + i;
        float t;
        if (!sphere_intersect(&r, &s->spheres[i], id == r.skip, h->t, &t)) continue;
        h->t = t;
        h->prim = id;
        h->b1 = h->b2 = 0.0f;
        found = 1;
        if (any_hit) return 1;
    }
    return found;
}

int accel_intersect(const accel *a, const scene *s, const ray *r, float tmax, hit *h) {
    if (a->kind == ACCEL_BVH) return bvh_intersect(a->tree, s, r, tmax, h);
    return flat_traverse(a, s, r, tmax, h, 0);
}

int accel_occluded(const accel *a, const scene *s, const ray *r, float tmax) {
    if (a->kind == ACCEL_BVH) return bvh_occluded(a->tree, s, r, tmax);
    hit h;
    return flat_traverse(a, s, r, tmax, &h, 1);
}
