/* accel_wide_walk.h - the wide BVH's walk (accel_wide.c), written once for
 * any vector width: accel_wide.c includes it for 4 lanes (two SSE
 * registers per row of 8 children, four for a node of 16; leaves of 4
 * triangles; any x86-64) and for 8 lanes (one AVX register per row of 8
 * children, leaves of 8; compiled for AVX2 and, for its 32 registers, for
 * AVX-512VL), and picks the widest the CPU has at run time.
 *
 * Every width computes the same numbers: each lane of the node test is the
 * scalar (box - o) * inv_d, max, min and tnear <= tfar * SLAB_WIDEN, and
 * each lane of the leaf test is triangle_intersect's (the flat kernel's
 * watertight test, accel_flat.h): IEEE operations without FMA, the same
 * result on any ISA. Nor would a different walk or tree change the answer,
 * which hit_before and the margins define (accel_wide.h); the tests check
 * every walk against the BVH (mesh_wide_walk_isas_match_bvh).
 *
 * Before including, define WALK(name) (the name with a width suffix),
 * WALK_TARGET (a function attribute or nothing) and WALK_LANES (4 or 8:
 * lanes of the node test's vectors and of a leaf; NODE_W must be a
 * multiple), and WALK_COUNT(field) (accel_wide.c: a counter's increment,
 * or nothing). This file undefines the first three at its end. Not a
 * public header. */

/* The leaves' kernel at WALK_LANES lanes, compiled for this walk's target
 * (the 4-lane walk has none: the flat kernel's 4-lane build). */
#define FLAT_LANES_ONLY
#define FLAT(name) WALK(f4_##name)
#if WALK_LANES == 8
#define FLAT_LANES 8
#define FLAT_TARGET WALK_TARGET
#define FLAT_SPLAT(x) {x, x, x, x, x, x, x, x}
#define FLAT_LANE_IDS {0, 1, 2, 3, 4, 5, 6, 7}
#define FLAT_BITS(m) _mm256_movemask_ps((__m256)(m))
#include "accel_flat.h"
#else
#include "accel_flat4.h"
#endif
#undef FLAT_LANES_ONLY
#define lfloat WALK(f4_vfloat)
#define lint WALK(f4_vint)
/* Leaves of WALK_LANES primitives: one leaf test. */
#if WALK_LANES == 8
typedef wide_leaf8 WALK(leaf);
#else
typedef wide_leaf4 WALK(leaf);
#endif

/* The node test's vectors: WALK_LANES children's floats. */
#if WALK_LANES == 8
typedef __m256 WALK(nvec);
WALK_TARGET static inline __m256 WALK(nload)(const char *p) { return _mm256_load_ps((const float *)p); }
WALK_TARGET static inline __m256 WALK(nsplat)(float x) { return _mm256_set1_ps(x); }
WALK_TARGET static inline __m256 WALK(nsub)(__m256 a, __m256 b) { return _mm256_sub_ps(a, b); }
WALK_TARGET static inline __m256 WALK(nmul)(__m256 a, __m256 b) { return _mm256_mul_ps(a, b); }
WALK_TARGET static inline __m256 WALK(nmin)(__m256 a, __m256 b) { return _mm256_min_ps(a, b); }
WALK_TARGET static inline __m256 WALK(nmax)(__m256 a, __m256 b) { return _mm256_max_ps(a, b); }
WALK_TARGET static inline void WALK(nstore)(float *p, __m256 a) { _mm256_store_ps(p, a); }
/* Bit k set where lane k of a <= lane k of b. */
WALK_TARGET static inline unsigned WALK(nle_bits)(__m256 a, __m256 b) {
    return (unsigned)_mm256_movemask_ps(_mm256_cmp_ps(a, b, _CMP_LE_OQ));
}
#elif defined(__SSE2__)
typedef __m128 WALK(nvec);
WALK_TARGET static inline __m128 WALK(nload)(const char *p) { return _mm_load_ps((const float *)p); }
WALK_TARGET static inline __m128 WALK(nsplat)(float x) { return _mm_set1_ps(x); }
WALK_TARGET static inline __m128 WALK(nsub)(__m128 a, __m128 b) { return _mm_sub_ps(a, b); }
WALK_TARGET static inline __m128 WALK(nmul)(__m128 a, __m128 b) { return _mm_mul_ps(a, b); }
WALK_TARGET static inline __m128 WALK(nmin)(__m128 a, __m128 b) { return _mm_min_ps(a, b); }
WALK_TARGET static inline __m128 WALK(nmax)(__m128 a, __m128 b) { return _mm_max_ps(a, b); }
WALK_TARGET static inline void WALK(nstore)(float *p, __m128 a) { _mm_store_ps(p, a); }
WALK_TARGET static inline unsigned WALK(nle_bits)(__m128 a, __m128 b) {
    return (unsigned)_mm_movemask_ps(_mm_cmple_ps(a, b));
}
#else /* no SSE: the compiler's 16-byte vectors, min and max as SSE defines them */
typedef lfloat WALK(nvec);
WALK_TARGET static inline lfloat WALK(nload)(const char *p) { return *(const lfloat *)p; }
WALK_TARGET static inline lfloat WALK(nsplat)(float x) { return (lfloat)FLAT_SPLAT(x); }
WALK_TARGET static inline lfloat WALK(nsub)(lfloat a, lfloat b) { return a - b; }
WALK_TARGET static inline lfloat WALK(nmul)(lfloat a, lfloat b) { return a * b; }
WALK_TARGET static inline lfloat WALK(nmin)(lfloat a, lfloat b) {
    lint m = a < b;
    return (lfloat)(((lint)a & m) | ((lint)b & ~m));
}
WALK_TARGET static inline lfloat WALK(nmax)(lfloat a, lfloat b) {
    lint m = a > b;
    return (lfloat)(((lint)a & m) | ((lint)b & ~m));
}
WALK_TARGET static inline void WALK(nstore)(float *p, lfloat a) { *(lfloat *)p = a; }
WALK_TARGET static inline unsigned WALK(nle_bits)(lfloat a, lfloat b) {
    lint m = a <= b;
    return (m[0] & 1u) | (m[1] & 2u) | (m[2] & 4u) | (m[3] & 8u);
}
#endif
#define nvec WALK(nvec)

