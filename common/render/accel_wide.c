/* accel_wide.c - the 8-wide BVH of accel_wide.h: Embree's generic builder
 * makes it, Tessera walks it and decides every hit.
 *
 * Build: one padded box per primitive (accel_padded_box), handed to
 * rtcBuildBVH (binned SAH, parallel on the device's threads); its callbacks
 * create the nodes and leaves below in Embree's thread-local allocator,
 * which the RTCBVH owns and frees.
 *
 * Walk: a node holds its children's boxes as structure of arrays, so one
 * 8-lane slab test (two SSE registers) covers all eight; the children hit
 * are visited nearest
 * first, the others kept on a fixed-size stack with their entry distance
 * and dropped when they come up behind the culling distance. A leaf holds up
 * to 4 primitives: its triangles' vertices as 4 lanes for the flat kernel's
 * watertight test (test_lanes in accel_flat.h: per lane exactly the IEEE
 * operations of triangle_intersect), its spheres by index.
 *
 * Why no candidate that could win is culled: the slab test is exact up to
 * rounding of a few ulps of the distances (pbrt, 3rd ed., 3.9.2); its far
 * distance is widened by SLAB_WIDEN, more than that rounding; boxes are
 * padded (accel_padded_box), which also covers rays lying in a box's plane;
 * and the culling distance is accel_cull_distance(best t), not best t. The
 * leaves compare candidates only by hit_before() on numbers computed with
 * the caller's tmax, never with the culling distance. */
#include "accel_wide.h"

#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <time.h>

#include "accel_embree.h"
#include <embree3/rtcore_builder.h>

#define FLAT_LANES_ONLY
#define FLAT(name) wide4_##name
#include "accel_flat4.h"

/* Children per node: 8 measured 3-8% faster than 4 (docs/meshes.md). The
 * walk's bytes do not depend on it; -DNODE_W=4 builds the 4-wide tree. */
#ifndef NODE_W
#define NODE_W 8
#endif

typedef wide4_vfloat vfloat;
typedef wide4_vint vint;
/* Static functions pass 8-float vectors among themselves only, so the ABI
 * note for 32-byte vectors without AVX does not concern us. */
#pragma GCC diagnostic ignored "-Wpsabi"
/* A node's lanes: NODE_W floats (two SSE registers' worth for 8). */
typedef float nfloat __attribute__((vector_size(NODE_W * sizeof(float))));
typedef int32_t nint __attribute__((vector_size(NODE_W * sizeof(int32_t))));

#define WIDE_MAX_DEPTH 40                       /* the builder's limit on the tree's depth */
#define WIDE_STACK ((NODE_W - 1) * WIDE_MAX_DEPTH + NODE_W) /* NODE_W - 1 siblings kept per level at most */
#define LEAF_TAG ((uintptr_t)1)                 /* low bit of a child reference: a leaf */
#define SLAB_WIDEN (1.0f + 3.0f / 8388608.0f)   /* 1 + 3 * 2^-23 >= pbrt's 1 + 2 gamma(3) */

/* An inner node: the boxes of its (up to) NODE_W children, box[2a][k] the lower
 * and box[2a + 1][k] the upper bound of child k on axis a; an absent child
 * has the empty box (lower +inf, upper -inf), which no ray enters. */
typedef struct {
    float box[6][NODE_W];
    uintptr_t child[NODE_W]; /* node pointer, or leaf pointer | LEAF_TAG */
} wide_node;

/* A leaf: triangles in lanes [0, tris) (vertex k's axis a at v[k][a][lane]),
 * spheres' primitive ids after them in id[tris, tris + spheres). */
typedef struct {
    float v[3][3][4];
    uint32_t id[4];
    uint32_t tris, spheres;
} wide_leaf;

struct accel_wide {
    accel_embree_device dev;
    RTCBVH bvh;
    uintptr_t root; /* 0 for a scene without primitives */
    accel_wide_stats stats;
};

/* What the build callbacks share. */
typedef struct {
    const scene *s;
    atomic_size_t nodes, leaves;
} build_ctx;

