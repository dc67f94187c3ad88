/* accel_wide.c - the wide BVH of accel_wide.h (nodes of up to 16
 * children): Tessera's binned SAH builder (or, from
 * ACCEL_WIDE_MORTON_MIN_PRIMITIVES, Embree's Morton-code builder, up to 8
 * children a node) makes it, Tessera walks it and decides every hit.
 *
 * Build: one padded box per primitive (accel_padded_box), handed to
 * sah_build (sah_build.h; par.h's threads) or to rtcBuildBVH (the Embree
 * device's threads); their callbacks create the nodes and leaves below in
 * the tree's own arena (bump_arena.h), which the accel_wide owns and
 * frees.
 *
 * Walk (accel_wide_walk.h, compiled for SSE, AVX2 and AVX-512VL; the
 * widest the CPU runs is chosen at build time): a node holds its children's
 * boxes as structure of arrays, so one 8-lane slab test (one AVX register,
 * or two SSE ones) covers eight, two a node of 16; the children hit are visited nearest
 * first, the others kept on a fixed-size stack with their entry distance
 * and dropped when they come up behind the culling distance. A leaf holds
 * up to 8 primitives for the AVX walks, 4 for the SSE walk: its triangles'
 * vertices as that many lanes for the flat kernel's watertight test
 * (test_loaded in accel_flat.h: per lane exactly the IEEE operations of
 * triangle_intersect), its spheres by index.
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
#include "bump_arena.h"
#include "elapsed.h"
#include "memhint.h"
#include "par.h"
#include "sah_build.h"
#include "shading_normal.h"

#include "accel_embree.h"
#include <embree3/rtcore_builder.h>

#if defined(__x86_64__) && defined(__GNUC__)
#include <immintrin.h>
#elif defined(__SSE2__)
#include <emmintrin.h>
#endif

/* Children per node at most. A node the builder gives more than
 * NODE_SMALL children has NODE_W slots (NODE16_TAG on its reference),
 * others NODE_SMALL: the binned SAH fills a node up to NODE_W children, so
 * the top of a tree is 16 wide and a walk tests fewer nodes (node tests
 * per walk at 2.6M triangles 2.83 -> 2.22), while nodes of 8 children or
 * fewer (at 164k, 2,036 of 3,464) keep 256 bytes (docs/meshes.md,
 * thirty-second session). 8 slots measured 3-8% faster than 4. The
 * walk's bytes depend on neither. */
#define NODE_W 16
#define NODE_SMALL 8


#define WIDE_MAX_DEPTH 40                       /* the builder's limit on the tree's depth */
#define WIDE_STACK ((NODE_W - 1) * WIDE_MAX_DEPTH + NODE_W) /* NODE_W - 1 siblings kept per level at most */
#define LEAF_TAG ((uintptr_t)1)                 /* low bit of a child reference: a leaf */
#define SPHERE_TAG ((uintptr_t)2)               /* next bit, of a leaf's: it holds spheres */
#define NODE16_TAG ((uintptr_t)4)               /* of an inner node's: it has NODE_W slots, not NODE_SMALL */
#define REF_TAGS (LEAF_TAG | SPHERE_TAG | NODE16_TAG)
#define SLAB_WIDEN (1.0f + 3.0f / 8388608.0f)   /* 1 + 3 * 2^-23 >= pbrt's 1 + 2 gamma(3) */

/* An inner node of W slots (NODE_SMALL or NODE_W): the boxes of its
 * children as 6 rows of W floats, row 2a the lower and row 2a + 1 the
 * upper bounds on axis a (child k's in lane k), then its W child
 * references (node pointer (| NODE16_TAG), or leaf pointer | LEAF_TAG (|
 * SPHERE_TAG)), filled from slot 0; an absent child has reference 0 and
 * the empty box (lower +inf, upper -inf), which no ray enters. 256 or 512
 * bytes. */
#define NODE_BYTES(W) (6 * sizeof(float) * (W) + sizeof(uintptr_t) * (W))