/* A ray prepared for the vector tests: the leaves' lanes (accel_flat.h),
 * the slab test's origin and inverse direction splatted, the byte offsets
 * of the rows of a node the ray enters and leaves by, and those of axes
 * kx, ky, kz in a leaf's vertex. The scalar tests' constants are a
 * ray_prep apart, whose address escapes to them: kept out of this struct,
 * they let the compiler keep this one in registers. */
typedef struct {
    WALK(f4_ray) lanes;
    nvec o[3], inv[3];
    const size_t *rows8, *rows16; /* octant_rows[0 and 1][the direction's octant] */
    size_t k[3];
} WALK(ray);

/* Fill w for the ray `in`. The shear constants are intersect.h's; the
 * inverse direction is safe_inverse's, the same bits: lane-wise IEEE
 * division where the direction is nonzero, else +-3e38 (its sign that of
 * the direction, also for -0). */
WALK_TARGET __attribute__((always_inline)) static inline void WALK(prepare)(const ray *in, ray_prep *r,
                                                                          WALK(ray) *w) {
    ray_prepare_shear(in, r); /* inv_d is left unset: only the node test reads it, from w->inv */
    const float o[3] = {in->o.x, in->o.y, in->o.z};
    float inv[4];
    unsigned down; /* bit a: the ray goes down axis a */
#ifdef __SSE2__
    __m128 d = _mm_setr_ps(in->d.x, in->d.y, in->d.z, 1.0f);
    __m128 q = _mm_div_ps(_mm_set1_ps(1.0f), d), zero = _mm_cmpeq_ps(d, _mm_setzero_ps());
    __m128 huge = _mm_or_ps(_mm_set1_ps(3.0e38f), _mm_and_ps(d, _mm_set1_ps(-0.0f)));
    _mm_storeu_ps(inv, _mm_or_ps(_mm_andnot_ps(zero, q), _mm_and_ps(zero, huge)));
    down = (unsigned)_mm_movemask_ps(d);
#else
    inv[0] = safe_inverse(in->d.x), inv[1] = safe_inverse(in->d.y), inv[2] = safe_inverse(in->d.z);
    down = (signbit(inv[0]) != 0) | (signbit(inv[1]) != 0) << 1 | (signbit(inv[2]) != 0) << 2;
#endif
    w->rows8 = octant_rows[0][down & 7];
    w->rows16 = octant_rows[1][down & 7];
    w->o[0] = WALK(nsplat)(o[0]), w->o[1] = WALK(nsplat)(o[1]), w->o[2] = WALK(nsplat)(o[2]);
    w->inv[0] = WALK(nsplat)(inv[0]), w->inv[1] = WALK(nsplat)(inv[1]), w->inv[2] = WALK(nsplat)(inv[2]);
    /* The leaves' lanes (accel_flat.h's ray_splat, without a count). */
    w->lanes.ox = WALK(f4_vsplat)(o[r->kx]);
    w->lanes.oy = WALK(f4_vsplat)(o[r->ky]);
    w->lanes.oz = WALK(f4_vsplat)(o[r->kz]);
    w->lanes.sx = WALK(f4_vsplat)(r->sx);
    w->lanes.sy = WALK(f4_vsplat)(r->sy);
    w->lanes.sz = WALK(f4_vsplat)(r->sz);
    w->lanes.skip = (lint)WALK(f4_vsplat)(0.0f) + (int32_t)r->skip;
    w->k[0] = sizeof(float) * WALK_LANES * (size_t)r->kx;
    w->k[1] = sizeof(float) * WALK_LANES * (size_t)r->ky;
    w->k[2] = sizeof(float) * WALK_LANES * (size_t)r->kz;
}

