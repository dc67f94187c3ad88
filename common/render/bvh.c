/* bvh.c - binned-SAH bounding volume hierarchy: build and traversal.
 *
 * Build: top-down, 16 centroid bins per split on the widest centroid axis,
 * cost = 1 per box test + 1 per primitive test; a node becomes a leaf when
 * splitting does not pay and it holds at most BVH_MAX_LEAF primitives.
 * Nodes are stored depth-first, so a node's first child is the next node. */
#include "bvh.h"

#include <stdlib.h>
#include <string.h>
#include "elapsed.h"

#define BVH_BINS 16
#define BVH_MAX_LEAF 8
#define BVH_STACK 64

typedef struct {
    float lo[3];
    uint32_t offset; /* leaf: first entry in prims[]; inner: index of the second child */
    float hi[3];
    uint16_t count;  /* primitives in a leaf; 0 for an inner node */
    uint16_t axis;   /* split axis of an inner node */
} bvh_node;

struct bvh {
    bvh_node *nodes;
    uint32_t *prims; /* primitive ids in leaf order */
    uint32_t prim_count;
    bvh_stats stats;
};

typedef struct {
    float lo[3], hi[3];
} box;

typedef struct {
    box *bounds;     /* per primitive */
    float (*centroid)[3];
    uint32_t *prims;
    bvh_node *nodes;
    size_t node_count;
    size_t leaf_count;
    size_t max_depth;
} builder;

static box box_empty(void) {
    box b = {{INFINITY, INFINITY, INFINITY}, {-INFINITY, -INFINITY, -INFINITY}};
    return b;
}
static void box_grow_box(box *b, const box *o) {
    for (int a = 0; a < 3; a++) {
        b->lo[a] = fminf(b->lo[a], o->lo[a]);
        b->hi[a] = fmaxf(b->hi[a], o->hi[a]);
    }
}
static void box_grow_point(box *b, const float p[3]) {
    for (int a = 0; a < 3; a++) {
        b->lo[a] = fminf(b->lo[a], p[a]);
        b->hi[a] = fmaxf(b->hi[a], p[a]);
    }
}
static float box_area(const box *b) {
    float dx = b->hi[0] - b->lo[0], dy = b->hi[1] - b->lo[1], dz = b->hi[2] - b->lo[2];
    if (dx < 0) return 0;
    return 2.0f * (dx * dy + dy * dz + dz * dx);
}

static box prim_box(const scene *s, uint32_t id) {
    box b = box_empty();
    if (id < s->triangle_count) {
        const triangle *t = &s->triangles[id];
        const vec3 *v[3] = {&t->v0, &t->v1, &t->v2};
        for (int k = 0; k < 3; k++) {
            float p[3] = {v[k]->x, v[k]->y, v[k]->z};
            box_grow_point(&b, p);
        }
    } else {
        const sphere *sp = &s->spheres[id - s->triangle_count];
        float c[3] = {sp->center.x, sp->center.y, sp->center.z};
        for (int a = 0; a < 3; a++) {
            b.lo[a] = c[a] - sp->radius;
            b.hi[a] = c[a] + sp->radius;
        }
    }
    return b;
}

static uint32_t make_leaf(builder *B, uint32_t node, uint32_t begin, uint32_t end) {
    B->nodes[node].offset = begin;
    B->nodes[node].count = (uint16_t)(end - begin);
    B->leaf_count++;
    return node;
}

/* Find the cheapest binned split of prims[begin, end) on `axis`. Returns the
 * cost (relative to the node's area) and sets *split_bin; the left side is
 * bins 0..*split_bin. */
static float best_split(builder *B, uint32_t begin, uint32_t end, int axis, float cmin, float cscale,
                        int *split_bin) {
    box bin_box[BVH_BINS];
    uint32_t bin_count[BVH_BINS] = {0};
    for (int i = 0; i < BVH_BINS; i++) bin_box[i] = box_empty();
    for (uint32_t i = begin; i < end; i++) {
        uint32_t p = B->prims[i];
        int bin = (int)((B->centroid[p][axis] - cmin) * cscale);
        bin = bin < 0 ? 0 : bin >= BVH_BINS ? BVH_BINS - 1 : bin;
        bin_count[bin]++;
        box_grow_box(&bin_box[bin], &B->bounds[p]);
    }
    float right_area[BVH_BINS];
    uint32_t right_count[BVH_BINS];
    box acc = box_empty();
    uint32_t n = 0;
    for (int i = BVH_BINS - 1; i > 0; i--) {
        box_grow_box(&acc, &bin_box[i]);
        n += bin_count[i];
        right_area[i] = box_area(&acc);
        right_count[i] = n;
    }
    float best = INFINITY;
    acc = box_empty();
    n = 0;
    for (int i = 0; i < BVH_BINS - 1; i++) {
        box_grow_box(&acc, &bin_box[i]);
        n += bin_count[i];
        if (n == 0 || right_count[i + 1] == 0) continue;
        float cost = box_area(&acc) * (float)n + right_area[i + 1] * (float)right_count[i + 1];
        if (cost < best) {
            best = cost;
            *split_bin = i;
        }
    }
    return best;
}

