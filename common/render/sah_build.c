/* sah_build.c - the binned SAH builder of sah_build.h.
 *
 * A set is a range of the primitive array with two boxes: the union of its
 * primitives' boxes (geom) and the bounds of their centres (cent, kept
 * doubled as lo + hi: the same order and the same bins, one addition
 * fewer). Splitting a set bins its centres along each axis, sweeps the bins
 * for the cheapest plane, then partitions the range in place, the two
 * sides' boxes gathered on the way. Every step is exact (minima, maxima,
 * counts) or the same operation on the same numbers, so the tree depends
 * on the boxes alone: the top is built on the calling thread, the subtrees
 * it leaves (deferred sets, each its own range) are then built by par.h's
 * threads, taken largest first. */
#include "sah_build.h"

#include <immintrin.h>
#include <math.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>

#include "par.h"

#define SAH_BINS 32
/* Levels kept for a set that reaches the depth limit unsplit: below
 * max_depth - LARGE_LEAF_LEVELS a set is cut by index into `width` parts a
 * level, so even 2^32 primitives end in leaves within the limit. */
#define LARGE_LEAF_LEVELS 11
/* A set is deferred to the threads below the top when it holds at most
 * 1 / (2 threads) of the primitives, but never one of fewer than this. */
#define DEFER_MIN 4096
/* Sets of at least this many primitives are binned by every thread at once. */
#define PAR_BIN_MIN (1u << 18)

typedef struct {
    __m128 lo, hi; /* lane 3 unused */
} box4;

typedef struct {
    size_t begin, end;
    box4 geom, cent;
} set;

/* How a set's centres map to bins: bin = clamp(floor((c - ofs) * scale)). */
typedef struct {
    unsigned nbins;
    __m128 ofs, scale, top; /* top: nbins - 1 */
} bin_map;

typedef struct {
    box4 box[3][SAH_BINS];
    uint32_t count[3][SAH_BINS];
} bins;

/* Bin a range of the primitive array into bins (choose_binning). */
typedef void (*bin_fn)(const sah_prim *p, size_t begin, size_t end, const bin_map *m, bins *b);

/* A split: the bin plane `pos` on `axis` (left: bins below pos), its cost
 * (the two sides' areas times their blocks); axis -1 when no plane leaves
 * primitives on both sides. */
typedef struct {
    int axis;
    unsigned pos;
    float cost;
    bin_map map;
} split;

/* A set left for the threads: it becomes child k of node. */
typedef struct {
    set s;
    unsigned depth, k;
    void *node;
} task;

typedef struct {
    const sah_args *a;
    sah_prim *prims;
    size_t defer_max; /* sets up to this size are deferred (0: none) */
    task *tasks;
    size_t task_count, task_cap;
    atomic_size_t next_task;
    atomic_int failed;
    int threads;     /* par.h's threads for the deferred sets */
    int bin_threads; /* threads that bin one large set at once: 1 once the deferred sets run */
    bin_fn bin;
} build;

static inline box4 box_empty(void) { return (box4){_mm_set1_ps(INFINITY), _mm_set1_ps(-INFINITY)}; }

static inline void box_grow(box4 *b, __m128 lo, __m128 hi) {
    b->lo = _mm_min_ps(b->lo, lo);
    b->hi = _mm_max_ps(b->hi, hi);
}

static inline void box_merge(box4 *b, const box4 *o) { box_grow(b, o->lo, o->hi); }

/* Half the surface area of a non-empty box. */
static inline float half_area(const box4 *b) {
    float d[4];
    _mm_storeu_ps(d, _mm_sub_ps(b->hi, b->lo));
    return d[0] * d[1] + d[1] * d[2] + d[2] * d[0];
}

static inline float blocks(const sah_args *a, size_t n) { return (float)((n + a->block - 1) / a->block); }

static inline __m128 prim_lo(const sah_prim *p) { return _mm_load_ps(p->lo); }
static inline __m128 prim_hi(const sah_prim *p) { return _mm_load_ps(p->hi); }