/* The slots of the node ref refers to, its rows and its references. */
static inline unsigned node_slots(uintptr_t ref) { return ref & NODE16_TAG ? NODE_W : NODE_SMALL; }
static inline float *node_row(uintptr_t ref, int row) {
    return (float *)(ref & ~REF_TAGS) + (size_t)row * node_slots(ref);
}
static inline uintptr_t *node_children(uintptr_t ref) {
    return (uintptr_t *)((char *)(ref & ~REF_TAGS) + 6 * sizeof(float) * node_slots(ref));
}

/* A leaf of up to L primitives, one per lane: a triangle's lane holds its
 * vertices (vertex k's axis a at v[k][a][lane]) and id; a sphere's lane NaN
 * vertices and the sphere's id (>= the triangle count); an empty lane NaN
 * vertices and PRIM_NONE. The reference to a leaf with spheres carries
 * SPHERE_TAG, so a leaf has no header: the 8-lane leaf is 320 bytes, 5
 * cache lines at its 64-byte alignment, all read by a leaf test. With a
 * header of counts (read first, before the vertices) it was 328 bytes in 6
 * lines: 9% more tree bytes, 1.6% more instructions in the walk (ico5). The
 * SSE walk's leaves hold 4, the 8-lane walks' 8: one leaf test each. */
#define WIDE_LEAF(L)             \
    struct {                     \
        float v[3][3][L];        \
        uint32_t id[L];          \
    }
typedef WIDE_LEAF(4) wide_leaf4;
typedef WIDE_LEAF(8) wide_leaf8;

/* The tree's memory (bump_arena.h): chunks handed out to the builder's
 * threads by an atomic bump pointer, on transparent huge pages for a
 * render of at least a quarter as many samples as primitives
 * (scene_render_is_long in scene.h), or where they are cheaper to fault
 * in (memhint_fresh_huge, chunk by chunk: a chunk's sample may find them
 * dearer than the load's buffers did). A walk's step then finds its page in the TLB:
 * render time -3% at 655k triangles (against Embree's thread-local
 * blocks of 4 KiB pages), -13% at 10.5M (docs/meshes.md). But fresh huge
 * pages are slow to get on a VM (and the kernel compacts for them): at
 * 10.5M they cost the build 0.3-0.5 s, at 2.6M 0.1-0.2 s, which a preview
 * of a few samples would not win back. Where 4 KiB faults are the dear
 * ones, a one-pixel 2.6M render took 1.02-1.12 s against 2.01-2.29 s
 * with every big buffer on huge pages (docs/meshes.md). */
#define ARENA_CHUNK_MIN ((size_t)4 << 20)
#define ARENA_CHUNK_MAX ((size_t)128 << 20)

/* The arena's hint for a long render: huge pages, asked for without a
 * probe (bump_arena_hint_fn). */
static int hint_huge(void *chunk, size_t bytes) {
    memhint_huge(chunk, bytes);
    return 1;
}

struct accel_wide {
    accel_embree_device dev;
    bump_arena *arena; /* the nodes and leaves */
    uintptr_t root; /* 0 for a scene without primitives */
    accel_wide_stats stats;
    /* The walk this CPU runs (choose_walk), and its leaves' lanes. */
    unsigned leaf_lanes;
    int (*intersect)(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h);
    int (*occluded)(const accel_wide *w, const scene *s, const ray *r, float tmax);
    int (*pair)(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h, const ray *sh, float sh_tmax,
                int *occluded);
};

static void choose_walk(accel_wide *w);

/* The walks' counters (accel_wide_get_walk_counts), compiled in only with
 * -DTESSERA_WALK_COUNT; else the hooks in accel_wide_walk.h are empty. */
#ifdef TESSERA_WALK_COUNT
static _Thread_local accel_wide_walk_counts walk_counts;
#define WALK_COUNT(field) (walk_counts.field++)
void accel_wide_get_walk_counts(accel_wide_walk_counts *out) { *out = walk_counts; }
#else
#define WALK_COUNT(field) ((void)0)
#endif

/* What the build callbacks share. */
typedef struct {
    const scene *s;
    bump_arena *arena;
    unsigned leaf_lanes; /* 4 (wide_leaf4) or 8 (wide_leaf8) */
    atomic_size_t nodes, leaves, wide_nodes; /* wide_nodes: those of NODE_W slots */
    atomic_size_t oversized; /* a leaf the builder made with more than leaf_lanes primitives (0: none) */
    atomic_int cancelled;    /* the scene's cancel callback said so (cb_progress) */
    int threads;             /* the SAH build's (build_sah) */
} build_ctx;