static void *cb_create_node(RTCThreadLocalAllocator alloc, unsigned int child_count, void *user) {
    build_ctx *b = user;
    (void)child_count;
    wide_node *n = rtcThreadLocalAlloc(alloc, sizeof *n, 64);
    if (!n) return NULL;
    for (int k = 0; k < NODE_W; k++) {
        for (int a = 0; a < 3; a++) {
            n->box[2 * a][k] = INFINITY;
            n->box[2 * a + 1][k] = -INFINITY;
        }
        n->child[k] = 0;
    }
    atomic_fetch_add_explicit(&b->nodes, 1, memory_order_relaxed);
    return n;
}

static void cb_set_children(void *node, void **children, unsigned int count, void *user) {
    wide_node *n = node;
    (void)user;
    for (unsigned k = 0; k < count && k < NODE_W; k++) n->child[k] = (uintptr_t)children[k];
}

static void cb_set_bounds(void *node, const struct RTCBounds **bounds, unsigned int count, void *user) {
    wide_node *n = node;
    (void)user;
    for (unsigned k = 0; k < count && k < NODE_W; k++) {
        const struct RTCBounds *b = bounds[k];
        n->box[0][k] = b->lower_x, n->box[1][k] = b->upper_x;
        n->box[2][k] = b->lower_y, n->box[3][k] = b->upper_y;
        n->box[4][k] = b->lower_z, n->box[5][k] = b->upper_z;
    }
}

static void *cb_create_leaf(RTCThreadLocalAllocator alloc, const struct RTCBuildPrimitive *prims, size_t count,
                            void *user) {
    build_ctx *b = user;
    const scene *s = b->s;
    wide_leaf *l = rtcThreadLocalAlloc(alloc, sizeof *l, 16);
    if (!l) return NULL;
    memset(l, 0, sizeof *l);
    for (size_t i = 0; i < count && i < 4; i++) { /* triangles first */
        uint32_t id = prims[i].primID;
        if (id >= s->triangle_count) continue;
        const triangle *t = &s->triangles[id];
        const vec3 *vs[3] = {&t->v0, &t->v1, &t->v2};
        for (int k = 0; k < 3; k++) {
            l->v[k][0][l->tris] = vs[k]->x;
            l->v[k][1][l->tris] = vs[k]->y;
            l->v[k][2][l->tris] = vs[k]->z;
        }
        l->id[l->tris++] = id;
    }
    for (size_t i = 0; i < count && i < 4; i++)
        if (prims[i].primID >= s->triangle_count) l->id[l->tris + l->spheres++] = prims[i].primID;
    atomic_fetch_add_explicit(&b->leaves, 1, memory_order_relaxed);
    return (void *)((uintptr_t)l | LEAF_TAG);
}

/* The build primitives: every primitive's padded box. Returns NULL when out
 * of memory; the caller frees. */
static struct RTCBuildPrimitive *build_primitives(const scene *s, size_t n) {
    struct RTCBuildPrimitive *p = aligned_alloc(32, (n * sizeof *p + 31) / 32 * 32);
    if (!p) return NULL;
    for (size_t i = 0; i < n; i++) {
        float lo[3], hi[3];
        accel_padded_box(s, (uint32_t)i, lo, hi);
        p[i] = (struct RTCBuildPrimitive){lo[0], lo[1], lo[2], 0, hi[0], hi[1], hi[2], (unsigned)i};
    }
    return p;
}

static double seconds_since(const struct timespec *t0) {
    struct timespec t1;
    clock_gettime(CLOCK_MONOTONIC, &t1);
    return (double)(t1.tv_sec - t0->tv_sec) + 1e-9 * (double)(t1.tv_nsec - t0->tv_nsec);
}