/* A primitive's bin on each axis (lanes 0-2). */
static inline __m128i bin_of(const bin_map *m, __m128 lo, __m128 hi) {
    __m128 pos = _mm_mul_ps(_mm_sub_ps(_mm_add_ps(lo, hi), m->ofs), m->scale);
    return _mm_cvttps_epi32(_mm_min_ps(_mm_max_ps(pos, _mm_setzero_ps()), m->top));
}

/* Up to 32 bins, fewer for small sets (Embree's rule: 4 + n / 20); an axis
 * along which the centres do not spread gets scale 0 (one bin). */
static bin_map map_for(const set *s) {
    bin_map m;
    size_t n = s->end - s->begin;
    m.nbins = n / 20 + 4 < SAH_BINS ? (unsigned)(n / 20 + 4) : SAH_BINS;
    float lo[4], hi[4], sc[4] = {0, 0, 0, 0};
    _mm_storeu_ps(lo, s->cent.lo);
    _mm_storeu_ps(hi, s->cent.hi);
    for (int a = 0; a < 3; a++) {
        float ext = hi[a] - lo[a];
        if (ext > 0.0f && isfinite(ext)) sc[a] = 0.99f * (float)m.nbins / ext;
    }
    m.ofs = s->cent.lo;
    m.scale = _mm_loadu_ps(sc);
    m.top = _mm_set1_ps((float)(m.nbins - 1));
    return m;
}

static void bins_clear(bins *b, unsigned nbins) {
    for (int a = 0; a < 3; a++)
        for (unsigned i = 0; i < nbins; i++) b->box[a][i] = box_empty(), b->count[a][i] = 0;
}

static inline void bin_one(bins *b, __m128 lo, __m128 hi, const bin_map *m) {
    __m128i bi = bin_of(m, lo, hi);
    int ix = _mm_cvtsi128_si32(bi), iy = _mm_cvtsi128_si32(_mm_shuffle_epi32(bi, 0x55)),
        iz = _mm_cvtsi128_si32(_mm_shuffle_epi32(bi, 0xaa));
    box_grow(&b->box[0][ix], lo, hi), b->count[0][ix]++;
    box_grow(&b->box[1][iy], lo, hi), b->count[1][iy]++;
    box_grow(&b->box[2][iz], lo, hi), b->count[2][iz]++;
}

static void bins_merge(bins *b, const bins *o, unsigned nbins) {
    for (int a = 0; a < 3; a++)
        for (unsigned i = 0; i < nbins; i++) box_merge(&b->box[a][i], &o->box[a][i]), b->count[a][i] += o->count[a][i];
}

/* Bin p[begin .. end) into b (cleared first). Two or four sets of bins
 * for alternate primitives (so that a bin's update need not wait on the
 * last) were no faster (docs/meshes.md). */
static void bin_range_sse(const sah_prim *p, size_t begin, size_t end, const bin_map *m, bins *b) {
    bins_clear(b, m->nbins);
    for (size_t i = begin; i < end; i++) bin_one(b, prim_lo(&p[i]), prim_hi(&p[i]), m);
}

#if defined(__x86_64__) && defined(__GNUC__)
/* bin_range_sse with AVX2: a bin's box is one 8-lane register, the lower
 * corner negated (lanes 0-2) beside the upper (lanes 4-6), so one maximum
 * updates both; the bin indices are bin_of's. The same bins exactly
 * (negation is exact): 7.5-10.7 against 11.2-14.5 ns per primitive
 * (docs/meshes.md). */
typedef struct {
    __m256 box[3][SAH_BINS];
    uint32_t count[3][SAH_BINS];
} bins8;