/* Whether the scene's cancel callback says stop (noted in b->cancelled). */
static int build_cancelled(build_ctx *b) {
    if (!scene_is_cancelled(b->s)) return 0;
    atomic_store(&b->cancelled, 1);
    return 1;
}

/* Embree's progress monitor: false stops the Morton build (rtcBuildBVH
 * then returns NULL) once the scene's cancel callback says so. Embree
 * calls it seldom: a cancel took 0.2-0.9 s to take effect in its
 * 2.6M-triangle SAH build of about 1.1 s (Tessera's own SAH build asks at
 * every set of more than 4096 primitives: 0.02-0.03 s). (Returning NULL from
 * cb_create_node is no quicker way out: Embree's builder source passes the
 * node to setNodeBounds unchecked.) */
static bool cb_progress(void *user, double done) {
    (void)done;
    return !build_cancelled(user);
}

/* A node for child_count children (NODE_W slots for more than
 * NODE_SMALL), all slots empty, as a tagged reference; NULL when out of
 * memory. */
static void *cb_create_node(RTCThreadLocalAllocator alloc, unsigned int child_count, void *user) {
    build_ctx *b = user;
    (void)alloc;
    unsigned slots = child_count > NODE_SMALL ? NODE_W : NODE_SMALL;
    char *n = bump_arena_alloc(b->arena, NODE_BYTES(slots));
    if (!n) return NULL;
    uintptr_t ref = (uintptr_t)n | (slots == NODE_W ? NODE16_TAG : 0);
    for (int a = 0; a < 3; a++)
        for (unsigned k = 0; k < slots; k++) node_row(ref, 2 * a)[k] = INFINITY, node_row(ref, 2 * a + 1)[k] = -INFINITY;
    memset(node_children(ref), 0, sizeof(uintptr_t) * slots);
    atomic_fetch_add_explicit(&b->nodes, 1, memory_order_relaxed);
    if (slots == NODE_W) atomic_fetch_add_explicit(&b->wide_nodes, 1, memory_order_relaxed);
    return (void *)ref;
}

static void cb_set_children(void *node, void **children, unsigned int count, void *user) {
    (void)user;
    uintptr_t ref = (uintptr_t)node;
    for (unsigned k = 0; k < count && k < node_slots(ref); k++) node_children(ref)[k] = (uintptr_t)children[k];
}

/* Child k's box into the rows of the node ref refers to. */
static void node_set_box(void *node, unsigned k, const float lo[3], const float hi[3]) {
    uintptr_t ref = (uintptr_t)node;
    for (int a = 0; a < 3; a++) node_row(ref, 2 * a)[k] = lo[a], node_row(ref, 2 * a + 1)[k] = hi[a];
}

static void cb_set_bounds(void *node, const struct RTCBounds **bounds, unsigned int count, void *user) {
    (void)user;
    for (unsigned k = 0; k < count && k < node_slots((uintptr_t)node); k++) {
        const struct RTCBounds *b = bounds[k];
        node_set_box(node, k, (const float[3]){b->lower_x, b->lower_y, b->lower_z},
                     (const float[3]){b->upper_x, b->upper_y, b->upper_z});
    }
}

/* Fill a leaf of `lanes` lanes (v: its 3 x 3 x lanes floats) with the
 * primitives ids[0 .. count), triangles first. Returns 1 if it holds a
 * sphere. */
static int fill_leaf(const scene *s, const uint32_t *ids, size_t count, unsigned lanes, float *v, uint32_t *id) {
    for (unsigned i = 0; i < 9 * lanes; i++) v[i] = NAN; /* lanes without a triangle: no test accepts NaN */
    for (unsigned i = 0; i < lanes; i++) id[i] = PRIM_NONE;
    unsigned n = 0;
    for (size_t i = 0; i < count && i < lanes; i++) {
        uint32_t p = ids[i];
        if (p >= s->triangle_count) continue;
        const triangle *t = &s->triangles[p];
        const vec3 *vs[3] = {&t->v0, &t->v1, &t->v2};
        for (int k = 0; k < 3; k++) {
            v[(3 * k + 0) * lanes + n] = vs[k]->x;
            v[(3 * k + 1) * lanes + n] = vs[k]->y;
            v[(3 * k + 2) * lanes + n] = vs[k]->z;
        }
        id[n++] = p;
    }
    int spheres = 0;
    for (size_t i = 0; i < count && i < lanes; i++)
        if (ids[i] >= s->triangle_count) id[n++] = ids[i], spheres = 1;
    return spheres;
}