static uint32_t build(builder *B, uint32_t begin, uint32_t end, size_t depth) {
    uint32_t node = (uint32_t)B->node_count++;
    if (depth > B->max_depth) B->max_depth = depth;
    box bounds = box_empty(), cbox = box_empty();
    for (uint32_t i = begin; i < end; i++) {
        box_grow_box(&bounds, &B->bounds[B->prims[i]]);
        box_grow_point(&cbox, B->centroid[B->prims[i]]);
    }
    memcpy(B->nodes[node].lo, bounds.lo, sizeof bounds.lo);
    memcpy(B->nodes[node].hi, bounds.hi, sizeof bounds.hi);
    uint32_t n = end - begin;
    if (n <= 1 || depth >= BVH_STACK - 2) return make_leaf(B, node, begin, end);
    int axis = 0;
    for (int a = 1; a < 3; a++)
        if (cbox.hi[a] - cbox.lo[a] > cbox.hi[axis] - cbox.lo[axis]) axis = a;
    float extent = cbox.hi[axis] - cbox.lo[axis];
    uint32_t mid = begin + n / 2;
    if (extent > 0) {
        float cscale = (float)BVH_BINS / extent;
        int bin = 0;
        float cost = best_split(B, begin, end, axis, cbox.lo[axis], cscale, &bin);
        float leaf_cost = (float)n * box_area(&bounds);
        if (cost + box_area(&bounds) >= leaf_cost && n <= BVH_MAX_LEAF) return make_leaf(B, node, begin, end);
        uint32_t *lo = B->prims + begin, *hi = B->prims + end - 1;
        while (lo <= hi) { /* partition by bin */
            int b = (int)((B->centroid[*lo][axis] - cbox.lo[axis]) * cscale);
            if (b <= bin) {
                lo++;
            } else {
                uint32_t t = *lo;
                *lo = *hi;
                *hi-- = t;
            }
        }
        mid = (uint32_t)(lo - B->prims);
        if (mid == begin || mid == end) mid = begin + n / 2;
    } else if (n <= BVH_MAX_LEAF) {
        return make_leaf(B, node, begin, end);
    }
    B->nodes[node].axis = (uint16_t)axis;
    build(B, begin, mid, depth + 1);
    B->nodes[node].offset = build(B, mid, end, depth + 1);
    B->nodes[node].count = 0;
    return node;
}

bvh *bvh_build(const scene *s) {
    struct timespec t0 = elapsed_mark();
    uint32_t n = s->triangle_count + s->sphere_count;
    bvh *b = calloc(1, sizeof *b);
    builder B = {0};
    if (!b) return NULL;
    b->nodes = calloc(2 * (size_t)n + 1, sizeof(bvh_node));
    b->prims = calloc((size_t)n + 1, sizeof(uint32_t));
    B.bounds = calloc((size_t)n + 1, sizeof(box));
    B.centroid = calloc((size_t)n + 1, sizeof *B.centroid);
    if (!b->nodes || !b->prims || !B.bounds || !B.centroid) {
        free(B.bounds);
        free(B.centroid);
        bvh_free(b);
        return NULL;
    }
    for (uint32_t i = 0; i < n; i++) {
        b->prims[i] = i;
        B.bounds[i] = prim_box(s, i);
        for (int a = 0; a < 3; a++) B.centroid[i][a] = 0.5f * (B.bounds[i].lo[a] + B.bounds[i].hi[a]);
    }
    B.prims = b->prims;
    B.nodes = b->nodes;
    b->prim_count = n;
    if (n > 0) build(&B, 0, n, 0); /* an empty scene has no nodes; traverse() checks */
    free(B.bounds);
    free(B.centroid);
    b->stats.build_seconds = elapsed_seconds(&t0);
    b->stats.node_count = B.node_count;
    b->stats.leaf_count = B.leaf_count;
    b->stats.max_depth = B.max_depth;
    b->stats.memory_bytes = B.node_count * sizeof(bvh_node) + (size_t)n * sizeof(uint32_t);
    return b;
}

