/* test_sah_build.c - Tessera's binned SAH builder (render/sah_build.h) on
 * its own: every primitive in exactly one leaf, leaves within their sizes
 * and in id order, every child's box the exact union of its primitives'
 * boxes, the depth limit kept, the same tree whatever the number of
 * threads, and a clean NULL when a callback fails or the build is
 * cancelled. The wide BVH's walks over its trees are checked against the
 * BVH in test_meshes.c. */
#include <math.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "render/rng.h"
#include "render/sah_build.h"
#include "harness.h"

/* The test's tree: nodes and leaves from malloc, every one kept in a list
 * (under a lock: the builder's threads make them at once) to be freed. */
typedef struct tnode {
    int leaf;
    unsigned count;          /* a leaf's primitives; an inner node's children as create_node announced them */
    void *child[SAH_MAX_WIDTH];
    float lo[SAH_MAX_WIDTH][3], hi[SAH_MAX_WIDTH][3];
    uint32_t ids[8];
    struct tnode *next_alloc;
} tnode;

typedef struct {
    pthread_mutex_t lock;
    tnode *all;
    atomic_int made, fail_after; /* fail_after < 0: never fail */
    atomic_int cancel_after;     /* cancelled() says yes from this many asks on (< 0: never) */
    atomic_int asked;
    unsigned leaf_max;
    atomic_int bad_leaf; /* a leaf outside [1, leaf_max] or out of id order */
} tree;

static tnode *tnode_new(tree *t) {
    if (atomic_load(&t->fail_after) >= 0 && atomic_fetch_add(&t->made, 1) >= atomic_load(&t->fail_after)) return NULL;
    tnode *n = calloc(1, sizeof *n);
    if (!n) return NULL;
    pthread_mutex_lock(&t->lock);
    n->next_alloc = t->all, t->all = n;
    pthread_mutex_unlock(&t->lock);
    return n;
}

static void *cb_node(unsigned count, void *user) {
    tnode *n = tnode_new(user);
    if (n) n->count = count;
    return n;
}

static void cb_child(void *node, unsigned k, void *child, const float lo[3], const float hi[3], void *user) {
    tnode *n = node;
    (void)user;
    n->child[k] = child;
    memcpy(n->lo[k], lo, sizeof n->lo[k]);
    memcpy(n->hi[k], hi, sizeof n->hi[k]); /* count: children_of(), after the build (threads set different k) */
}

/* An inner node's children: those set, from the first. */
static unsigned children_of(const tnode *n) {
    unsigned k = 0;
    while (k < SAH_MAX_WIDTH && n->child[k]) k++;
    return k;
}

static void *cb_leaf(const sah_prim *p, size_t count, void *user) {
    tree *t = user;
    if (count < 1 || count > t->leaf_max) atomic_store(&t->bad_leaf, 1);
    for (size_t i = 1; i < count; i++)
        if (p[i - 1].id >= p[i].id) atomic_store(&t->bad_leaf, 1);
    tnode *n = tnode_new(t);
    if (!n) return NULL;
    n->leaf = 1;
    n->count = (unsigned)(count < 8 ? count : 8);
    for (unsigned i = 0; i < n->count; i++) n->ids[i] = p[i].id;
    return n;
}

static int cb_cancelled(void *user) {
    tree *t = user;
    int limit = atomic_load(&t->cancel_after);
    return limit >= 0 && atomic_fetch_add(&t->asked, 1) >= limit;
}

static void tree_init(tree *t, unsigned leaf_max) {
    memset(t, 0, sizeof *t);
    pthread_mutex_init(&t->lock, NULL);
    atomic_store(&t->fail_after, -1);
    atomic_store(&t->cancel_after, -1);
    t->leaf_max = leaf_max;
}

static void tree_free(tree *t) {
    for (tnode *n = t->all, *next; n; n = next) next = n->next_alloc, free(n);
    pthread_mutex_destroy(&t->lock);
}

/* What a check of a subtree found. */
typedef struct {
    const float (*box)[6]; /* the input boxes by id */
    size_t n;
    unsigned char *seen;
    size_t dup, missing, bad_box, bad_node, deepest;
    unsigned width;
} audit;

/* The union of the subtree's primitives' boxes into lo/hi; checks that
 * every child box is exactly its subtree's union. */