/* A leaf of ids[0 .. count) in the arena, as a tagged reference; NULL
 * when out of memory. */
static void *make_leaf(build_ctx *b, const uint32_t *ids, size_t count) {
    void *leaf;
    int spheres = 0;
    if (count > b->leaf_lanes) /* never with maxLeafSize set; were it to happen, the build fails, no primitive is lost */
        atomic_store_explicit(&b->oversized, count, memory_order_relaxed);
    if (b->leaf_lanes == 8) {
        wide_leaf8 *l = leaf = bump_arena_alloc(b->arena, sizeof *l);
        if (l) spheres = fill_leaf(b->s, ids, count, 8, &l->v[0][0][0], l->id);
    } else {
        wide_leaf4 *l = leaf = bump_arena_alloc(b->arena, sizeof *l);
        if (l) spheres = fill_leaf(b->s, ids, count, 4, &l->v[0][0][0], l->id);
    }
    if (!leaf) return NULL;
    atomic_fetch_add_explicit(&b->leaves, 1, memory_order_relaxed);
    return (void *)((uintptr_t)leaf | LEAF_TAG | (spheres ? SPHERE_TAG : 0));
}

static void *cb_create_leaf(RTCThreadLocalAllocator alloc, const struct RTCBuildPrimitive *prims, size_t count,
                            void *user) {
    uint32_t ids[8];
    (void)alloc;
    for (size_t i = 0; i < count && i < 8; i++) ids[i] = prims[i].primID;
    return make_leaf(user, ids, count);
}

/* sah_build's callbacks (sah_build.h), into the same nodes and leaves. */
static void *sah_create_node(unsigned count, void *user) { return cb_create_node(NULL, count, user); }

static void sah_set_child(void *node, unsigned k, void *child, const float lo[3], const float hi[3], void *user) {
    (void)user;
    node_children((uintptr_t)node)[k] = (uintptr_t)child;
    node_set_box(node, k, lo, hi);
}

static void *sah_create_leaf(const sah_prim *prims, size_t count, void *user) {
    uint32_t ids[8];
    for (size_t i = 0; i < count && i < 8; i++) ids[i] = prims[i].id;
    return make_leaf(user, ids, count);
}

static int sah_cancelled(void *user) { return build_cancelled(user); }

/* Every primitive's padded box, into the SAH's records or Embree's (one of
 * the two set), made by par.h's threads: at 10.5M triangles 0.4 s on one
 * thread, most of it the first touch of 336 MB. */
typedef struct {
    const scene *s;
    sah_prim *sah;
    struct RTCBuildPrimitive *rtc;
} prim_boxes;

static void make_boxes(void *ctx, size_t begin, size_t end, int part) {
    prim_boxes *B = ctx;
    (void)part;
    for (size_t i = begin; i < end; i++) {
        float lo[3], hi[3];
        accel_padded_box(B->s, (uint32_t)i, lo, hi);
        if (B->sah) B->sah[i] = (sah_prim){{lo[0], lo[1], lo[2]}, (uint32_t)i, {hi[0], hi[1], hi[2]}, 0};
        else B->rtc[i] = (struct RTCBuildPrimitive){lo[0], lo[1], lo[2], 0, hi[0], hi[1], hi[2], (unsigned)i};
    }
}

/* Embree's build primitives for s's n primitives. Returns NULL when out
 * of memory; the caller frees. */
static struct RTCBuildPrimitive *build_primitives(const scene *s, size_t n) {
    struct RTCBuildPrimitive *p = aligned_alloc(32, (n * sizeof *p + 31) / 32 * 32);
    memhint_fresh(p, n * sizeof *p);
    if (!p) return NULL;
    prim_boxes boxes = {s, NULL, p};
    par_run(n, par_parts_touch(n, 1 << 14), make_boxes, &boxes);
    return p;
}