/* The slab test of the children of the node at n, of W slots (rows: its
 * octant's row offsets for W), against [0, cull]: returns the bits of the
 * children the ray may enter and writes their entry distances to tnear. */
WALK_TARGET __attribute__((always_inline)) static inline unsigned WALK(node_test)(const char *n, const unsigned W,
                                                                               const size_t *rows,
                                                                               const WALK(ray) *w, nvec cull,
                                                                               float tnear[NODE_W]) {
    const nvec zero = WALK(nsplat)(0.0f), widen = WALK(nsplat)(SLAB_WIDEN);
    unsigned bits = 0;
    for (unsigned i = 0; i < W; i += WALK_LANES) {
        const char *b = n + sizeof(float) * i;
        nvec nx = WALK(nmul)(WALK(nsub)(WALK(nload)(b + rows[0]), w->o[0]), w->inv[0]);
        nvec ny = WALK(nmul)(WALK(nsub)(WALK(nload)(b + rows[1]), w->o[1]), w->inv[1]);
        nvec nz = WALK(nmul)(WALK(nsub)(WALK(nload)(b + rows[2]), w->o[2]), w->inv[2]);
        nvec fx = WALK(nmul)(WALK(nsub)(WALK(nload)(b + rows[3]), w->o[0]), w->inv[0]);
        nvec fy = WALK(nmul)(WALK(nsub)(WALK(nload)(b + rows[4]), w->o[1]), w->inv[1]);
        nvec fz = WALK(nmul)(WALK(nsub)(WALK(nload)(b + rows[5]), w->o[2]), w->inv[2]);
        nvec tn = WALK(nmax)(WALK(nmax)(nx, ny), WALK(nmax)(nz, zero));
        nvec tf = WALK(nmin)(WALK(nmin)(fx, fy), WALK(nmin)(fz, cull));
        WALK(nstore)(tnear + i, tn);
        bits |= WALK(nle_bits)(tn, WALK(nmul)(tf, widen)) << i;
    }
    return bits;
}

/* The lanes of a leaf's vertex `vtx`, axis at byte offset `off`. */
WALK_TARGET static inline lfloat WALK(leaf_row)(const WALK(leaf) *l, int vtx, size_t off) {
    return *(const lfloat *)((const char *)l->v[vtx] + off);
}

/* Test the primitives of the leaf `ref` refers to with the caller's tmax
 * and fold every hit into *h by hit_before (h->t starts at tmax). Returns 1
 * if some primitive hit (with any_hit: as soon as one does). */