static void audit_tree(audit *A, const tnode *n, size_t depth, float lo[3], float hi[3]) {
    for (int a = 0; a < 3; a++) lo[a] = INFINITY, hi[a] = -INFINITY;
    if (n->leaf) {
        for (unsigned i = 0; i < n->count; i++) {
            uint32_t id = n->ids[i];
            if (id >= A->n) {
                A->bad_node++;
                continue;
            }
            if (A->seen[id]++) A->dup++;
            for (int a = 0; a < 3; a++) lo[a] = fminf(lo[a], A->box[id][a]), hi[a] = fmaxf(hi[a], A->box[id][3 + a]);
        }
        return;
    }
    if (depth + 1 > A->deepest) A->deepest = depth + 1;
    unsigned count = children_of(n);
    if (count < 2 || count > A->width || count != n->count) A->bad_node++; /* or create_node was told otherwise */
    for (unsigned k = count; k < SAH_MAX_WIDTH; k++)
        if (n->child[k]) A->bad_node++; /* a gap before it */
    for (unsigned k = 0; k < count; k++) {
        float clo[3], chi[3];
        audit_tree(A, n->child[k], depth + 1, clo, chi);
        if (memcmp(clo, n->lo[k], sizeof clo) || memcmp(chi, n->hi[k], sizeof chi)) A->bad_box++;
        for (int a = 0; a < 3; a++) lo[a] = fminf(lo[a], clo[a]), hi[a] = fmaxf(hi[a], chi[a]);
    }
}

/* The tree as text-free bytes (preorder: kind, counts, boxes, ids) for
 * comparing two builds. */
typedef struct {
    unsigned char *b;
    size_t len, cap;
} bytes;

static void put(bytes *o, const void *p, size_t n) {
    if (o->len + n > o->cap) {
        o->cap = (o->len + n) * 2;
        o->b = realloc(o->b, o->cap);
    }
    memcpy(o->b + o->len, p, n);
    o->len += n;
}

static void serialise(bytes *o, const tnode *n) {
    unsigned count = n->leaf ? n->count : children_of(n);
    put(o, &n->leaf, sizeof n->leaf);
    put(o, &count, sizeof count);
    if (n->leaf) {
        put(o, n->ids, n->count * sizeof n->ids[0]);
        return;
    }
    for (unsigned k = 0; k < count; k++) {
        put(o, n->lo[k], sizeof n->lo[k]);
        put(o, n->hi[k], sizeof n->hi[k]);
        serialise(o, n->child[k]);
    }
}

enum { UNIFORM, IDENTICAL, CLUSTERED, GEOMETRIC, SLIVERS, GRADED };

/* n boxes of a kind, from the seed. */
static float (*make_boxes(int kind, size_t n, uint64_t seed))[6] {
    float (*b)[6] = malloc(n * sizeof *b);
    rng_stream r = rng_stream_start(seed, 0, 0);
    for (size_t i = 0; i < n; i++) {
        float c[3], h[3];
        for (int a = 0; a < 3; a++) c[a] = 100.0f * rng_next(&r), h[a] = 0.5f * rng_next(&r);
        if (kind == IDENTICAL) c[0] = c[1] = c[2] = 1.0f, h[0] = h[1] = h[2] = 0.25f;
        if (kind == CLUSTERED && i % 2) c[0] = c[1] = c[2] = 50.0f; /* half the boxes centred on one point */
        if (kind == GEOMETRIC) /* centres 1.2^-i along x: the SAH peels a few off at a time */
            c[0] = powf(1.2f, -(float)(i % 400)), c[1] = c[2] = 0.0f, h[0] = h[1] = h[2] = 0.5f * c[0];
        if (kind == SLIVERS) h[1] = h[2] = 0.0f; /* flat in y and z */
        if (kind == GRADED) /* the array's later boxes spread wider and are bigger: no two parts alike */
            for (int a = 0; a < 3; a++) c[a] *= 1.0f + 3.0f * (float)i / (float)n, h[a] *= 1.0f + (float)(i % 7);
        for (int a = 0; a < 3; a++) b[i][a] = c[a] - h[a], b[i][3 + a] = c[a] + h[a];
    }
    return b;
}