__attribute__((target("avx2"))) static void bin_range_avx2(const sah_prim *p, size_t begin, size_t end,
                                                            const bin_map *m, bins *out) {
    bins8 b;
    const __m256 neg_lo = _mm256_setr_ps(-0.0f, -0.0f, -0.0f, -0.0f, 0.0f, 0.0f, 0.0f, 0.0f);
    for (int a = 0; a < 3; a++)
        for (unsigned i = 0; i < m->nbins; i++) b.box[a][i] = _mm256_set1_ps(-INFINITY), b.count[a][i] = 0;
    for (size_t i = begin; i < end; i++) {
        __m256 v = _mm256_load_ps(p[i].lo); /* lo, id, hi, pad */
        int idx[4];
        _mm_storeu_si128((__m128i *)idx, bin_of(m, _mm256_castps256_ps128(v), _mm256_extractf128_ps(v, 1)));
        __m256 nv = _mm256_xor_ps(v, neg_lo);
        for (int a = 0; a < 3; a++) b.box[a][idx[a]] = _mm256_max_ps(b.box[a][idx[a]], nv), b.count[a][idx[a]]++;
    }
    const __m128 sign = _mm_set1_ps(-0.0f);
    for (int a = 0; a < 3; a++)
        for (unsigned i = 0; i < m->nbins; i++) {
            out->box[a][i].lo = _mm_xor_ps(_mm256_castps256_ps128(b.box[a][i]), sign);
            out->box[a][i].hi = _mm256_extractf128_ps(b.box[a][i], 1);
            out->count[a][i] = b.count[a][i];
        }
}
#endif

/* The binning this CPU runs: AVX2's unless TESSERA_NO_AVX2 is set (as for
 * the walks), else SSE's; the same bins either way. */
static bin_fn choose_binning(void) {
#if defined(__x86_64__) && defined(__GNUC__)
    if (!getenv("TESSERA_NO_AVX2") && __builtin_cpu_supports("avx2")) return bin_range_avx2;
#endif
    return bin_range_sse;
}

/* Binning by every thread at once: each part bins its own range, the parts
 * are merged (minima, maxima and sums: the same bins in any order). */
typedef struct {
    const sah_prim *p;
    size_t begin;
    const bin_map *m;
    bin_fn bin;
    bins part[PAR_MAX_PARTS];
} par_bins;

static void bin_part(void *ctx, size_t begin, size_t end, int part) {
    par_bins *P = ctx;
    P->bin(P->p, P->begin + begin, P->begin + end, P->m, &P->part[part]);
}

static void bin_set(build *B, const set *s, const bin_map *m, bins *out) {
    size_t n = s->end - s->begin;
    par_bins *P = B->bin_threads < 2 || n < PAR_BIN_MIN ? NULL : malloc(sizeof *P);
    if (!P) { /* one thread (also when out of memory): the same bins */
        B->bin(B->prims, s->begin, s->end, m, out);
        return;
    }
    P->p = B->prims, P->begin = s->begin, P->m = m, P->bin = B->bin;
    int parts = B->bin_threads < PAR_MAX_PARTS ? B->bin_threads : PAR_MAX_PARTS;
    par_run(n, parts, bin_part, P);
    *out = P->part[0];
    for (int k = 1; k < parts; k++) bins_merge(out, &P->part[k], m->nbins);
    free(P);
}

/* The cheapest bin plane of s: per axis, the right sides' areas by a sweep
 * from the top bin, then the left sides' from the bottom; cost = left area x
 * left blocks + right area x right blocks, the first of equal costs kept. */
static split find_split(build *B, const set *s) {
    split best = {.axis = -1, .cost = INFINITY, .map = map_for(s)};
    const bin_map *m = &best.map;
    float sc[4];
    _mm_storeu_ps(sc, m->scale);
    bins b;
    bin_set(B, s, m, &b);
    for (int a = 0; a < 3; a++) {
        if (sc[a] == 0.0f) continue;
        float right_area[SAH_BINS];
        size_t right_count[SAH_BINS];
        box4 acc = box_empty();
        size_t cnt = 0;
        for (unsigned i = m->nbins - 1; i > 0; i--) {
            box_merge(&acc, &b.box[a][i]);
            cnt += b.count[a][i];
            right_count[i] = cnt;
            right_area[i] = cnt ? half_area(&acc) : 0.0f;
        }
        acc = box_empty();
        cnt = 0;
        for (unsigned i = 1; i < m->nbins; i++) {
            box_merge(&acc, &b.box[a][i - 1]);
            cnt += b.count[a][i - 1];
            if (!cnt || !right_count[i]) continue;
            float cost = half_area(&acc) * blocks(B->a, cnt) + right_area[i] * blocks(B->a, right_count[i]);
            if (cost < best.cost) best.cost = cost, best.axis = a, best.pos = i;
        }
    }
    return best;
}