WALK_TARGET __attribute__((always_inline)) static inline int WALK(leaf_test)(uintptr_t ref, const scene *s,
                                                                            const ray_prep *r, const WALK(ray) *w,
                                                                            float tmax, hit *h, int any_hit) {
    const WALK(leaf) *l = (const WALK(leaf) *)(ref & ~REF_TAGS);
    int found = 0;
    WALK_COUNT(leaves);
    lint ids = *(const lint *)l->id;
    WALK(f4_group) g;
    /* Lanes without a triangle have NaN vertices: never candidates. */
    WALK(f4_test_loaded)(WALK(leaf_row)(l, 0, w->k[0]), WALK(leaf_row)(l, 0, w->k[1]), WALK(leaf_row)(l, 0, w->k[2]),
                         WALK(leaf_row)(l, 1, w->k[0]), WALK(leaf_row)(l, 1, w->k[1]), WALK(leaf_row)(l, 1, w->k[2]),
                         WALK(leaf_row)(l, 2, w->k[0]), WALK(leaf_row)(l, 2, w->k[1]), WALK(leaf_row)(l, 2, w->k[2]),
                         &w->lanes, ids != w->lanes.skip, tmax, &g);
    /* Lanes off the edges that hit: triangle_intersect's numbers, without calling it. */
    unsigned edge = WALK(f4_vbits)(g.edge);
    for (unsigned bits = WALK(f4_vbits)(g.ok) & ~edge; bits; bits &= bits - 1) {
        if (any_hit) return 1;
        int k = __builtin_ctz(bits);
        uint32_t id = l->id[k];
        float inv = 1.0f / g.det[k], t = g.T[k] * inv;
        if (hit_before(t, id, h)) {
            *h = (hit){t, id, g.V[k] * inv, g.W[k] * inv, &l->v[0][0][k], WALK_LANES}, found = 1;
            shading_normal_prefetch(s, id);
        }
    }
    /* Lanes on an edge (rare): the scalar test decides, in a loop of its
     * own so that the one above calls nothing. */
    for (; edge; edge &= edge - 1) {
        int k = __builtin_ctz(edge);
        uint32_t id = l->id[k];
        float t, b1, b2;
        if (!triangle_intersect(r, &s->triangles[id], tmax, &t, &b1, &b2)) continue;
        if (any_hit) return 1;
        if (hit_before(t, id, h)) *h = (hit){t, id, b1, b2, &l->v[0][0][k], WALK_LANES}, found = 1;
    }
    if (!(ref & SPHERE_TAG)) return found;
    for (int k = 0; k < WALK_LANES; k++) { /* the spheres' lanes: ids from the triangle count up */
        uint32_t id = l->id[k];
        float t;
        if (id == PRIM_NONE || id < s->triangle_count) continue;
        if (!sphere_intersect(r, &s->spheres[id - s->triangle_count], id == r->skip, tmax, &t)) continue;
        if (any_hit) return 1;
        if (hit_before(t, id, h)) *h = (hit){t, id, 0.0f, 0.0f, NULL, 0}, found = 1;
    }
    return found;
}

/* A walk in progress: the ray, the next reference to visit, the stack of
 * children kept for later and the best hit so far. Resumable one step at a
 * time, so that two walks can take turns (WALK(pair)). */
typedef struct {
    ray_prep r;  /* what the scalar tests read (edge lanes, spheres) */
    WALK(ray) w; /* what the vector tests read */
    float tmax, cull, cull_wide;
    uintptr_t cur;
    int sp, found;
    hit *h;
    stack_entry stack[WIDE_STACK];
} WALK(state);

/* Start a walk of `in` with tmax into *st, its hit to go to *h. Returns 1
 * if there is a tree to walk, else 0 (a miss, *h reset). */
WALK_TARGET __attribute__((always_inline)) static inline int WALK(start)(const accel_wide *wb, const ray *in,
                                                                      float tmax, hit *h, WALK(state) *st) {
    h->t = tmax;
    h->prim = PRIM_NONE;
    h->b1 = h->b2 = 0.0f;
    h->corners = NULL;
    st->h = h;
    WALK_COUNT(walks);
    st->cur = wb->root;
    st->sp = st->found = 0;
    if (!st->cur) return 0;
    WALK(prepare)(in, &st->r, &st->w);
    st->tmax = tmax;
    st->cull = accel_cull_distance(tmax);
    st->cull_wide = st->cull * SLAB_WIDEN;
    return 1;
}

/* One step of a walk: visit st->cur (a node's test, or a leaf's) and choose
 * the next reference; with any_hit, stop at the first hit. Of a node's
 * children hit, the nearest is visited next and the others pushed, the
 * farthest deepest (for any_hit, in any order); an entry popped behind the
 * culling distance is dropped (the condition the node test would apply).
 * The children pushed are prefetched as they are pushed, and a node's line
 * of child references with its boxes, so that neither waits on memory
 * after the node test (2026-11-26, paired runs, one thread per core:
 * whole-run CPU -7.7% at 655k triangles, -5.5% at 2.6M, -3.5% at 164k and
 * Suzanne's 2.0M, none at 41k). Returns 1 while the walk goes on, 0 when it
 * has ended, st->found then saying whether something was hit. */