void bvh_free(bvh *b) {
    if (!b) return;
    free(b->nodes);
    free(b->prims);
    free(b);
}

void bvh_get_stats(const bvh *b, bvh_stats *out) { *out = b->stats; }

/* One axis of the slab test: the distances to the planes lo and hi into
 * *near and *far. A subnormal direction component has an infinite inverse,
 * and an origin exactly on a plane then makes 0 * inf = NaN: the axis then
 * constrains nothing (-inf, +inf), which may visit a box the ray only
 * grazes but never culls one it crosses. (Before, the NaN fell through
 * min_f / max_f and lost such a ray's hit: mesh_wide_far_origins_match_definition.) */
static inline void slab(float lo, float hi, float o, float inv, float *near, float *far) {
    float t0 = (lo - o) * inv, t1 = (hi - o) * inv;
    int undefined = t0 != t0 || t1 != t1;
    *near = undefined ? -INFINITY : min_f(t0, t1);
    *far = undefined ? INFINITY : max_f(t0, t1);
}

/* Slab test; the far distance is widened by 2 ulp-ish (pbrt's 1 + 2*gamma(3))
 * so that rounding never culls a box the ray touches. */
static inline int node_hit(const bvh_node *n, const ray_prep *r, float tmax) {
    float nx, fx, ny, fy, nz, fz;
    slab(n->lo[0], n->hi[0], r->o.x, r->inv_d.x, &nx, &fx);
    slab(n->lo[1], n->hi[1], r->o.y, r->inv_d.y, &ny, &fy);
    slab(n->lo[2], n->hi[2], r->o.z, r->inv_d.z, &nz, &fz);
    float tnear = max_f(max_f(nx, ny), max_f(nz, 0.0f));
    float tfar = min_f(min_f(fx, fy), min_f(fz, tmax));
    return tnear <= tfar * 1.0000004f;
}

/* Test primitive id against the ray (tmax: the caller's); if the hit comes
 * before *h (hit_before), update *h. The test never sees h->t, so which hit
 * wins does not depend on the order of the tests. */
static inline int prim_hit(const scene *s, const ray_prep *r, uint32_t id, float tmax, hit *h) {
    float t, b1 = 0, b2 = 0;
    int found;
    if (id == r->skip && id < s->triangle_count) return 0;
    if (id < s->triangle_count)
        found = triangle_intersect(r, &s->triangles[id], tmax, &t, &b1, &b2);
    else
        found = sphere_intersect(r, &s->spheres[id - s->triangle_count], id == r->skip, tmax, &t);
    if (!found || !hit_before(t, id, h)) return 0;
    h->t = t;
    h->prim = id;
    h->b1 = b1;
    h->b2 = b2;
    return 1;
}

/* Walk the tree; with any_hit, stop at the first hit. Boxes are culled
 * behind accel_cull_distance(best t), not behind best t: a candidate at
 * exactly that t with a smaller index must still be found (coincident
 * triangles), and its box's slab distances round differently from the
 * triangle test's t. (Until 2026-11-27 the cull was best t itself, and a
 * mesh of coincident triangles lost such ties: 5 of 30 000 rays in
 * mesh_wide_morton_build_matches_bvh.) */
static inline int traverse(const bvh *b, const scene *s, const ray *ray_in, float tmax, hit *h, int any_hit) {
    ray_prep r;
    h->t = tmax;
    h->prim = PRIM_NONE;
    if (b->prim_count == 0) return 0;
    ray_prepare(ray_in, &r);
    uint32_t stack[BVH_STACK];
    int sp = 0, found = 0;
    uint32_t i = 0;
    for (;;) {
        const bvh_node *n = &b->nodes[i];
        if (node_hit(n, &r, accel_cull_distance(h->t))) {
            if (n->count) {
                for (uint32_t k = 0; k < n->count; k++) {
                    if (prim_hit(s, &r, b->prims[n->offset + k], tmax, h)) {
                        found = 1;
                        if (any_hit) return 1;
                    }
                }
            } else {
                int far_first = vec3_comp(r.d, n->axis) < 0.0f;
                stack[sp++] = far_first ? i + 1 : n->offset;
                i = far_first ? n->offset : i + 1;
                continue;
            }
        }
        if (sp == 0) break;
        i = stack[--sp];
    }
    return found;
}

int bvh_intersect(const bvh *b, const scene *s, const ray *r, float tmax, hit *h) {
    return traverse(b, s, r, tmax, h, 0);
}

int bvh_occluded(const bvh *b, const scene *s, const ray *r, float tmax) {
    hit h;
    return traverse(b, s, r, tmax, &h, 1);
}