/* A split's plane on its axis alone: the map's offset, scale and top bin
 * there, and the first bin on the right. */
typedef struct {
    int axis;
    float ofs, scale, top;
    int pos;
} plane;

static plane plane_of(const split *sp) {
    float o[4], sc[4];
    _mm_storeu_ps(o, sp->map.ofs);
    _mm_storeu_ps(sc, sp->map.scale);
    return (plane){sp->axis, o[sp->axis], sc[sp->axis], (float)(sp->map.nbins - 1), (int)sp->pos};
}

/* Whether p's centre is below the plane: bin_of's operations on the plane's
 * axis alone, so the same bin as binning gave it. */
static inline int goes_left(const plane *pl, const sah_prim *p) {
    int a = pl->axis;
    float pos = (p->lo[a] + p->hi[a] - pl->ofs) * pl->scale;
    pos = pos > 0.0f ? pos : 0.0f;
    pos = pos < pl->top ? pos : pl->top;
    return (int)pos < pl->pos;
}

static inline void set_grow(set *s, const sah_prim *p) {
    __m128 lo = prim_lo(p), hi = prim_hi(p), c = _mm_add_ps(lo, hi);
    box_grow(&s->geom, lo, hi);
    box_grow(&s->cent, c, c);
}

static set set_new(size_t begin, size_t end) { return (set){begin, end, box_empty(), box_empty()}; }

/* Split p[begin .. end) in place by pl: the left side's primitives first,
 * into *l and *r with their boxes. */
static void partition_range(sah_prim *p, size_t begin, size_t end, const plane *pl, set *l, set *r) {
    size_t i = begin, j = end;
    set L = set_new(0, 0), R = set_new(0, 0);
    for (;;) {
        while (i < j && goes_left(pl, &p[i])) set_grow(&L, &p[i]), i++;
        while (i < j && !goes_left(pl, &p[j - 1])) set_grow(&R, &p[j - 1]), j--;
        if (i >= j) break;
        sah_prim t = p[i];
        p[i] = p[j - 1], p[j - 1] = t;
        set_grow(&L, &p[i]), set_grow(&R, &p[j - 1]);
        i++, j--;
    }
    *l = L, *r = R;
    l->begin = begin, l->end = i;
    r->begin = i, r->end = end;
}

/* A large set's partition in chunks of PAR_SPLIT_CHUNK primitives, a
 * number fixed by the set's size alone, so the order it leaves (which a
 * middle split and build_large read) is the same on any number of
 * threads: each chunk is partitioned in place (by par.h's threads when the
 * build bins on several), then the right-side primitives in the final left
 * range are swapped, k-th with k-th in chunk order, with the left-side ones
 * in the final right range. */
#define PAR_SPLIT_CHUNK ((size_t)1 << 16)
#define PAR_SPLIT_MAX_CHUNKS 1024 /* larger sets take larger chunks */

typedef struct {
    sah_prim *p;
    size_t begin, end, chunk, chunks;
    plane pl;
    set side[PAR_SPLIT_MAX_CHUNKS][2];
    /* The swaps: the misplaced right-side runs (in the final left range)
     * and left-side runs (in the final right range), in chunk order. */
    size_t run_r[PAR_SPLIT_MAX_CHUNKS][2], run_l[PAR_SPLIT_MAX_CHUNKS][2];
    size_t runs_r, runs_l, swaps;
} par_split;

static void split_chunks(void *ctx, size_t begin, size_t end, int part) {
    par_split *P = ctx;
    (void)part;
    for (size_t c = begin; c < end; c++) {
        size_t b = P->begin + c * P->chunk, e = b + P->chunk < P->end ? b + P->chunk : P->end;
        partition_range(P->p, b, e, &P->pl, &P->side[c][0], &P->side[c][1]);
    }
}

/* The position of the k-th element of runs[0 .. count). */
static size_t run_at(size_t (*runs)[2], size_t count, size_t k) {
    for (size_t i = 0; i < count; i++) {
        size_t len = runs[i][1] - runs[i][0];
        if (k < len) return runs[i][0] + k;
        k -= len;
    }
    return runs[count - 1][1]; /* not reached: k < the runs' total */
}