WALK_TARGET __attribute__((always_inline)) static inline int WALK(step)(const scene *s, WALK(state) *st,
                                                                     int any_hit) {
    uintptr_t cur = st->cur;
    stack_entry *stack = st->stack;
    int sp = st->sp;
    if (!(cur & LEAF_TAG)) {
        const uintptr_t *child = node_children(cur);
        /* The children's line, fetched with the boxes' rather than after the test. */
        __builtin_prefetch(child);
        WALK_COUNT(nodes);
        float tn[NODE_W] __attribute__((aligned(32)));
        const char *n = (const char *)(cur & ~REF_TAGS);
        unsigned bits = cur & NODE16_TAG ? WALK(node_test)(n, NODE_W, st->w.rows16, &st->w, WALK(nsplat)(st->cull), tn)
                                         : WALK(node_test)(n, NODE_SMALL, st->w.rows8, &st->w, WALK(nsplat)(st->cull), tn);
        if (bits) {
            int k = __builtin_ctz(bits);
            cur = child[k];
            unsigned rest = bits & (bits - 1);
            if (!rest) return st->cur = cur, 1;
            if (any_hit) { /* any order will do: keep the others as they come */
                for (; rest; rest &= rest - 1) {
                    uintptr_t c = child[__builtin_ctz(rest)];
                    prefetch_ref(c);
                    stack[sp++].ref = c;
                }
                return st->cur = cur, st->sp = sp, 1;
            }
            if (!(rest & (rest - 1))) { /* two: keep the farther */
                int j = __builtin_ctz(rest);
                uintptr_t other = child[j];
                float t = tn[j];
                if (tn[j] < tn[k]) t = tn[k], other = cur, cur = child[j];
                prefetch_ref(other);
                stack[sp++] = (stack_entry){other, t};
                return st->cur = cur, st->sp = sp, 1;
            }
            sp = push_sorted(stack, sp, child, bits, tn);
            st->cur = stack[--sp].ref;
            st->sp = sp;
            return 1;
        }
    } else if (WALK(leaf_test)(cur, s, &st->r, &st->w, st->tmax, st->h, any_hit)) {
        st->found = 1;
        if (any_hit) return 0;
        st->cull = accel_cull_distance(st->h->t);
        st->cull_wide = st->cull * SLAB_WIDEN;
    }
    /* Next: the nearest kept child still in front of the culling
     * distance. A shadow ray's never shrinks, and every child kept
     * passed tnear <= min(tfar, cull) * SLAB_WIDEN: none to drop. */
    if (any_hit) {
        if (sp == 0) return 0;
        st->cur = stack[--sp].ref;
        st->sp = sp;
        return 1;
    }
    do {
        if (sp == 0) return 0;
    } while (!(stack[--sp].tnear <= st->cull_wide));
    st->cur = stack[sp].ref;
    st->sp = sp;
    return 1;
}

/* A whole walk of one ray: its steps until the end. */
WALK_TARGET __attribute__((always_inline)) static inline int WALK(walk)(const accel_wide *w, const scene *s,
                                                                     const ray *r, float tmax, hit *h, int any_hit) {
    WALK(state) st;
    if (!WALK(start)(w, r, tmax, h, &st)) return 0;
    while (WALK(step)(s, &st, any_hit)) {
    }
    return st.found;
}

WALK_TARGET static int WALK(intersect)(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h) {
    return WALK(walk)(w, s, r, tmax, h, 0);
}

WALK_TARGET static int WALK(occluded)(const accel_wide *w, const scene *s, const ray *r, float tmax) {
    hit h;
    return WALK(walk)(w, s, r, tmax, &h, 1);
}

/* The closest hit of r and whether sh is occluded, the two walks taking
 * turns a step each, so that while one waits for a node from memory the
 * CPU works on the other. The same answers as WALK(intersect) and
 * WALK(occluded): each walk visits what it would alone, in the same order. */
WALK_TARGET static int WALK(pair)(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h,
                                  const ray *sh, float sh_tmax, int *occluded) {
    hit hs;
    WALK(state) a, b;
    int ga = WALK(start)(w, r, tmax, h, &a), gb = WALK(start)(w, sh, sh_tmax, &hs, &b);
    while (ga && gb) {
        ga = WALK(step)(s, &a, 0);
        gb = WALK(step)(s, &b, 1);
    }
    while (ga) ga = WALK(step)(s, &a, 0);
    while (gb) gb = WALK(step)(s, &b, 1);
    *occluded = b.found;
    return a.found;
}

#undef nvec
#undef lfloat
#undef lint
#undef WALK
#undef WALK_TARGET
#undef WALK_LANES