accel_wide *accel_wide_build(const scene *s, char *err, size_t err_len) {
    struct timespec t0;
    clock_gettime(CLOCK_MONOTONIC, &t0);
    accel_wide *w = calloc(1, sizeof *w);
    if (!w) return snprintf(err, err_len, "out of memory"), NULL;
    if (accel_embree_device_open(&w->dev, err, err_len) != 0) {
        free(w);
        return NULL;
    }
    w->stats.config = w->dev.config;
    w->stats.node_width = NODE_W;
    size_t n = (size_t)s->triangle_count + s->sphere_count;
    w->stats.primitive_count = n;
    if (n == 0) return w; /* nothing to hit: root 0 */
    struct RTCBuildPrimitive *prims = build_primitives(s, n);
    w->bvh = prims ? rtcNewBVH(w->dev.device) : NULL;
    if (!w->bvh) {
        free(prims);
        snprintf(err, err_len, "%s", w->dev.error[0] ? w->dev.error : "out of memory");
        accel_wide_free(w);
        return NULL;
    }
    build_ctx b = {.s = s};
    struct RTCBuildArguments args = rtcDefaultBuildArguments();
    args.buildQuality = RTC_BUILD_QUALITY_MEDIUM; /* binned SAH */
    args.maxBranchingFactor = NODE_W;
    args.maxDepth = WIDE_MAX_DEPTH;
    args.sahBlockSize = 4; /* 1 to 4 primitives cost one leaf test */
    args.minLeafSize = 3;  /* measured: 6.5% fewer instructions than 1 at 655k triangles */
    args.maxLeafSize = 4;
    args.traversalCost = 1.0f;
    args.intersectionCost = 1.0f;
    args.bvh = w->bvh;
    args.primitives = prims;
    args.primitiveCount = n;
    args.primitiveArrayCapacity = n;
    args.createNode = cb_create_node;
    args.setNodeChildren = cb_set_children;
    args.setNodeBounds = cb_set_bounds;
    args.createLeaf = cb_create_leaf;
    args.userPtr = &b;
    w->root = (uintptr_t)rtcBuildBVH(&args);
    free(prims);
    if (!w->root || w->dev.error[0]) {
        snprintf(err, err_len, "building the wide BVH: %s", w->dev.error[0] ? w->dev.error : "out of memory");
        accel_wide_free(w);
        return NULL;
    }
    w->stats.node_count = atomic_load(&b.nodes);
    w->stats.leaf_count = atomic_load(&b.leaves);
    w->stats.memory_bytes = (size_t)atomic_load(&w->dev.bytes);
    w->stats.peak_bytes = (size_t)atomic_load(&w->dev.peak) + n * sizeof *prims;
    w->stats.build_seconds = seconds_since(&t0);
    return w;
}

void accel_wide_free(accel_wide *w) {
    if (!w) return;
    if (w->bvh) rtcReleaseBVH(w->bvh);
    accel_embree_device_close(&w->dev);
    free(w);
}

void accel_wide_get_stats(const accel_wide *w, accel_wide_stats *out) { *out = w->stats; }

static inline nfloat nsplat(float x) {
    nfloat v;
    for (int k = 0; k < NODE_W; k++) v[k] = x;
    return v;
}

/* A node's row of NODE_W floats (16-byte aligned). */
static inline nfloat nload(const float *p) { return *(const nfloat *)p; }

/* Lane-wise a < b ? a : b and a > b ? a : b (minps / maxps per half).
 * Vectors of 8 go by pointer: GCC notes an ABI change for passing them by
 * value without AVX (they are inlined either way). */
static inline nfloat nmin(const nfloat *a, const nfloat *b) {
#ifdef __SSE2__
    union { nfloat n; __m128 h[NODE_W / 4]; } x = {*a}, y = {*b};
    for (int i = 0; i < NODE_W / 4; i++) x.h[i] = _mm_min_ps(x.h[i], y.h[i]);
    return x.n;
#else
    nint m = *a < *b;
    return (nfloat)(((nint)*a & m) | ((nint)*b & ~m));
#endif
}
static inline nfloat nmax(const nfloat *a, const nfloat *b) {
#ifdef __SSE2__
    union { nfloat n; __m128 h[NODE_W / 4]; } x = {*a}, y = {*b};
    for (int i = 0; i < NODE_W / 4; i++) x.h[i] = _mm_max_ps(x.h[i], y.h[i]);
    return x.n;
#else
    nint m = *a > *b;
    return (nfloat)(((nint)*a & m) | ((nint)*b & ~m));
#endif
}

