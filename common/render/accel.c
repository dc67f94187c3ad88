/* accel.c - the two intersectors behind accel.h, and the choice between them.
 *
 * The flat intersector runs the watertight test of intersect.h on 4, 8 or 16
 * triangles at once with GCC/Clang vector extensions, which compile to SSE
 * on any x86-64 (or NEON on ARM) without machine-specific flags. Each lane
 * performs exactly the IEEE operations of the scalar triangle_intersect(),
 * in the same order, so the result is the one the scalar loop over the
 * triangles in index order would give; the rare lanes that need the scalar
 * test's double-precision edge fallback are handed to that very function. */
#include "accel.h"

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#endif

/* Triangle arrays are padded to this many lanes, the widest kernel's. */
#define LANES 16

/* Triangle vertices as structure of arrays: v[vertex][axis][i], padded with
 * lanes that are masked off to a multiple of LANES. */
typedef struct {
    float *v[3][3];
    uint32_t count;
} flat_triangles;

typedef int (*flat_traverse_fn)(const flat_triangles *f, const scene *s, const ray *r, float tmax, hit *h,
                                int any_hit);

struct accel {
    accel_kind kind;
    bvh *tree;                /* ACCEL_BVH */
    accel_embree *embree;     /* ACCEL_EMBREE */
    accel_wide *wide;         /* ACCEL_WIDE */
    flat_triangles flat;      /* ACCEL_FLAT */
    flat_traverse_fn flat_fn; /* the widest kernel this CPU runs */
};

static flat_traverse_fn flat_choose(void);

static accel_kind choose_kind(const scene *s, accel_kind want) {
    if (want != ACCEL_AUTO) return want;
    if (s->triangle_count <= ACCEL_FLAT_MAX_TRIANGLES && s->sphere_count <= ACCEL_FLAT_MAX_SPHERES) return ACCEL_FLAT;
    size_t n = (size_t)s->triangle_count + s->sphere_count;
    return n >= ACCEL_WIDE_MIN_PRIMITIVES ? ACCEL_WIDE : ACCEL_BVH;
}

/* Lay out s's triangles for the flat intersector. Returns 0, or -1 when out
 * of memory (what was allocated is freed by accel_free). */