/* Whether n primitives are built by the Morton builder
 * (ACCEL_WIDE_MORTON_MIN_PRIMITIVES, TESSERA_WIDE_BUILDER). */
static int use_morton(size_t n) {
    const char *b = getenv("TESSERA_WIDE_BUILDER");
    if (b && strcmp(b, "morton") == 0) return 1;
    if (b && strcmp(b, "sah") == 0) return 0;
    return n >= ACCEL_WIDE_MORTON_MIN_PRIMITIVES;
}

/* The leaves' sizes for the builders: leaves of 4 from 3 primitives up
 * for the SSE walk, 6.5% fewer instructions than from 1 at 655k
 * triangles; leaves of 8 from 8 up for the 8-lane walks (from 3: 5-7% more
 * instructions per ray, from 6: 7%), which also take 40% fewer bytes than
 * leaves of 4 (docs/meshes.md). A block of 1 to leaf_lanes primitives
 * costs one leaf test. */
static unsigned leaf_min(unsigned leaf_lanes) { return leaf_lanes == 8 ? 8 : 3; }

/* Tessera's binned SAH (sah_build.h) over b's scene: the root, or NULL
 * when out of memory or cancelled (b->cancelled says which). */
static void *build_sah(build_ctx *b, size_t n, size_t *peak) {
    sah_prim *p = aligned_alloc(32, (n * sizeof *p + 31) / 32 * 32);
    memhint_fresh(p, n * sizeof *p);
    if (!p) return NULL;
    prim_boxes boxes = {b->s, p, NULL};
    par_run(n, par_parts_touch(n, 1 << 14), make_boxes, &boxes);
    sah_args args = {.width = NODE_W, .leaf_min = leaf_min(b->leaf_lanes), .leaf_max = b->leaf_lanes,
                     .block = b->leaf_lanes, .max_depth = WIDE_MAX_DEPTH, .trav_cost = 1.0f, .isect_cost = 1.0f,
                     .create_node = sah_create_node, .set_child = sah_set_child, .create_leaf = sah_create_leaf,
                     .cancelled = sah_cancelled, .user = b};
    void *root = sah_build(&args, p, n);
    free(p);
    b->threads = sah_build_threads(n);
    *peak = n * sizeof *p;
    return root;
}

/* Embree's Morton-code builder (rtcBuildBVH at RTC_BUILD_QUALITY_LOW) on
 * w's device over b's scene: the root, or NULL with w->dev.error set or b
 * cancelled, or out of memory. */
static void *build_morton(accel_wide *w, build_ctx *b, size_t n, size_t *peak) {
    struct RTCBuildPrimitive *prims = build_primitives(b->s, n);
    RTCBVH bvh = prims ? rtcNewBVH(w->dev.device) : NULL;
    if (!bvh) {
        free(prims);
        return NULL;
    }
    struct RTCBuildArguments args = rtcDefaultBuildArguments();
    args.buildQuality = RTC_BUILD_QUALITY_LOW;
    args.maxBranchingFactor = NODE_SMALL; /* Embree's limit: 8 */
    args.maxDepth = WIDE_MAX_DEPTH;
    args.sahBlockSize = b->leaf_lanes;
    args.maxLeafSize = b->leaf_lanes;
    args.minLeafSize = leaf_min(b->leaf_lanes);
    args.traversalCost = 1.0f;
    args.intersectionCost = 1.0f;
    args.bvh = bvh;
    args.primitives = prims;
    args.primitiveCount = n;
    args.primitiveArrayCapacity = n;
    args.createNode = cb_create_node;
    args.setNodeChildren = cb_set_children;
    args.setNodeBounds = cb_set_bounds;
    args.createLeaf = cb_create_leaf;
    args.userPtr = b;
    args.buildProgress = cb_progress;
    void *root = rtcBuildBVH(&args);
    /* The tree is in the arena: the RTCBVH holds only its builder's arrays
     * (256 MiB at 10.5M triangles), freed now rather than with the tree. */
    rtcReleaseBVH(bvh);
    free(prims);
    *peak = (size_t)atomic_load(&w->dev.peak) + n * sizeof *prims;
    return root;
}