static void split_swaps(void *ctx, size_t begin, size_t end, int part) {
    par_split *P = ctx;
    (void)part;
    if (begin >= end) return;
    size_t i = run_at(P->run_r, P->runs_r, begin), j = run_at(P->run_l, P->runs_l, begin);
    size_t ri = 0, lj = 0; /* the runs holding i and j */
    while (!(i >= P->run_r[ri][0] && i < P->run_r[ri][1])) ri++;
    while (!(j >= P->run_l[lj][0] && j < P->run_l[lj][1])) lj++;
    for (size_t k = begin; k < end; k++) {
        sah_prim t = P->p[i];
        P->p[i] = P->p[j], P->p[j] = t;
        if (++i == P->run_r[ri][1] && ri + 1 < P->runs_r) i = P->run_r[++ri][0];
        if (++j == P->run_l[lj][1] && lj + 1 < P->runs_l) j = P->run_l[++lj][0];
    }
}

/* partition's plane split of a large set s (PAR_BIN_MIN primitives or
 * more). Returns -1 when out of memory (nothing moved). */
static int partition_chunks(build *B, const set *s, const plane *pl, set *l, set *r) {
    par_split *P = malloc(sizeof *P);
    if (!P) return -1;
    size_t n = s->end - s->begin;
    P->p = B->prims, P->begin = s->begin, P->end = s->end, P->pl = *pl;
    P->chunk = PAR_SPLIT_CHUNK;
    while ((n + P->chunk - 1) / P->chunk > PAR_SPLIT_MAX_CHUNKS) P->chunk *= 2;
    P->chunks = (n + P->chunk - 1) / P->chunk;
    int parts = B->bin_threads < PAR_MAX_PARTS ? B->bin_threads : PAR_MAX_PARTS;
    if (parts > 1) par_run(P->chunks, parts, split_chunks, P);
    else split_chunks(P, 0, P->chunks, 0);
    set L = set_new(0, 0), R = set_new(0, 0);
    size_t lefts = 0;
    for (size_t c = 0; c < P->chunks; c++) {
        box_merge(&L.geom, &P->side[c][0].geom), box_merge(&L.cent, &P->side[c][0].cent);
        box_merge(&R.geom, &P->side[c][1].geom), box_merge(&R.cent, &P->side[c][1].cent);
        lefts += P->side[c][0].end - P->side[c][0].begin;
    }
    size_t mid = s->begin + lefts;
    P->runs_r = P->runs_l = P->swaps = 0;
    for (size_t c = 0; c < P->chunks; c++) {
        const set *cl = &P->side[c][0], *cr = &P->side[c][1];
        if (cr->begin < mid && cr->begin < cr->end) { /* right-side primitives left of mid */
            size_t e = cr->end < mid ? cr->end : mid;
            P->run_r[P->runs_r][0] = cr->begin, P->run_r[P->runs_r][1] = e, P->runs_r++;
            P->swaps += e - cr->begin;
        }
        if (cl->end > mid && cl->begin < cl->end) { /* left-side primitives right of mid */
            size_t b = cl->begin > mid ? cl->begin : mid;
            P->run_l[P->runs_l][0] = b, P->run_l[P->runs_l][1] = cl->end, P->runs_l++;
        }
    }
    if (P->swaps) {
        if (parts > 1) par_run(P->swaps, parts, split_swaps, P);
        else split_swaps(P, 0, P->swaps, 0);
    }
    free(P);
    *l = L, *r = R;
    l->begin = s->begin, l->end = mid;
    r->begin = mid, r->end = s->end;
    return 0;
}

/* Split s in two, in place: by sp's plane, or (no plane) at the middle of
 * the range. Both sides get their boxes. A set of PAR_BIN_MIN primitives
 * or more is split in chunks (partition_chunks), on every thread while
 * the top of the tree is built: at 2.6M triangles one core idled through
 * the top's partitions (a perf timeline, docs/meshes.md). Returns -1 when
 * out of memory. */