static sah_prim *prims_of(const float (*b)[6], size_t n) {
    sah_prim *p = aligned_alloc(32, (n * sizeof *p + 31) / 32 * 32);
    for (size_t i = 0; i < n; i++)
        p[i] = (sah_prim){{b[i][0], b[i][1], b[i][2]}, (uint32_t)i, {b[i][3], b[i][4], b[i][5]}, 0};
    return p;
}

/* The builder's width in build_and_check (sah_args.width). */
static unsigned test_width = 8;

static sah_args args_for(tree *t, unsigned leaf_min, unsigned leaf_max, unsigned max_depth) {
    return (sah_args){.width = test_width, .leaf_min = leaf_min, .leaf_max = leaf_max, .block = leaf_max,
                      .max_depth = max_depth, .trav_cost = 1.0f, .isect_cost = 1.0f, .create_node = cb_node,
                      .set_child = cb_child, .create_leaf = cb_leaf, .cancelled = cb_cancelled, .user = t};
}

/* Build over n boxes of a kind and check the tree; returns its bytes
 * (serialise) in *out if asked (the caller frees out->b). */
static void build_and_check(const char *what, int kind, size_t n, unsigned leaf_min, unsigned leaf_max,
                            unsigned max_depth, bytes *out) {
    float (*b)[6] = make_boxes(kind, n, 7 + n);
    sah_prim *p = prims_of((const float (*)[6])b, n);
    tree t;
    tree_init(&t, leaf_max);
    sah_args a = args_for(&t, leaf_min, leaf_max, max_depth);
    tnode *root = sah_build(&a, p, n);
    CHECK(root != NULL, "%s, %zu boxes: the build failed", what, n);
    if (root) {
        audit A = {.box = (const float (*)[6])b, .n = n, .seen = calloc(n, 1), .width = test_width};
        float lo[3], hi[3];
        audit_tree(&A, root, 0, lo, hi);
        for (size_t i = 0; i < n; i++) A.missing += !A.seen[i];
        CHECK(A.dup == 0 && A.missing == 0, "%s, %zu boxes: %zu in two leaves, %zu in none", what, n, A.dup,
              A.missing);
        CHECK(A.bad_box == 0, "%s, %zu boxes: %zu child boxes are not their subtree's union", what, n, A.bad_box);
        CHECK(A.bad_node == 0, "%s, %zu boxes: %zu nodes with fewer than 2 or more than %u children, not as many as "
              "announced, or a bad id", what, n, A.bad_node, test_width);
        CHECK(A.deepest <= max_depth, "%s, %zu boxes: %zu levels of nodes, the limit is %u", what, n, A.deepest,
              max_depth);
        CHECK(!atomic_load(&t.bad_leaf), "%s, %zu boxes: a leaf outside 1..%u primitives or out of id order", what,
              n, leaf_max);
        if (out) serialise(out, root);
        free(A.seen);
    }
    tree_free(&t);
    free(p);
    free(b);
}

TEST(sah_build_trees_hold_every_primitive_once) {
    static const struct {
        const char *what;
        int kind;
    } kinds[] = {{"uniform", UNIFORM},
                 {"identical", IDENTICAL},
                 {"clustered", CLUSTERED},
                 {"geometric", GEOMETRIC},
                 {"slivers", SLIVERS},
                 {"graded", GRADED}};
    static const size_t sizes[] = {1, 2, 7, 8, 9, 17, 100, 3001, 40000};
    for (size_t k = 0; k < sizeof kinds / sizeof kinds[0]; k++)
        for (size_t i = 0; i < sizeof sizes / sizeof sizes[0]; i++) {
            build_and_check(kinds[k].what, kinds[k].kind, sizes[i], 8, 8, 40, NULL); /* the 8-lane walks' leaves */
            build_and_check(kinds[k].what, kinds[k].kind, sizes[i], 3, 4, 40, NULL); /* the SSE walk's */
            test_width = 16; /* the wide BVH's (accel_wide.c) */
            build_and_check(kinds[k].what, kinds[k].kind, sizes[i], 8, 8, 40, NULL);
            build_and_check(kinds[k].what, kinds[k].kind, sizes[i], 3, 4, 40, NULL);
            test_width = 8;
        }
    /* The depth limit reached: below it sets are cut by index. */
    build_and_check("uniform, depth 12", UNIFORM, 100000, 8, 8, 12, NULL);
    build_and_check("geometric, depth 14", GEOMETRIC, 4000, 3, 4, 14, NULL);
    test_width = 16;
    build_and_check("uniform, depth 12, 16 wide", UNIFORM, 100000, 8, 8, 12, NULL);
    test_width = 8;
}