accel_wide *accel_wide_build(const scene *s, char *err, size_t err_len) {
    struct timespec t0 = elapsed_mark();
    accel_wide *w = calloc(1, sizeof *w);
    if (!w) return snprintf(err, err_len, "out of memory"), NULL;
    size_t n = (size_t)s->triangle_count + s->sphere_count;
    int morton = n && use_morton(n);
    if (morton && accel_embree_device_open(&w->dev, err, err_len) != 0) {
        free(w);
        return NULL;
    }
    w->stats.config = w->dev.config;
    w->stats.node_width = morton ? NODE_SMALL : NODE_W;
    w->stats.builder = morton ? "Morton" : "binned SAH";
    choose_walk(w);
    w->stats.primitive_count = n;
    if (n == 0) return w; /* nothing to hit: root 0 */
    /* Chunks of about a tenth of the tree (a node and a leaf per 8
     * primitives), 4 to 128 MiB. */
    size_t tree = n / 8 * (NODE_BYTES(NODE_SMALL) + sizeof(wide_leaf8)), chunk = tree / 10;
    chunk = chunk < ARENA_CHUNK_MIN ? ARENA_CHUNK_MIN : chunk > ARENA_CHUNK_MAX ? ARENA_CHUNK_MAX : chunk;
    int long_render = scene_render_is_long(s, n);
    bump_arena_hint_fn hint = long_render ? hint_huge : tree >= MEMHINT_MIN_BYTES ? memhint_fresh_huge : NULL;
    if (!(w->arena = bump_arena_new(chunk, hint))) {
        snprintf(err, err_len, "out of memory");
        accel_wide_free(w);
        return NULL;
    }
    /* A short render's chunks come first from the loader's freed buffers,
     * already faulted in (s->spare: bump_arena.h), as many as the tree's
     * estimate can use, then from fresh memory; a long render's stay on
     * huge pages. */
    w->stats.spare_bytes = long_render ? 0 : bump_spare_bytes(s->spare);
    if (!long_render) bump_arena_take_spare(w->arena, s->spare, tree);
    build_ctx b = {.s = s, .arena = w->arena, .leaf_lanes = w->leaf_lanes};
    size_t peak = 0;
    w->root = (uintptr_t)(morton ? build_morton(w, &b, n, &peak) : build_sah(&b, n, &peak));
    size_t oversized = atomic_load(&b.oversized);
    if (w->root && !w->dev.error[0] && oversized) {
        snprintf(err, err_len, "building the wide BVH: the builder made a leaf of %zu primitives (at most %u)",
                 oversized, b.leaf_lanes);
        accel_wide_free(w);
        return NULL;
    }
    if (atomic_load(&b.cancelled) || !w->root || w->dev.error[0]) {
        snprintf(err, err_len, "building the wide BVH: %s",
                 atomic_load(&b.cancelled) ? "cancelled" : w->dev.error[0] ? w->dev.error : "out of memory");
        accel_wide_free(w);
        return NULL;
    }
    w->stats.build_threads = b.threads;
    w->stats.node_count = atomic_load(&b.nodes);
    w->stats.wide_node_count = atomic_load(&b.wide_nodes);
    w->stats.leaf_count = atomic_load(&b.leaves);
    w->stats.memory_bytes = bump_arena_bytes(w->arena);
    w->stats.huge_pages = bump_arena_on_huge_pages(w->arena);
    w->stats.peak_bytes = peak + w->stats.memory_bytes;
    w->stats.build_seconds = elapsed_seconds(&t0);
    return w;
}

void accel_wide_free(accel_wide *w) {
    if (!w) return;
    bump_arena_free(w->arena);
    accel_embree_device_close(&w->dev);
    free(w);
}

void accel_wide_get_stats(const accel_wide *w, accel_wide_stats *out) { *out = w->stats; }

/* For each octant of a ray's direction (bit a set: it goes down axis a),
 * the byte offsets in a node of W slots of the rows of boxes it enters by
 * on axes x, y, z, then of those it leaves by: [0] for NODE_SMALL slots,
 * [1] for NODE_W. Row 2a holds axis a's lower bounds, row 2a + 1 its upper
 * ones: a ray going up axis a enters by the lower. */