static int partition(build *B, const set *s, const split *sp, set *l, set *r) {
    sah_prim *p = B->prims;
    if (sp->axis < 0) {
        size_t mid = s->begin + (s->end - s->begin) / 2;
        *l = set_new(s->begin, mid), *r = set_new(mid, s->end);
        for (size_t i = l->begin; i < l->end; i++) set_grow(l, &p[i]);
        for (size_t i = r->begin; i < r->end; i++) set_grow(r, &p[i]);
        return 0;
    }
    plane pl = plane_of(sp);
    if (s->end - s->begin >= PAR_BIN_MIN) return partition_chunks(B, s, &pl, l, r);
    partition_range(p, s->begin, s->end, &pl, l, r);
    return 0;
}

/* A leaf of s's primitives, in order of id. */
static void *make_leaf(build *B, const set *s) {
    sah_prim *p = B->prims + s->begin;
    size_t n = s->end - s->begin;
    for (size_t i = 1; i < n; i++) {
        sah_prim t = p[i];
        size_t j = i;
        for (; j > 0 && p[j - 1].id > t.id; j--) p[j] = p[j - 1];
        p[j] = t;
    }
    return B->a->create_leaf(p, n, B->a->user);
}

static void *build_set(build *B, const set *s, unsigned depth);

static int task_push(build *B, const set *s, unsigned depth, void *node, unsigned k) {
    if (B->task_count == B->task_cap) {
        size_t cap = B->task_cap ? 2 * B->task_cap : 64;
        task *t = realloc(B->tasks, cap * sizeof *t);
        if (!t) return -1;
        B->tasks = t, B->task_cap = cap;
    }
    B->tasks[B->task_count++] = (task){*s, depth, k, node};
    return 0;
}

/* Make child (the subtree of set c) child k of node, with c's box. */
static void attach(build *B, void *node, unsigned k, void *child, const set *c) {
    float lo[4], hi[4];
    _mm_storeu_ps(lo, c->geom.lo);
    _mm_storeu_ps(hi, c->geom.hi);
    B->a->set_child(node, k, child, lo, hi, B->a->user);
}

/* A node over children[0 .. count): each built now, or deferred. */
static void *make_node(build *B, set *children, unsigned count, unsigned depth) {
    void *node = B->a->create_node(count, B->a->user);
    if (!node) return NULL;
    for (unsigned k = 0; k < count; k++) {
        const set *c = &children[k];
        if (c->end - c->begin <= B->defer_max) {
            if (task_push(B, c, depth + 1, node, k) != 0) return NULL;
            continue;
        }
        void *child = build_set(B, c, depth + 1);
        if (!child) return NULL;
        attach(B, node, k, child, c);
    }
    return node;
}

/* A set too deep for the SAH: cut by index into `width` parts a level. */
static void *build_large(build *B, const set *s, unsigned depth) {
    size_t n = s->end - s->begin;
    if (n <= B->a->leaf_max) return make_leaf(B, s);
    set children[SAH_MAX_WIDTH];
    unsigned count = B->a->width;
    size_t per = (n + count - 1) / count;
    if (per < B->a->leaf_max) per = B->a->leaf_max;
    unsigned c = 0;
    for (size_t b = s->begin; b < s->end; b += per, c++) {
        children[c] = set_new(b, b + per < s->end ? b + per : s->end);
        for (size_t i = children[c].begin; i < children[c].end; i++) set_grow(&children[c], &B->prims[i]);
    }
    void *node = B->a->create_node(c, B->a->user);
    if (!node) return NULL;
    for (unsigned k = 0; k < c; k++) {
        void *child = build_large(B, &children[k], depth + 1);
        if (!child) return NULL;
        attach(B, node, k, child, &children[k]);
    }
    return node;
}

/* The subtree of s, whose root is at `depth`: a leaf, or a node whose
 * children come from splitting s and then, while there is room, the
 * splittable child with the largest box (Embree's generic builder). */