/* The same tree, bit for bit, on 1, 2 and 3 threads (above the size where
 * a set is binned by every thread and the subtrees go to the threads), and
 * with the SSE binning instead of AVX2's (TESSERA_NO_AVX2; the same on a
 * CPU without AVX2). */
TEST(sah_build_same_tree_with_any_threads) {
    bytes ref = {0}, sse = {0};
    build_and_check("graded, 1 thread", GRADED, 300000, 8, 8, 40, &ref);
    setenv("TESSERA_NO_AVX2", "1", 1);
    build_and_check("graded, SSE binning", GRADED, 300000, 8, 8, 40, &sse);
    unsetenv("TESSERA_NO_AVX2");
    CHECK(ref.len > 0 && sse.len == ref.len && memcmp(ref.b, sse.b, ref.len) == 0,
          "the SSE binning built a different tree from the AVX2 one's (%zu against %zu bytes)", sse.len, ref.len);
    free(sse.b);
    static const char *threads[] = {"2", "3"};
    for (size_t i = 0; i < 2; i++) {
        bytes other = {0};
        setenv("TESSERA_LOAD_THREADS", threads[i], 1);
        build_and_check("graded, threads", GRADED, 300000, 8, 8, 40, &other);
        unsetenv("TESSERA_LOAD_THREADS");
        CHECK(ref.len > 0 && other.len == ref.len && memcmp(ref.b, other.b, ref.len) == 0,
              "%s threads built a different tree from 1 thread's (%zu against %zu bytes)", threads[i], other.len,
              ref.len);
        free(other.b);
    }
    free(ref.b);
}

/* A callback's NULL or a cancel ends the build with NULL, on one thread or
 * several, whatever was made so far left to the caller. */
TEST(sah_build_fails_cleanly) {
    size_t n = 300000;
    float (*b)[6] = make_boxes(UNIFORM, n, 3);
    static const char *threads[] = {"1", "2"};
    for (int th = 0; th < 2; th++) {
        setenv("TESSERA_LOAD_THREADS", threads[th], 1);
        static const int fail_after[] = {0, 1, 500, 20000};
        for (size_t f = 0; f < sizeof fail_after / sizeof fail_after[0]; f++) {
            sah_prim *p = prims_of((const float (*)[6])b, n);
            tree t;
            tree_init(&t, 8);
            atomic_store(&t.fail_after, fail_after[f]);
            sah_args a = args_for(&t, 8, 8, 40);
            CHECK(sah_build(&a, p, n) == NULL, "%s threads: the build went on after callback %d failed",
                  threads[th], fail_after[f]);
            tree_free(&t);
            free(p);
        }
        static const int cancel_after[] = {0, 3};
        for (size_t c = 0; c < 2; c++) {
            sah_prim *p = prims_of((const float (*)[6])b, n);
            tree t;
            tree_init(&t, 8);
            atomic_store(&t.cancel_after, cancel_after[c]);
            sah_args a = args_for(&t, 8, 8, 40);
            CHECK(sah_build(&a, p, n) == NULL, "%s threads: the build ignored a cancel after %d asks", threads[th],
                  cancel_after[c]);
            CHECK(atomic_load(&t.asked) > cancel_after[c], "%s threads: cancelled() was asked %d times", threads[th],
                  atomic_load(&t.asked));
            tree_free(&t);
            free(p);
        }
        unsetenv("TESSERA_LOAD_THREADS");
    }
    /* A width the builder's arrays cannot hold (or less than 2): refused
     * before any callback. */
    static const unsigned widths[] = {1, SAH_MAX_WIDTH + 1};
    for (size_t w = 0; w < 2; w++) {
        sah_prim *p = prims_of((const float (*)[6])b, 1000);
        tree t;
        tree_init(&t, 8);
        sah_args a = args_for(&t, 8, 8, 40);
        a.width = widths[w];
        void *root = sah_build(&a, p, 1000);
        CHECK(root == NULL && t.all == NULL, "width %u: the build was not refused (root %p, %s made)", widths[w], root,
              t.all ? "nodes or leaves" : "nothing");
        tree_free(&t);
        free(p);
    }
    free(b);
}