/* Bit k set where lane k of m is. */
static inline unsigned nbits(const nint *m) {
#ifdef __SSE2__
    union { nint n; __m128 h[NODE_W / 4]; } x = {*m};
    unsigned bits = 0;
    for (int i = 0; i < NODE_W / 4; i++) bits |= (unsigned)_mm_movemask_ps(x.h[i]) << (4 * i);
    return bits;
#else
    unsigned bits = 0;
    for (int k = 0; k < NODE_W; k++) bits |= ((*m)[k] & 1u) << k;
    return bits;
#endif
}

/* A ray prepared for the walk: the test constants (intersect.h), the slab
 * test's origin and inverse direction splatted, and for each axis which row
 * of a node's boxes the ray enters by (the lower bound where it goes up). */
typedef struct {
    ray_prep r;
    wide4_ray lanes;
    nfloat o[3], inv[3];
    size_t near[3], far[3]; /* float offsets of the rows in wide_node.box */
} walk_ray;

static inline void walk_ray_prepare(const ray *in, walk_ray *w) {
    ray_prepare(in, &w->r);
    wide4_ray_splat(&w->r, 0, &w->lanes);
    const float o[3] = {in->o.x, in->o.y, in->o.z};
    const float inv[3] = {w->r.inv_d.x, w->r.inv_d.y, w->r.inv_d.z};
    for (int a = 0; a < 3; a++) {
        w->o[a] = nsplat(o[a]);
        w->inv[a] = nsplat(inv[a]);
        size_t down = signbit(inv[a]) != 0;
        w->near[a] = NODE_W * (2 * a + down);
        w->far[a] = NODE_W * (2 * a + 1 - down);
    }
}

/* The slab test of n's children against [0, cull]: returns the bits of the
 * children the ray may enter and their entry distances in *tnear. */
static inline unsigned node_test(const wide_node *n, const walk_ray *w, float cull, nfloat *tnear) {
    const float *b = &n->box[0][0];
    nfloat nx = (nload(b + w->near[0]) - w->o[0]) * w->inv[0];
    nfloat ny = (nload(b + w->near[1]) - w->o[1]) * w->inv[1];
    nfloat nz = (nload(b + w->near[2]) - w->o[2]) * w->inv[2];
    nfloat fx = (nload(b + w->far[0]) - w->o[0]) * w->inv[0];
    nfloat fy = (nload(b + w->far[1]) - w->o[1]) * w->inv[1];
    nfloat fz = (nload(b + w->far[2]) - w->o[2]) * w->inv[2];
    nfloat zero = nsplat(0.0f), c = nsplat(cull);
    nfloat nxy = nmax(&nx, &ny), nz0 = nmax(&nz, &zero), fxy = nmin(&fx, &fy), fzc = nmin(&fz, &c);
    nfloat tn = nmax(&nxy, &nz0), tf = nmin(&fxy, &fzc);
    *tnear = tn;
    nint hit = tn <= tf * nsplat(SLAB_WIDEN);
    return nbits(&hit);
}

/* Test leaf l's primitives with the caller's tmax and fold every hit into
 * *h by hit_before (h->t starts at tmax). Returns 1 if some primitive hit
 * (with any_hit: as soon as one does). */