static void *build_set(build *B, const set *s, unsigned depth) {
    const sah_args *a = B->a;
    size_t n = s->end - s->begin;
    if (atomic_load_explicit(&B->failed, memory_order_relaxed)) return NULL;
    if (n > 4096 && a->cancelled && a->cancelled(a->user)) return atomic_store(&B->failed, 1), NULL;
    if (n <= a->leaf_min) return make_leaf(B, s);
    if (depth + LARGE_LEAF_LEVELS >= a->max_depth) return build_large(B, s, depth);
    split sp = find_split(B, s);
    if (n <= a->leaf_max) {
        float area = half_area(&s->geom);
        float leaf_cost = a->isect_cost * area * blocks(a, n);
        float split_cost = a->trav_cost * area + a->isect_cost * sp.cost;
        if (leaf_cost <= split_cost) return make_leaf(B, s);
    }
    set children[SAH_MAX_WIDTH];
    if (partition(B, s, &sp, &children[0], &children[1]) != 0) return atomic_store(&B->failed, 1), NULL;
    unsigned count = 2;
    while (count < a->width) {
        int pick = -1;
        float pick_area = -INFINITY;
        for (unsigned k = 0; k < count; k++) {
            if (children[k].end - children[k].begin <= a->leaf_min) continue;
            float area = half_area(&children[k].geom);
            if (area > pick_area) pick = (int)k, pick_area = area;
        }
        if (pick < 0) break;
        set whole = children[pick];
        split csp = find_split(B, &whole);
        if (partition(B, &whole, &csp, &children[pick], &children[count]) != 0)
            return atomic_store(&B->failed, 1), NULL;
        count++;
    }
    return make_node(B, children, count, depth);
}

/* par_run's body: each thread takes deferred sets, largest first, until
 * none are left. */
static void run_tasks(void *ctx, size_t begin, size_t end, int part) {
    build *B = ctx;
    (void)begin, (void)end, (void)part;
    for (;;) {
        size_t i = atomic_fetch_add(&B->next_task, 1);
        if (i >= B->task_count) return;
        task *t = &B->tasks[i];
        void *child = build_set(B, &t->s, t->depth);
        if (!child) {
            atomic_store(&B->failed, 1);
            return;
        }
        attach(B, t->node, t->k, child, &t->s);
    }
}

static int task_larger(const void *x, const void *y) {
    const task *a = x, *b = y;
    size_t na = a->s.end - a->s.begin, nb = b->s.end - b->s.begin;
    if (na != nb) return na > nb ? -1 : 1;
    return a->s.begin < b->s.begin ? -1 : 1; /* ranges are disjoint */
}

/* The whole set's boxes, every thread a range. */
typedef struct {
    const sah_prim *p;
    set part[PAR_MAX_PARTS];
} par_bounds;

static void bounds_part(void *ctx, size_t begin, size_t end, int part) {
    par_bounds *P = ctx;
    set s = set_new(begin, end);
    for (size_t i = begin; i < end; i++) set_grow(&s, &P->p[i]);
    P->part[part] = s;
}

int sah_build_threads(size_t n) { return par_parts(n, DEFER_MIN); }

void *sah_build(const sah_args *a, sah_prim *prims, size_t n) {
    if (a->width < 2 || a->width > SAH_MAX_WIDTH) return NULL; /* the children arrays hold SAH_MAX_WIDTH */
    build B = {.a = a, .prims = prims, .bin = choose_binning()};
    B.threads = B.bin_threads = sah_build_threads(n);
    par_bounds *P = malloc(sizeof *P);
    if (!P) return NULL;
    P->p = prims;
    par_run(n, B.threads, bounds_part, P);
    set root = set_new(0, n);
    for (int k = 0; k < B.threads; k++) box_merge(&root.geom, &P->part[k].geom), box_merge(&root.cent, &P->part[k].cent);
    free(P);
    if (B.threads > 1 && n / (2 * (size_t)B.threads) >= DEFER_MIN) B.defer_max = n / (2 * (size_t)B.threads);
    void *ref = build_set(&B, &root, 0);
    if (ref && B.task_count) {
        /* The deferred sets' own subtrees are built where they are taken:
         * nothing more is deferred, no set is binned by several threads. */
        B.defer_max = 0, B.bin_threads = 1;
        qsort(B.tasks, B.task_count, sizeof *B.tasks, task_larger);
        par_run((size_t)B.threads, B.threads, run_tasks, &B);
    }
    free(B.tasks);
    if (atomic_load(&B.failed)) return NULL;
    return ref;
}