static int flat_build(flat_triangles *f, const scene *s) {
    f->count = s->triangle_count;
    uint32_t padded = (s->triangle_count + LANES - 1) / LANES * LANES;
    size_t bytes = (size_t)(padded ? padded : LANES) * sizeof(float);
    for (int k = 0; k < 3; k++)
        for (int a = 0; a < 3; a++) {
            f->v[k][a] = aligned_alloc(LANES * sizeof(float), bytes);
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

accel *accel_build_err(const scene *s, accel_kind kind, char *err, size_t err_len) {
    accel *a = calloc(1, sizeof *a);
    if (!a) return snprintf(err, err_len, "out of memory"), NULL;
    a->kind = choose_kind(s, kind);
    a->flat_fn = flat_choose();
    snprintf(err, err_len, "out of memory");
    int ok = a->kind == ACCEL_BVH      ? (a->tree = bvh_build(s)) != NULL
             : a->kind == ACCEL_EMBREE ? (a->embree = accel_embree_build(s, err, err_len)) != NULL
             : a->kind == ACCEL_WIDE   ? (a->wide = accel_wide_build(s, err, err_len)) != NULL
                                       : flat_build(&a->flat, s) == 0;
    if (!ok) {
        accel_free(a);
        return NULL;
    }
    return a;
}

accel *accel_build(const scene *s, accel_kind kind) {
    char err[256];
    return accel_build_err(s, kind, err, sizeof err);
}

void accel_free(accel *a) {
    if (!a) return;
    bvh_free(a->tree);
    accel_embree_free(a->embree);
    accel_wide_free(a->wide);
    for (int k = 0; k < 3; k++)
        for (int ax = 0; ax < 3; ax++) free(a->flat.v[k][ax]);
    free(a);
}

accel_kind accel_get_kind(const accel *a) { return a->kind; }

const char *accel_kind_name(accel_kind k) {
    static const char *const names[] = {"auto", "bvh", "flat", "embree", "wide"}; /* in accel_kind order */
    return (unsigned)k < sizeof names / sizeof names[0] ? names[k] : "?";
}


int accel_get_embree_stats(const accel *a, accel_embree_stats *out) {
    if (!a->embree) return -1;
    accel_embree_get_stats(a->embree, out);
    return 0;
}

int accel_get_wide_stats(const accel *a, accel_wide_stats *out) {
    if (!a->wide) return -1;
    accel_wide_get_stats(a->wide, out);
    return 0;
}

int accel_get_bvh_stats(const accel *a, bvh_stats *out) {
    if (!a->tree) return -1;
    bvh_get_stats(a->tree, out);
    return 0;
}

/* 4 lanes: SSE2, which every x86-64 has. */
#define FLAT(name) flat4_##name
#include "accel_flat4.h"

#if defined(__x86_64__) && defined(__GNUC__)
#define HAVE_FLAT8 1
/* 8 lanes with AVX2 (no FMA: products are rounded as in the scalar test). */
#define FLAT_LANES 8
#define FLAT(name) flat8_##name
#define FLAT_TARGET __attribute__((target("avx2")))
#define FLAT_SPLAT(x) {x, x, x, x, x, x, x, x}
#define FLAT_LANE_IDS {0, 1, 2, 3, 4, 5, 6, 7}
#define FLAT_BITS(m) _mm256_movemask_ps((__m256)(m))
#include "accel_flat.h"

/* 16 lanes with AVX-512F (again no FMA). Vector compares yield mask
 * registers, which the compiler turns back into the all-ones lanes the
 * kernel expects; the arithmetic per lane is unchanged. */
#define FLAT_LANES 16
#define FLAT(name) flat16_##name
#define FLAT_TARGET __attribute__((target("avx512f")))
#define FLAT_SPLAT(x) {x, x, x, x, x, x, x, x, x, x, x, x, x, x, x, x}
#define FLAT_LANE_IDS {0, 1, 2, 3, 4, 5, 6, 7, 8, 9, 10, 11, 12, 13, 14, 15}
#define FLAT_BITS(m) _mm512_test_epi32_mask((__m512i)(m), (__m512i)(m))
#include "accel_flat.h"
#endif

/* The widest kernel this CPU can run. TESSERA_NO_AVX512 (any value) stops at
 * AVX2, TESSERA_NO_AVX2 at SSE (for tests: every width on one machine). */
static flat_traverse_fn flat_choose(void) {
#ifdef HAVE_FLAT8
    if (getenv("TESSERA_NO_AVX2") != NULL) return flat4_traverse;
    if (getenv("TESSERA_NO_AVX512") == NULL && __builtin_cpu_supports("avx512f")) return flat16_traverse;
    if (__builtin_cpu_supports("avx2")) return flat8_traverse;
#endif
    return flat4_traverse;
}

int accel_flat_lanes(const accel *a) {
#ifdef HAVE_FLAT8
    if (a->flat_fn == flat16_traverse) return 16;
    if (a->flat_fn == flat8_traverse) return 8;
#endif
    return 4;
}

int accel_intersect(const accel *a, const scene *s, const ray *r, float tmax, hit *h) {
    if (a->kind == ACCEL_WIDE) return accel_wide_intersect(a->wide, s, r, tmax, h);
    h->corners = NULL; /* only the wide walk's leaves hand them out (hit_corners) */
    if (a->kind == ACCEL_EMBREE) return accel_embree_intersect(a->embree, s, r, tmax, h);
    if (a->kind == ACCEL_BVH) return bvh_intersect(a->tree, s, r, tmax, h);
    return a->flat_fn(&a->flat, s, r, tmax, h, 0);
}

int accel_intersect_occluded(const accel *a, const scene *s, const ray *r, float tmax, hit *h, const ray *sh,
                             float sh_tmax, int *occluded) {
    if (a->kind == ACCEL_WIDE) return accel_wide_intersect_occluded(a->wide, s, r, tmax, h, sh, sh_tmax, occluded);
    *occluded = accel_occluded(a, s, sh, sh_tmax);
    return accel_intersect(a, s, r, tmax, h);
}

int accel_occluded(const accel *a, const scene *s, const ray *r, float tmax) {
    if (a->kind == ACCEL_WIDE) return accel_wide_occluded(a->wide, s, r, tmax);
    if (a->kind == ACCEL_EMBREE) return accel_embree_occluded(a->embree, s, r, tmax);
    if (a->kind == ACCEL_BVH) return bvh_occluded(a->tree, s, r, tmax);
    hit h;
    return a->flat_fn(&a->flat, s, r, tmax, &h, 1);
}