static inline int leaf_test(const wide_leaf *l, const scene *s, const walk_ray *w, float tmax, hit *h, int any_hit) {
    const ray_prep *r = &w->r;
    int found = 0;
    if (l->tris) {
        const float *const p[3][3] = {{l->v[0][0], l->v[0][1], l->v[0][2]},
                                      {l->v[1][0], l->v[1][1], l->v[1][2]},
                                      {l->v[2][0], l->v[2][1], l->v[2][2]}};
        vint ids;
        memcpy(&ids, l->id, sizeof ids);
        int32_t nt = (int32_t)l->tris;
        vint real = ((vint){0, 1, 2, 3} < (vint){nt, nt, nt, nt}) & (ids != w->lanes.skip);
        wide4_group g;
        wide4_test_lanes(p, r, &w->lanes, real, tmax, &g);
        for (unsigned bits = wide4_vbits(g.ok | g.edge); bits; bits &= bits - 1) {
            int k = __builtin_ctz(bits);
            uint32_t id = l->id[k];
            float t, b1, b2;
            if (g.edge[k]) {
                if (!triangle_intersect(r, &s->triangles[id], tmax, &t, &b1, &b2)) continue;
            } else {
                float inv = 1.0f / g.det[k];
                t = g.T[k] * inv;
                b1 = g.V[k] * inv;
                b2 = g.W[k] * inv;
            }
            if (any_hit) return 1;
            if (hit_before(t, id, h)) *h = (hit){t, id, b1, b2}, found = 1;
        }
    }
    for (uint32_t i = l->tris; i < l->tris + l->spheres; i++) {
        uint32_t id = l->id[i];
        float t;
        if (!sphere_intersect(r, &s->spheres[id - s->triangle_count], id == r->skip, tmax, &t)) continue;
        if (any_hit) return 1;
        if (hit_before(t, id, h)) *h = (hit){t, id, 0.0f, 0.0f}, found = 1;
    }
    return found;
}

typedef struct {
    uintptr_t ref;
    float tnear;
} stack_entry;

/* Push the children of n in `bits` (two or more) with their entry
 * distances, the nearest last (so popped first); returns the new top. */
static inline int push_sorted(stack_entry *stack, int sp, const wide_node *n, unsigned bits, const nfloat *tn) {
    int first = sp;
    for (; bits; bits &= bits - 1) {
        int k = __builtin_ctz(bits);
        stack_entry e = {n->child[k], (*tn)[k]};
        int j = sp++;
        while (j > first && stack[j - 1].tnear < e.tnear) { /* farther ones below */
            stack[j] = stack[j - 1];
            j--;
        }
        stack[j] = e;
    }
    return sp;
}

/* Walk the tree; with any_hit, stop at the first hit. */
static inline int walk(const accel_wide *wb, const scene *s, const ray *in, float tmax, hit *h, int any_hit) {
    h->t = tmax;
    h->prim = PRIM_NONE;
    h->b1 = h->b2 = 0.0f;
    if (!wb->root) return 0;
    walk_ray w;
    walk_ray_prepare(in, &w);
    float cull = accel_cull_distance(tmax);
    stack_entry stack[WIDE_STACK];
    int sp = 0, found = 0;
    uintptr_t cur = wb->root;
    for (;;) {
        if (!(cur & LEAF_TAG)) {
            const wide_node *n = (const wide_node *)cur;
            nfloat tn;
            unsigned bits = node_test(n, &w, cull, &tn);
            if (bits) {
                if ((bits & (bits - 1)) == 0) {
                    cur = n->child[__builtin_ctz(bits)];
                    continue;
                }
                sp = push_sorted(stack, sp, n, bits, &tn);
                cur = stack[--sp].ref;
                continue;
            }
        } else if (leaf_test((const wide_leaf *)(cur & ~LEAF_TAG), s, &w, tmax, h, any_hit)) {
            found = 1;
            if (any_hit) return 1;
            cull = accel_cull_distance(h->t);
        }
        /* Next: the nearest kept child still in front of the culling distance. */
        for (;;) {
            if (sp == 0) return found;
            stack_entry e = stack[--sp];
            if (e.tnear <= cull * SLAB_WIDEN) {
                cur = e.ref;
                break;
            }
        }
    }
}

int accel_wide_intersect(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h) {
    return walk(w, s, r, tmax, h, 0);
}

int accel_wide_occluded(const accel_wide *w, const scene *s, const ray *r, float tmax) {
    hit h;
    return walk(w, s, r, tmax, &h, 1);
}