#define ROW(W, a, up) (sizeof(float) * (W) * (2 * (a) + !(up)))
#define OCTANT(W, o)                                                                                            \
    {ROW(W, 0, !((o) & 1)), ROW(W, 1, !((o) & 2)), ROW(W, 2, !((o) & 4)), ROW(W, 0, (o) & 1), ROW(W, 1, (o) & 2), \
     ROW(W, 2, (o) & 4)}
#define OCTANTS(W) \
    {OCTANT(W, 0), OCTANT(W, 1), OCTANT(W, 2), OCTANT(W, 3), OCTANT(W, 4), OCTANT(W, 5), OCTANT(W, 6), OCTANT(W, 7)}
static const size_t octant_rows[2][8][6] = {OCTANTS(NODE_SMALL), OCTANTS(NODE_W)};
#undef OCTANTS
#undef OCTANT
#undef ROW

typedef struct {
    uintptr_t ref;
    float tnear;
} stack_entry;

/* Ask for the first line of the node or leaf ref refers to (a child kept
 * for later: it is then in cache when popped). */
static inline void prefetch_ref(uintptr_t ref) { __builtin_prefetch((const void *)(ref & ~REF_TAGS)); }

/* Push the children child[k] for k in `bits` (two or more) with their entry
 * distances tn[k], the nearest last (so popped first), prefetching each;
 * returns the new top. */
static inline int push_sorted(stack_entry *stack, int sp, const uintptr_t *child, unsigned bits, const float *tn) {
    int first = sp;
    for (; bits; bits &= bits - 1) {
        int k = __builtin_ctz(bits);
        stack_entry e = {child[k], tn[k]};
        prefetch_ref(e.ref);
        int j = sp++;
        while (j > first && stack[j - 1].tnear < e.tnear) { /* farther ones below */
            stack[j] = stack[j - 1];
            j--;
        }
        stack[j] = e;
    }
    return sp;
}

/* The walks: SSE (4 lanes, any x86-64), and where NODE_W is 8, AVX2 and
 * AVX-512VL (8 lanes). */
#define WALK(name) walk4_##name
#define WALK_TARGET
#define WALK_LANES 4
#include "accel_wide_walk.h"

#if defined(__x86_64__) && defined(__GNUC__)
#define HAVE_WALK8 1
#define WALK(name) walk8_##name
#define WALK_TARGET __attribute__((target("avx2")))
#define WALK_LANES 8
#include "accel_wide_walk.h"

#define WALK(name) walk16_##name
#define WALK_TARGET __attribute__((target("avx512f,avx512vl")))
#define WALK_LANES 8
#include "accel_wide_walk.h"
#endif

/* The widest walk this CPU runs; the environment variables of the flat
 * kernel (accel.c) stop it lower: TESSERA_NO_AVX512 at AVX2,
 * TESSERA_NO_AVX2 at SSE (for tests: every walk on one machine). */
static void choose_walk(accel_wide *w) {
#define USE_WALK(name, isa, lanes) \
    (w->intersect = name##_intersect, w->occluded = name##_occluded, w->pair = name##_pair, \
     w->stats.walk_isa = isa, w->leaf_lanes = lanes)
    USE_WALK(walk4, "sse2", 4);
#ifdef HAVE_WALK8
    if (getenv("TESSERA_NO_AVX2") != NULL) return;
    if (getenv("TESSERA_NO_AVX512") == NULL && __builtin_cpu_supports("avx512f") &&
        __builtin_cpu_supports("avx512vl")) {
        USE_WALK(walk16, "avx512", 8);
        return;
    }
    if (__builtin_cpu_supports("avx2")) USE_WALK(walk8, "avx2", 8);
#endif
#undef USE_WALK
}

int accel_wide_intersect(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h) {
    return w->intersect(w, s, r, tmax, h);
}

int accel_wide_occluded(const accel_wide *w, const scene *s, const ray *r, float tmax) {
    return w->occluded(w, s, r, tmax);
}

int accel_wide_intersect_occluded(const accel_wide *w, const scene *s, const ray *r, float tmax, hit *h,
                                  const ray *sh, float sh_tmax, int *occluded) {
    return w->pair(w, s, r, tmax, h, sh, sh_tmax, occluded);
}
