/* test_meshes.c - the Embree intersector and the wide BVH against the BVH:
 * the same hit, bit for bit, on every ray (all pick the smallest (t, index),
 * accel_embree.h, accel_wide.h), with every Embree ISA this CPU has forced
 * (for Embree's walk and for the wide BVH's builder), in renders with any
 * threads and workers, and under an emulated CPU without SSE4.2's
 * successors (qemu). */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <limits.h>
#include <pthread.h>
#include <stdatomic.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

#include "render/accel.h"
#include "render/bump_arena.h"
#include "render/obj.h"
#include "render/rng.h"
#include "render/render.h"
#include "render/scene.h"
#include "harness.h"
#include "memhint.h"
#include "render/mesh_normals.h"
#include "render/scene_memory.h"
#include "util.h"

#define ICO_SCENE "tests/scenes/icospheres.json" /* 2,572 triangles and a sphere */

static vec3 unit_direction(rng_stream *r) {
    float z = 1.0f - 2.0f * rng_next(r), phi = 6.2831853f * rng_next(r), s = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    return vec3_make(s * cosf(phi), s * sinf(phi), z);
}

/* Ray i of a test set over s: leaving a triangle, aimed at a vertex or an
 * edge midpoint (the rays where two triangles nearly tie), or random with a
 * random tmax. */
static ray test_ray(const scene *s, uint64_t i, float *tmax) {
    rng_stream rng = rng_stream_start(13, i, 0);
    uint32_t t = (uint32_t)(rng_next(&rng) * (float)s->triangle_count) % s->triangle_count;
    const triangle *tr = &s->triangles[t];
    *tmax = INFINITY;
    if (i % 3 == 0) {
        float b1 = rng_next(&rng), b2 = rng_next(&rng) * (1 - b1);
        vec3 p = vec3_add(tr->v0, vec3_add(vec3_scale(vec3_sub(tr->v1, tr->v0), b1),
                                           vec3_scale(vec3_sub(tr->v2, tr->v0), b2)));
        return (ray){p, unit_direction(&rng), t};
    }
    if (i % 3 == 1) {
        vec3 target = (i / 3) % 2 ? tr->v1 : vec3_scale(vec3_add(tr->v0, tr->v2), 0.5f);
        vec3 o = vec3_scale(unit_direction(&rng), 0.9f);
        return (ray){o, vec3_normalize(vec3_sub(target, o)), PRIM_NONE};
    }
    if (i % 2) *tmax = 2.0f * rng_next(&rng);
    return (ray){vec3_scale(unit_direction(&rng), 0.9f * rng_next(&rng)), unit_direction(&rng), PRIM_NONE};
}

/* Whether the corners a hit hands shading (hit_corners: the wide walk's
 * leaf lane, else the scene's record) are the hit triangle's, and the
 * normal made from them is scene.triangle_normals', bit for bit. */
static int corners_match(const scene *s, const hit *h) {
    if (h->prim >= s->triangle_count) return h->corners == NULL;
    vec3 v[3];
    hit_corners(s, h, &v[0], &v[1], &v[2]);
    const triangle *t = &s->triangles[h->prim];
    vec3 n = triangle_geometric_normal(v[0], v[1], v[2]);
    return !memcmp(&v[0], &t->v0, sizeof(vec3)) && !memcmp(&v[1], &t->v1, sizeof(vec3)) &&
           !memcmp(&v[2], &t->v2, sizeof(vec3)) && !memcmp(&n, &s->triangle_normals[h->prim], sizeof n);
}

/* Whether a's paired query (accel_intersect_occluded) of r, with test ray j
 * as its shadow ray, gives r's hit (found, *h) and ray j's occlusion. */
static int pair_matches(const scene *s, const accel *a, const ray *r, float tmax, const hit *h, int found,
                        uint64_t j) {
    float sh_tmax;
    ray sh = test_ray(s, j, &sh_tmax);
    if (!(sh_tmax < INFINITY)) sh_tmax = 0.5f + (float)(j % 7) * 0.25f; /* a shadow ray ends before the light */
    hit hp;
    int occluded = -1, fp = accel_intersect_occluded(a, s, r, tmax, &hp, &sh, sh_tmax, &occluded);
    if (occluded != accel_occluded(a, s, &sh, sh_tmax) || fp != found) return 0;
    return !found || (hp.prim == h->prim && !memcmp(&hp.t, &h->t, 4) && !memcmp(&hp.b1, &h->b1, 4) &&
                      !memcmp(&hp.b2, &h->b2, 4) && corners_match(s, &hp));
}

/* How many of n test rays a and b answer differently (hit, prim, t, b1, b2
 * compared as bits; occlusion), whether b's paired query (closest hit
 * and a shadow ray at once) gives its separate answers, and whether both
 * hand shading the hit triangle's own corners (corners_match); *hits
 * counts b's hits, *from_leaves those whose corners came from b's tree. */
static int count_differences(const scene *s, const accel *a, const accel *b, uint64_t n, int *hits,
                             int *from_leaves) {
    int differ = 0;
    *hits = *from_leaves = 0;
    for (uint64_t i = 0; i < n; i++) {
        float tmax;
        ray r = test_ray(s, i, &tmax);
        hit ha, hb;
        int fa = accel_intersect(a, s, &r, tmax, &ha), fb = accel_intersect(b, s, &r, tmax, &hb);
        *hits += fa;
        if (fa != fb || (fa && (ha.prim != hb.prim || memcmp(&ha.t, &hb.t, 4) || memcmp(&ha.b1, &hb.b1, 4) ||
                                memcmp(&ha.b2, &hb.b2, 4)))) {
            if (differ < 3)
                fprintf(stderr, "  ray %llu: %d prim %u t %.9g | %d prim %u t %.9g\n", (unsigned long long)i, fa,
                        ha.prim, ha.t, fb, hb.prim, hb.t);
            differ++;
        } else if (accel_occluded(a, s, &r, tmax) != fa || accel_occluded(b, s, &r, tmax) != fb) {
            differ++;
        } else if (!pair_matches(s, b, &r, tmax, &hb, fb, i + n)) {
            if (differ < 3) fprintf(stderr, "  ray %llu: the paired walk answers otherwise\n", (unsigned long long)i);
            differ++;
        } else if (fb && (!corners_match(s, &hb) || !corners_match(s, &ha))) {
            if (differ < 3) fprintf(stderr, "  ray %llu: the hit's corners are not prim %u's\n", (unsigned long long)i, hb.prim);
            differ++;
        }
        if (fb && hb.corners) (*from_leaves)++;
    }
    return differ;
}

/* 150 000 test rays through the BVH and through `kind` on the scene at path:
 * the same answers, bit for bit. */
static void matches_bvh(const char *path, accel_kind kind) {
    char err[512];
    scene *s = scene_load(path, NULL, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    accel *tree = accel_build(s, ACCEL_BVH), *other = accel_build_err(s, kind, err, sizeof err);
    CHECK(tree && other && accel_get_kind(other) == kind, "build: %s", err);
    int hits = 0, from_leaves = 0;
    int differ = tree && other ? count_differences(s, tree, other, 150000, &hits, &from_leaves) : -1;
    CHECK(differ == 0, "%s: %d of 150000 rays differ between the BVH and %s", path, differ,
          kind == ACCEL_WIDE ? "the wide BVH" : "Embree");
    CHECK(hits > 50000, "%s: only %d rays hit (test rays not aimed at the scene?)", path, hits);
    /* The wide walk hands shading its leaves' corners; Embree's hits go to
     * the scene's records. */
    CHECK(kind == ACCEL_WIDE ? from_leaves > hits / 2 : from_leaves == 0, "%s: %d of %d hits with corners from %s",
          path, from_leaves, hits, kind == ACCEL_WIDE ? "the wide BVH's leaves" : "Embree");
    accel_free(tree);
    accel_free(other);
    scene_free(s);
}

TEST(mesh_embree_matches_bvh_icospheres) { matches_bvh(ICO_SCENE, ACCEL_EMBREE); }
TEST(mesh_embree_matches_bvh_features) { matches_bvh("scenes/features.json", ACCEL_EMBREE); }
TEST(mesh_wide_matches_bvh_icospheres) { matches_bvh(ICO_SCENE, ACCEL_WIDE); }
TEST(mesh_wide_matches_bvh_features) { matches_bvh("scenes/features.json", ACCEL_WIDE); }

/* The wide BVH of s walked by walk e: 0 the widest this CPU runs, 1 at
 * most AVX2 (TESSERA_NO_AVX512), 2 SSE (TESSERA_NO_AVX2); its stats into
 * *st. Returns NULL, with a failed check naming err, if the build fails;
 * the caller frees the accel. */
static accel *build_wide_walk(const scene *s, int e, accel_wide_stats *st, char *err, size_t err_len) {
    if (e >= 1) setenv("TESSERA_NO_AVX512", "1", 1);
    if (e == 2) setenv("TESSERA_NO_AVX2", "1", 1);
    accel *wide = accel_build_err(s, ACCEL_WIDE, err, err_len);
    unsetenv("TESSERA_NO_AVX512");
    unsetenv("TESSERA_NO_AVX2");
    CHECK(wide && accel_get_wide_stats(wide, st) == 0, "build: %s", err);
    return wide;
}

/* Every walk of the wide BVH this CPU runs (accel_wide.c picks the widest;
 * TESSERA_NO_AVX512 stops it at AVX2, TESSERA_NO_AVX2 at SSE): each gives
 * the BVH's answers, bit for bit, on the icospheres (with a sphere) and on
 * features.json, 60 000 rays each. */
TEST(mesh_wide_walk_isas_match_bvh) {
    static const char *const scenes[] = {ICO_SCENE, "scenes/features.json"};
    const char *seen[3] = {NULL, NULL, NULL};
    int node_width = 0;
    for (size_t p = 0; p < 2; p++) {
        char err[512];
        scene *s = scene_load(scenes[p], NULL, err, sizeof err);
        CHECK(s != NULL, "%s", err);
        if (!s) continue;
        accel *tree = accel_build(s, ACCEL_BVH);
        for (int e = 0; e < 3; e++) {
            accel_wide_stats st = {0};
            accel *wide = build_wide_walk(s, e, &st, err, sizeof err);
            if (!wide) continue;
            seen[e] = st.walk_isa, node_width = st.node_width;
            int hits = 0, leaves = 0, differ = tree ? count_differences(s, tree, wide, 60000, &hits, &leaves) : -1;
            CHECK(differ == 0 && hits > 20000 && leaves > hits / 2,
                  "%s, %s walk: %d of 60000 rays differ from the BVH, %d hit, %d with the leaf's corners", scenes[p],
                  st.walk_isa, differ, hits, leaves);
            accel_free(wide);
        }
        accel_free(tree);
        scene_free(s);
    }
    /* The walks the environment asked for, where the CPU has them. */
    CHECK(seen[2] && strcmp(seen[2], "sse2") == 0, "TESSERA_NO_AVX2: walk %s", seen[2] ? seen[2] : "?");
#if defined(__x86_64__) && defined(__GNUC__)
    CHECK(node_width == 16, "the SAH-built wide BVH's nodes hold up to %d children, not 16", node_width);
    const char *want1 = __builtin_cpu_supports("avx2") ? "avx2" : "sse2";
    const char *want0 = __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512vl") ? "avx512" : want1;
    CHECK(seen[1] && strcmp(seen[1], want1) == 0, "TESSERA_NO_AVX512: walk %s, not %s", seen[1] ? seen[1] : "?", want1);
    CHECK(seen[0] && strcmp(seen[0], want0) == 0, "default: walk %s, not %s", seen[0] ? seen[0] : "?", want0);
#endif
}

/* A vertex's shadow ray traced alongside the next ray (the default) or at
 * once (integrator_options.no_pair): the same image bytes, on the
 * icospheres (the wide BVH's paired walk) and on features.json (cut-outs,
 * whose shadow rays are never paired, and the flat kernel). */
TEST(mesh_paired_shadow_rays_same_bytes) {
    static const char *const scenes[] = {ICO_SCENE, "scenes/features.json"};
    for (size_t p = 0; p < 2; p++) {
        char err[512];
        scene_overrides ov = {.width = 48, .height = 48, .spp = 8, .max_depth = -1};
        scene *s = scene_load(scenes[p], &ov, err, sizeof err);
        CHECK(s != NULL, "%s", err);
        if (!s) continue;
        size_t n = 3 * (size_t)s->settings.width * (size_t)s->settings.height;
        float *rgb[2] = {malloc(n * sizeof(float)), malloc(n * sizeof(float))};
        trace_stats st[2] = {{0}, {0}};
        for (int k = 0; k < 2; k++) {
            render_options ro = {.threads = 2, .tile_size = 16, .passes = 1, .integrator = {.no_pair = k}};
            CHECK(rgb[k] && render_frame(s, &ro, rgb[k], &st[k]) == 0, "%s: render failed", scenes[p]);
        }
        CHECK(rgb[0] && rgb[1] && memcmp(rgb[0], rgb[1], n * sizeof(float)) == 0,
              "%s: paired and unpaired shadow rays give different pictures", scenes[p]);
        CHECK(st[0].shadow_rays == st[1].shadow_rays && st[0].shadow_rays > 1000 && st[0].rays == st[1].rays,
              "%s: %llu and %llu shadow rays", scenes[p], (unsigned long long)st[0].shadow_rays,
              (unsigned long long)st[1].shadow_rays);
        free(rgb[0]);
        free(rgb[1]);
        scene_free(s);
    }
}

/* The largest extent of s's triangles' bounding box. */
static float s_extent(const scene *s) {
    float lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t i = 0; i < s->triangle_count; i++) {
        const vec3 *v[3] = {&s->triangles[i].v0, &s->triangles[i].v1, &s->triangles[i].v2};
        for (int k = 0; k < 3; k++)
            for (int a = 0; a < 3; a++) {
                float x = vec3_comp(*v[k], a);
                lo[a] = fminf(lo[a], x), hi[a] = fmaxf(hi[a], x);
            }
    }
    return fmaxf(hi[0] - lo[0], fmaxf(hi[1] - lo[1], hi[2] - lo[2]));
}

/* Ray i of a set whose origins are far from the world's origin: aimed at a
 * point of a triangle from 10 to 10^6 times `size` (the scene's) away, along a
 * random direction or along an axis with the other components tiny (down
 * to 1e-38, subnormal after the scaling) or zero: distances up to 10^6
 * times the boxes' size, where only SLAB_WIDEN's relative margin covers the
 * slab test's rounding, and inverse directions up to +-inf. */
static ray far_ray(const scene *s, float size, uint64_t i, float *tmax) {
    rng_stream rng = rng_stream_start(29, i, 0);
    uint32_t t = (uint32_t)(rng_next(&rng) * (float)s->triangle_count) % s->triangle_count;
    const triangle *tr = &s->triangles[t];
    float b1 = rng_next(&rng), b2 = rng_next(&rng) * (1 - b1);
    vec3 p = vec3_add(tr->v0, vec3_add(vec3_scale(vec3_sub(tr->v1, tr->v0), b1),
                                       vec3_scale(vec3_sub(tr->v2, tr->v0), b2)));
    vec3 d = unit_direction(&rng);
    static const float tiny[] = {1e-4f, 1e-7f, 1e-20f, 1e-30f, 1e-38f, 0.0f};
    if (i % 3 != 0) { /* along axis a, the other components tiny */
        int a = (int)(i / 3 % 3);
        float e = tiny[i / 9 % 6], sign = rng_next(&rng) < 0.5f ? -1.0f : 1.0f;
        float c[3] = {e * d.x, e * d.y, e * d.z};
        c[a] = sign;
        d = vec3_make(c[0], c[1], c[2]);
    }
    float far = 10.0f * powf(10.0f, (float)(i / 54 % 6)) * size;
    *tmax = i % 2 ? INFINITY : 2.0f * far;
    return (ray){vec3_sub(p, vec3_scale(d, far)), d, PRIM_NONE};
}

/* The answer by its definition (accel_wide.h): every primitive tested, the
 * smallest (t, index) kept. Returns 1 and fills *h for a hit. */
static int brute_intersect(const scene *s, const ray *r, float tmax, hit *h) {
    ray_prep rp;
    ray_prepare(r, &rp);
    *h = (hit){tmax, PRIM_NONE, 0.0f, 0.0f, NULL, 0};
    for (uint32_t i = 0; i < s->triangle_count; i++) {
        float t, b1, b2;
        if (i != rp.skip && triangle_intersect(&rp, &s->triangles[i], tmax, &t, &b1, &b2) && hit_before(t, i, h))
            *h = (hit){t, i, b1, b2, NULL, 0};
    }
    for (uint32_t i = 0; i < s->sphere_count; i++) {
        uint32_t id = scene_sphere_base(s) + i;
        float t;
        if (sphere_intersect(&rp, &s->spheres[i], id == rp.skip, tmax, &t) && hit_before(t, id, h))
            *h = (hit){t, id, 0.0f, 0.0f, NULL, 0};
    }
    return h->prim != PRIM_NONE;
}

/* Rays from far away (far_ray) through every walk of the wide BVH this CPU
 * runs and through the BVH: the answers by the definition
 * (brute_intersect), bit for bit. Some rays have a subnormal direction
 * component and an origin in a box's plane (0 * inf = NaN in a slab test):
 * the BVH lost 1 of these 24 000 hits until bvh.c's slab() handled it (and
 * 2 of 60 000, e.g. o.x = -0.54296875 on a vertex's x, d.x = 4e-40). */
TEST(mesh_wide_far_origins_match_definition) {
    char err[512];
    scene *s = scene_load(ICO_SCENE, NULL, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    enum { RAYS = 24000 };
    hit *want = malloc(RAYS * sizeof *want);
    CHECK(want != NULL, "out of memory");
    if (!want) {
        scene_free(s);
        return;
    }
    int hits = 0;
    float size = s_extent(s);
    for (uint64_t i = 0; i < RAYS; i++) {
        float tmax;
        ray r = far_ray(s, size, i, &tmax);
        hits += brute_intersect(s, &r, tmax, &want[i]);
    }
    CHECK(hits > RAYS / 4, "only %d of %d far rays hit (not aimed at the scene?)", hits, (int)RAYS);
    for (int e = 0; e < 4; e++) { /* the three walks, then the BVH */
        accel_wide_stats st = {.walk_isa = "bvh"};
        accel *wide = e < 3 ? build_wide_walk(s, e, &st, err, sizeof err) : accel_build(s, ACCEL_BVH);
        if (!wide) continue;
        int differ = 0;
        for (uint64_t i = 0; i < RAYS; i++) {
            float tmax;
            ray r = far_ray(s, size, i, &tmax);
            hit h;
            int f = accel_intersect(wide, s, &r, tmax, &h), fw = want[i].prim != PRIM_NONE;
            if (f != fw || (f && (h.prim != want[i].prim || memcmp(&h.t, &want[i].t, 4) ||
                                  memcmp(&h.b1, &want[i].b1, 4) || memcmp(&h.b2, &want[i].b2, 4)))) {
                if (differ < 3)
                    fprintf(stderr, "  %s ray %llu: prim %u t %.9g, not prim %u t %.9g\n", st.walk_isa,
                            (unsigned long long)i, h.prim, h.t, want[i].prim, want[i].t);
                differ++;
            } else if (accel_occluded(wide, s, &r, tmax) != fw) {
                differ++;
            }
        }
        CHECK(differ == 0, "%s walk: %d of %d far rays differ from the definition", st.walk_isa, differ, (int)RAYS);
        accel_free(wide);
    }
    free(want);
    scene_free(s);
}

/* Trees too small to have an inner node, or with spheres sharing a leaf
 * with triangles: a quad (2 triangles) and a sphere, then 3 quads and 2
 * spheres crossing each other, through the wide BVH and the BVH. */
TEST(mesh_wide_small_trees_match_bvh) {
    static const char *const shapes[] = {
        "{\"type\": \"quad\", \"vertices\": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], \"material\": \"m\"},"
        "{\"type\": \"sphere\", \"center\": [0, 0, 0.5], \"radius\": 0.7, \"material\": \"m\"}",
        "{\"type\": \"quad\", \"vertices\": [[-1, -1, 0], [1, -1, 0], [1, 1, 0], [-1, 1, 0]], \"material\": \"m\"},"
        "{\"type\": \"quad\", \"vertices\": [[-1, 0, -1], [1, 0, -1], [1, 0, 1], [-1, 0, 1]], \"material\": \"m\"},"
        "{\"type\": \"quad\", \"vertices\": [[0, -1, -1], [0, 1, -1], [0, 1, 1], [0, -1, 1]], \"material\": \"m\"},"
        "{\"type\": \"sphere\", \"center\": [0.3, 0, 0], \"radius\": 0.5, \"material\": \"m\"},"
        "{\"type\": \"sphere\", \"center\": [-0.3, 0.2, 0], \"radius\": 0.4, \"material\": \"m\"}"};
    for (size_t k = 0; k < sizeof shapes / sizeof shapes[0]; k++) {
        char json[4096], err[512];
        snprintf(json, sizeof json,
                 "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov\": 40},"
                 " \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, \"shapes\": [%s]}",
                 shapes[k]);
        scene *s = util_scene_from_text(json, err, sizeof err);
        CHECK(s != NULL, "%s", err);
        if (!s) continue;
        accel *tree = accel_build(s, ACCEL_BVH), *wide = accel_build_err(s, ACCEL_WIDE, err, sizeof err);
        accel_wide_stats st = {0};
        CHECK(tree && wide && accel_get_wide_stats(wide, &st) == 0 && st.primitive_count == s->triangle_count + s->sphere_count,
              "build: %s", err);
        int hits = 0, leaves = 0, differ = tree && wide ? count_differences(s, tree, wide, 30000, &hits, &leaves) : -1;
        CHECK(differ == 0 && hits > 5000, "scene %zu (%zu nodes, %zu leaves): %d of 30000 rays differ, %d hit", k,
              st.node_count, st.leaf_count, differ, hits);
        accel_free(tree);
        accel_free(wide);
        scene_free(s);
    }
}

/* The wide BVH built by Morton codes (what "auto" builds from
 * ACCEL_WIDE_MORTON_MIN_PRIMITIVES; TESSERA_WIDE_BUILDER=morton forces it
 * here): the BVH's answers on the icospheres, on features.json and on a
 * mesh of 1200 coincident triangles (one Morton code for all: the builder
 * must split them anyway, within the walk's depth), then the SAH again. */
TEST(mesh_wide_morton_build_matches_bvh) {
    char obj[200000];
    size_t len = (size_t)snprintf(obj, sizeof obj, "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0.5 0.5 1\n");
    for (int i = 0; i < 1200 && len + 32 < sizeof obj; i++)
        len += (size_t)snprintf(obj + len, sizeof obj - len, i % 2 ? "f 1 2 3\n" : "f 1 2 4\n");
    const char *obj_path = util_write_temp("coincident.obj", obj);
    char json[1024];
    snprintf(json, sizeof json,
             "{\"camera\": {\"type\": \"perspective\", \"position\": [0.3, 0.3, -3], \"look_at\": [0.3, 0.3, 0], "
             "\"fov\": 40}, \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, "
             "\"shapes\": [{\"type\": \"mesh\", \"file\": \"%s\", \"material\": \"m\"}]}",
             obj_path ? obj_path : "");
    const char *json_path = util_write_temp("coincident.json", json);
    const char *scenes[] = {ICO_SCENE, "scenes/features.json", json_path};
    for (size_t p = 0; p < 3; p++) {
        char err[512];
        scene *s = scenes[p] ? scene_load(scenes[p], NULL, err, sizeof err) : NULL;
        CHECK(s != NULL, "%s: %s", scenes[p] ? scenes[p] : "temp scene", scenes[p] ? err : "not written");
        if (!s) continue;
        accel *tree = accel_build(s, ACCEL_BVH);
        for (int b = 0; b < 2; b++) {
            setenv("TESSERA_WIDE_BUILDER", b ? "sah" : "morton", 1);
            accel *wide = accel_build_err(s, ACCEL_WIDE, err, sizeof err);
            unsetenv("TESSERA_WIDE_BUILDER");
            accel_wide_stats st = {0};
            CHECK(wide && accel_get_wide_stats(wide, &st) == 0, "%s: build: %s", scenes[p], err);
            if (!wide) continue;
            CHECK(strcmp(st.builder, b ? "binned SAH" : "Morton") == 0, "%s: built by %s", scenes[p], st.builder);
            int hits = 0, leaves = 0, differ = tree ? count_differences(s, tree, wide, 30000, &hits, &leaves) : -1;
            CHECK(differ == 0 && hits > 3000 && leaves > hits / 2,
                  "%s, %s build (%zu nodes, %zu leaves): %d of 30000 rays differ, %d hit, %d with the leaf's corners",
                  scenes[p], st.builder, st.node_count, st.leaf_count, differ, hits, leaves);
            accel_free(wide);
        }
        accel_free(tree);
        scene_free(s);
    }
}

/* The wide tree asks for huge pages for a render of at least n / 4
 * samples, whichever builder makes it (accel_wide.c, tree_on_huge_pages):
 * a one-pixel preview of a large mesh is not worth their first touch. */
TEST(mesh_wide_tree_huge_pages_follow_the_samples) {
    char err[512];
    scene *s = scene_load(ICO_SCENE, NULL, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    size_t n = (size_t)s->triangle_count + s->sphere_count;
    static const struct {
        const char *builder;
        int width, height, spp, huge;
    } cases[] = {{"morton", 1, 1, 1, 0}, {"sah", 1, 1, 1, 0}, {"morton", 64, 64, 64, 1}, {"sah", 64, 64, 64, 1}};
    CHECK(n >= 8 && 64u * 64u * 64u >= n / 4, "%zu primitives: the cases need at least 8 and at most 2^20", n);
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        s->settings.width = cases[k].width, s->settings.height = cases[k].height, s->settings.spp = cases[k].spp;
        setenv("TESSERA_WIDE_BUILDER", cases[k].builder, 1);
        accel *wide = accel_build_err(s, ACCEL_WIDE, err, sizeof err);
        unsetenv("TESSERA_WIDE_BUILDER");
        accel_wide_stats st = {0};
        CHECK(wide && accel_get_wide_stats(wide, &st) == 0, "%s build: %s", cases[k].builder, err);
        CHECK(st.huge_pages == cases[k].huge, "%s build of %zu primitives for %dx%dx%d: huge_pages %d, want %d",
              cases[k].builder, n, cases[k].width, cases[k].height, cases[k].spp, st.huge_pages, cases[k].huge);
        accel_free(wide);
    }
    scene_free(s);
}

/* The triangle records follow the same rule as the tree (scene.h,
 * scene_render_is_long): huge pages for a render of at least n / 4
 * samples, ordinary ones for a preview, whose load would only pay their
 * first touch. */
TEST(mesh_triangle_records_huge_pages_follow_the_samples) {
    static const struct {
        int width, height, spp, huge;
    } cases[] = {{1, 1, 1, 0}, {64, 64, 64, 1}, {16, 16, 1, 0}, {32, 32, 1, 1}};
    for (size_t k = 0; k < sizeof cases / sizeof cases[0]; k++) {
        char err[512];
        scene_overrides ov = {.width = cases[k].width, .height = cases[k].height, .spp = cases[k].spp, .max_depth = -1};
        scene *s = scene_load(ICO_SCENE, &ov, err, sizeof err);
        CHECK(s != NULL, "%s", err);
        if (!s) return;
        size_t n = (size_t)s->triangle_count + s->sphere_count;
        CHECK(n / 4 > 16 * 16 && n / 4 <= 32 * 32, "%zu primitives: the cases want n / 4 in (256, 1024]", n);
        CHECK(s->triangles_on_huge_pages == cases[k].huge, "%dx%dx%d over %zu primitives: on huge pages %d, want %d",
              cases[k].width, cases[k].height, cases[k].spp, n, s->triangles_on_huge_pages, cases[k].huge);
        scene_free(s);
    }
}

/* The page probe (memhint.c): its answer is its rule applied to its own
 * figures, and TESSERA_HUGE_PAGES overrides it both ways; a buffer under
 * MEMHINT_MIN_BYTES never asks. */
TEST(memhint_probe_follows_its_figures_and_the_environment_overrides) {
    setenv("TESSERA_HUGE_PAGES", "1", 1);
    CHECK(memhint_huge_is_cheap() == 1, "TESSERA_HUGE_PAGES=1: not cheap");
    CHECK(memhint_fresh_wants_huge(MEMHINT_MIN_BYTES) == 1, "forced: a buffer of MEMHINT_MIN_BYTES does not ask");
    CHECK(memhint_fresh_wants_huge(MEMHINT_MIN_BYTES - 1) == 0, "a buffer under MEMHINT_MIN_BYTES asks");
    setenv("TESSERA_HUGE_PAGES", "0", 1);
    CHECK(memhint_huge_is_cheap() == 0 && memhint_fresh_wants_huge((size_t)1 << 30) == 0,
          "TESSERA_HUGE_PAGES=0: huge pages still asked for");
    unsetenv("TESSERA_HUGE_PAGES");
    int cheap = memhint_huge_is_cheap();
    double small, huge;
    memhint_probe_ms(&small, &huge);
    CHECK(small >= 0.0 && huge >= 0.0 && isfinite(small) && isfinite(huge), "probe figures %g and %g ms", small,
          huge);
    double latest = memhint_sampled_ms(); /* a big scene loaded before may have sampled a buffer */
    CHECK(cheap == memhint_rule_cheap(small, latest >= 0.0 ? latest : huge),
          "probe: %g ms on 4 KiB pages, %g on huge ones, %g in the latest buffer, answered %d", small, huge, latest,
          cheap);
    CHECK(cheap == (small >= 0.0 && (latest >= 0.0 ? latest : huge) < 0.75 * small), "the rule is not 3/4");
    CHECK(memhint_huge_is_cheap() == cheap, "a second call answered differently");
}

/* A fresh 2 MiB-aligned mapping of `bytes` (munmap(*map, bytes + 2 MiB)
 * frees it), or NULL. */
static char *fresh_aligned(size_t bytes, void **map) {
    *map = mmap(NULL, bytes + (2u << 20), PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (*map == MAP_FAILED) return NULL;
    return (char *)(((uintptr_t)*map + (2u << 20) - 1) & ~(uintptr_t)((2u << 20) - 1));
}

/* Resident 4 KiB pages among the first `pages` of p. */
static size_t resident_pages(char *p, size_t pages) {
    static unsigned char v[4096];
    if (pages > sizeof v || mincore(p, pages * 4096, v) != 0) return (size_t)-1;
    size_t n = 0;
    for (size_t i = 0; i < pages; i++) n += v[i] & 1;
    return n;
}

/* The page rule on figures (memhint.c), and the samples that give huge
 * pages their latest figure: a big fresh buffer's front faulted in (its
 * contents zero), its time the new figure, which decides for the buffer;
 * no sample of a buffer already touched, of a smaller one, or where huge
 * pages are not the cheaper ones already; TESSERA_HUGE_PAGES still
 * decides. */
TEST(memhint_samples_big_buffers_and_follows_the_latest_figure) {
    CHECK(memhint_rule_cheap(2, 0.5) && !memhint_rule_cheap(2, 1.5) && !memhint_rule_cheap(-1, 0.5) &&
              !memhint_rule_cheap(2, -1),
          "cheap: under 3/4 of the 4 KiB pages' figure, both known");
    unsetenv("TESSERA_HUGE_PAGES");
    (void)memhint_huge_is_cheap(); /* the probe, once: its figures restored below */
    double small0, huge0, sampled0 = memhint_sampled_ms();
    memhint_probe_ms(&small0, &huge0);

    memhint_set_figures(2, 0.5, -1);
    CHECK(memhint_huge_is_cheap(), "the probe's 0.5 ms against 2: not cheap");
    memhint_set_figures(2, 0.5, 11);
    CHECK(!memhint_huge_is_cheap(), "a latest figure of 11 ms against 2, the probe's 0.5: cheap");
    memhint_set_figures(2, 11, 0.5);
    CHECK(memhint_huge_is_cheap(), "a latest figure of 0.5 ms against 2, the probe's 11: not cheap");

    size_t big = MEMHINT_SAMPLE_MIN_BYTES;
    void *map;
    char *p = fresh_aligned(big, &map);
    CHECK(p != NULL, "cannot map");
    if (!p) return;
    memhint_set_figures(2, 11, -1); /* not cheap: no sample, 4 KiB pages */
    CHECK(memhint_fresh_huge(p, big) == 0 && memhint_sampled_ms() == -1 && resident_pages(p, 1024) == 0,
          "huge pages dearer: a sample was taken or huge pages asked for");
    memhint_set_figures(2, 0.5, -1); /* cheap: a sample */
    int got = memhint_fresh_huge(p, big);
    double s1 = memhint_sampled_ms();
    CHECK(s1 >= 0.0 && isfinite(s1) && got == memhint_rule_cheap(2, s1),
          "a fresh %zu MiB buffer: sample %g ms, on huge pages %d", big >> 20, s1, got);
    CHECK(resident_pages(p, 1024) == 1024, "the sampled front: %zu of 1024 pages resident", resident_pages(p, 1024));
    size_t nonzero = 0;
    for (size_t i = 0; i < MEMHINT_PROBE_BYTES; i++) nonzero += p[i] != 0;
    CHECK(nonzero == 0, "the sample wrote %zu bytes", nonzero);
    memhint_set_figures(2, 0.5, -1);
    CHECK(memhint_fresh_huge(p, big) == 1 && memhint_sampled_ms() == -1, "a touched front was sampled again");
    munmap(map, big + (2u << 20));
    p = fresh_aligned(big, &map);
    CHECK(p != NULL, "cannot map");
    if (!p) return;
    memhint_set_figures(2, 0.5, -1);
    CHECK(memhint_fresh_huge(p, big - 1 - (2u << 20)) == 1 && memhint_sampled_ms() == -1,
          "a buffer under MEMHINT_SAMPLE_MIN_BYTES was sampled");
    setenv("TESSERA_HUGE_PAGES", "1", 1);
    CHECK(memhint_fresh_huge(p, big) == 1 && memhint_sampled_ms() == -1 && resident_pages(p, 1024) == 0,
          "TESSERA_HUGE_PAGES=1: sampled, or not on huge pages");
    setenv("TESSERA_HUGE_PAGES", "0", 1);
    CHECK(memhint_fresh_huge(p, big) == 0, "TESSERA_HUGE_PAGES=0: on huge pages");
    unsetenv("TESSERA_HUGE_PAGES");
    munmap(map, big + (2u << 20));
    memhint_set_figures(small0, huge0, sampled0);
}

/* A grid of 2 * side^2 triangles in the plane y = 0 over [0, 500]^2 as
 * OBJ text (malloc'd, the caller frees). */
static char *grid_obj(int side) {
    size_t cap = (size_t)(side + 1) * (side + 1) * 40 + (size_t)side * side * 2 * 40, len = 0;
    char *t = malloc(cap);
    if (!t) return NULL;
    for (int z = 0; z <= side; z++)
        for (int x = 0; x <= side; x++)
            len += (size_t)snprintf(t + len, cap - len, "v %.4f 0 %.4f\n", 500.0 * x / side, 500.0 * z / side);
    for (int z = 0; z < side; z++)
        for (int x = 0; x < side; x++) {
            int a = z * (side + 1) + x + 1, b = a + 1, c = a + side + 1, d = c + 1;
            len += (size_t)snprintf(t + len, cap - len, "f %d %d %d\nf %d %d %d\n", a, c, b, b, c, d);
        }
    return t;
}

/* A one-pixel render of a mesh whose records pass MEMHINT_MIN_BYTES: its
 * records and tree on huge pages when they are the cheaper ones to fault
 * in (forced), on ordinary pages when not (forced), and the picture the
 * same either way. */
TEST(mesh_big_buffers_take_huge_pages_where_they_are_cheaper) {
    char err[512];
    char *obj = grid_obj(256);
    CHECK(obj != NULL, "out of memory");
    if (!obj) return;
    const char *obj_path = util_write_temp("pages-grid.obj", obj);
    free(obj);
    CHECK(obj_path != NULL, "cannot write grid.obj");
    if (!obj_path) return;
    char json[1024];
    snprintf(json, sizeof json,
             "{\"render\": {\"width\": 8, \"height\": 8, \"spp\": 2, \"max_depth\": 4, \"seed\": 1},"
             " \"camera\": {\"type\": \"perspective\", \"position\": [250, 400, -300], \"look_at\": [250, 0, 250],"
             " \"up\": [0, 1, 0], \"fov\": 50},"
             " \"materials\": {\"white\": {\"type\": \"diffuse\", \"albedo\": [0.7, 0.7, 0.7]}},"
             " \"shapes\": [{\"type\": \"mesh\", \"file\": \"%s\", \"material\": \"white\"},"
             " {\"type\": \"sphere\", \"center\": [250, 300, 250], \"radius\": 50, \"emission\": [5, 5, 5]}]}",
             obj_path);
    const char *scene_path = util_write_temp("pages-grid.json", json);
    float *img[2] = {NULL, NULL};
    for (int cheap = 0; cheap < 2; cheap++) {
        setenv("TESSERA_HUGE_PAGES", cheap ? "1" : "0", 1);
        scene_overrides ov = {.width = 1, .height = 1, .spp = 1, .max_depth = -1};
        scene *s = scene_load(scene_path, &ov, err, sizeof err);
        CHECK(s != NULL, "%s", err);
        if (!s) break;
        CHECK((size_t)s->triangle_count * sizeof(triangle) >= MEMHINT_MIN_BYTES, "%u triangles: too few",
              s->triangle_count);
        CHECK(s->triangles_on_huge_pages == cheap, "huge pages cheaper %d: records on huge pages %d", cheap,
              s->triangles_on_huge_pages);
        accel *wide = accel_build_err(s, ACCEL_WIDE, err, sizeof err);
        accel_wide_stats st = {0};
        CHECK(wide && accel_get_wide_stats(wide, &st) == 0, "wide build: %s", err);
        CHECK(st.huge_pages == cheap, "huge pages cheaper %d: tree on huge pages %d", cheap, st.huge_pages);
        accel_free(wide);
        trace_stats ts = {0};
        img[cheap] = util_render(s, 1, 8, 1, &ts);
        scene_free(s);
    }
    unsetenv("TESSERA_HUGE_PAGES");
    CHECK(img[0] && img[1] && memcmp(img[0], img[1], 3 * sizeof(float)) == 0, "the pixel differs with the pages");
    free(img[0]);
    free(img[1]);
}

/* Every Embree kernel this CPU can run, forced, and every build quality:
 * the same answers as the BVH (the tests at the leaves are Tessera's;
 * Embree's arithmetic and tree only order them). */
TEST(mesh_embree_every_isa_agrees) {
    static const struct {
        const char *isa, *cpu;
    } isas[] = {{"sse2", "sse2"}, {"sse4.2", "sse4.2"}, {"avx", "avx"}, {"avx2", "avx2"}, {"avx512", "avx512f"}};
    char err[512], cfg[64];
    scene *s = scene_load(ICO_SCENE, NULL, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    accel *tree = accel_build(s, ACCEL_BVH);
    int tried = 0;
    for (size_t k = 0; k < sizeof isas / sizeof isas[0]; k++) {
        __builtin_cpu_init();
        int have = strcmp(isas[k].cpu, "sse2") == 0     ? __builtin_cpu_supports("sse2")
                   : strcmp(isas[k].cpu, "sse4.2") == 0 ? __builtin_cpu_supports("sse4.2")
                   : strcmp(isas[k].cpu, "avx") == 0    ? __builtin_cpu_supports("avx")
                   : strcmp(isas[k].cpu, "avx2") == 0   ? __builtin_cpu_supports("avx2")
                                                        : __builtin_cpu_supports("avx512f");
        if (!have) continue;
        snprintf(cfg, sizeof cfg, "isa=%s", isas[k].isa);
        setenv("TESSERA_EMBREE_CONFIG", cfg, 1);
        accel *emb = accel_build_err(s, ACCEL_EMBREE, err, sizeof err);
        unsetenv("TESSERA_EMBREE_CONFIG");
        accel_embree_stats st;
        CHECK(emb && accel_get_embree_stats(emb, &st) == 0 && strcmp(st.config, cfg) == 0, "%s: %s", cfg, err);
        int hits = 0, leaves = 0, differ = emb && tree ? count_differences(s, tree, emb, 60000, &hits, &leaves) : -1;
        CHECK(differ == 0, "%s: %d of 60000 rays differ from the BVH", cfg, differ);
        accel_free(emb);
        /* The wide BVH built by that ISA's Morton builder, on one thread and
         * on all. */
        static const char *const threads[] = {"", ",threads=1"};
        for (int th = 0; th < 2; th++) {
            char wcfg[96];
            snprintf(wcfg, sizeof wcfg, "%s%s", cfg, threads[th]);
            setenv("TESSERA_EMBREE_CONFIG", wcfg, 1);
            setenv("TESSERA_WIDE_BUILDER", "morton", 1);
            accel *wide = accel_build_err(s, ACCEL_WIDE, err, sizeof err);
            unsetenv("TESSERA_WIDE_BUILDER");
            unsetenv("TESSERA_EMBREE_CONFIG");
            accel_wide_stats ws;
            CHECK(wide && accel_get_wide_stats(wide, &ws) == 0 && strcmp(ws.config, wcfg) == 0, "%s: %s", wcfg, err);
            differ = wide && tree ? count_differences(s, tree, wide, 60000, &hits, &leaves) : -1;
            CHECK(differ == 0 && leaves > hits / 2,
                  "wide BVH built with %s: %d of 60000 rays differ from the BVH, %d of %d hits with the leaf's corners",
                  wcfg, differ, leaves, hits);
            accel_free(wide);
        }
        tried++;
    }
    CHECK(tried >= 2, "only %d ISAs tried", tried);
    static const char *const qualities[] = {"medium", "high"}; /* low is the default, tested above */
    for (size_t k = 0; k < 2; k++) {
        setenv("TESSERA_EMBREE_QUALITY", qualities[k], 1);
        accel *emb = accel_build_err(s, ACCEL_EMBREE, err, sizeof err);
        unsetenv("TESSERA_EMBREE_QUALITY");
        int hits = 0, leaves = 0, differ = emb && tree ? count_differences(s, tree, emb, 60000, &hits, &leaves) : -1;
        CHECK(differ == 0, "build quality %s: %d of 60000 rays differ from the BVH", qualities[k], differ);
        accel_free(emb);
    }
    accel_free(tree);
    scene_free(s);
}

/* The picture through Embree and through the wide BVH is the BVH's, bit for
 * bit, with 1 and 2 render threads, and in a local farm of 1, 2 and 3
 * workers (render.accel "auto": the wide BVH). */
TEST(mesh_embree_same_image_threads_and_workers) {
    char err[512];
    scene *s = scene_load(ICO_SCENE, NULL, err, sizeof err);
    CHECK(s && accel_get_kind(s->accel) == ACCEL_WIDE, "auto should pick the wide BVH for %u triangles: %s",
          s ? s->triangle_count : 0, s ? "" : err);
    if (!s) return;
    size_t bytes = (size_t)s->settings.width * (size_t)s->settings.height * 3 * sizeof(float);
    trace_stats st;
    accel_free(s->accel);
    s->accel = accel_build(s, ACCEL_BVH);
    float *b1 = util_render(s, 1, 16, 1, &st);
    static const accel_kind kinds[] = {ACCEL_EMBREE, ACCEL_WIDE};
    for (int k = 0; k < 2; k++) {
        accel_free(s->accel);
        s->accel = accel_build(s, kinds[k]);
        const char *name = kinds[k] == ACCEL_WIDE ? "wide BVH" : "Embree";
        float *e1 = util_render(s, 1, 16, 1, &st), *e2 = util_render(s, 2, 7, 1, &st);
        CHECK(e1 && e2 && b1 && memcmp(e1, b1, bytes) == 0, "%s (1 thread) and BVH images differ", name);
        CHECK(e1 && e2 && memcmp(e1, e2, bytes) == 0, "%s images differ with 1 and 2 threads", name);
        free(e1);
        free(e2);
    }
    free(b1);
    scene_free(s);

    char ref[512], cmd[2048], out[8192];
    snprintf(ref, sizeof ref, "%s", util_temp_path("ico-ref.pfm"));
    snprintf(cmd, sizeof cmd, "%s render " ICO_SCENE " --workers 0 --threads 1 --no-progress -o %s", harness_tessera(),
             ref);
    CHECK(util_run(cmd, out, sizeof out) == 0, "%s: %s", cmd, out);
    static const char *const runs[][2] = {{"1", "1"}, {"2", "2"}, {"3", "1"}};
    for (size_t i = 0; i < sizeof runs / sizeof runs[0]; i++) {
        const char *img = util_temp_path("ico-farm.pfm");
        snprintf(cmd, sizeof cmd, "%s render " ICO_SCENE " --workers %s --threads %s --tile-size 11 --no-progress -o %s",
                 harness_tessera(), runs[i][0], runs[i][1], img);
        int rc = util_run(cmd, out, sizeof out);
        CHECK(rc == 0 && !strstr(out, "Sanitizer") && !strstr(out, "runtime error"), "%s (%d): %s", cmd, rc, out);
        CHECK(util_same_file(img, ref), "%s: image differs from the in-process one", cmd);
    }
}

/* The whole program under qemu emulating a Nehalem (SSE4.2, no AVX): the
 * wide BVH's builder and Embree (the same scene with render.accel "embree")
 * pick their SSE kernels, the flat kernel its 4 lanes, and the picture is
 * the one this machine makes natively. Fails without qemu-x86_64 (unless
 * TESSERA_TESTS_WITHOUT_QEMU, see util_have_qemu); skipped under the
 * sanitizers (their runtimes do not run under qemu-user). */
TEST(mesh_embree_same_image_under_qemu_nehalem) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    return;
#else
    if (!util_have_qemu()) return;
    /* The Embree scene: ICO_SCENE with render.accel "embree" and its mesh
     * named by absolute path, written to a temporary file. */
    char dir[PATH_MAX], embree_scene[PATH_MAX], cmd[3 * PATH_MAX], out[8192];
    snprintf(embree_scene, sizeof embree_scene, "%s", util_temp_path("icospheres-embree.json"));
    CHECK(realpath("tests/scenes", dir) != NULL, "tests/scenes: not found");
    snprintf(cmd, sizeof cmd,
             "sed -e 's|\"render\": {|\"render\": {\"accel\": \"embree\",|' "
             "-e 's|\"icosphere3.obj\"|\"%s/icosphere3.obj\"|' " ICO_SCENE " > %s",
             dir, embree_scene);
    CHECK(util_run(cmd, out, sizeof out) == 0, "%s: %s", cmd, out);
    const char *const scenes[][2] = {{ICO_SCENE, "intersector: wide"}, {embree_scene, "intersector: embree"}};
    for (int k = 0; k < 2; k++) {
        char args[PATH_MAX + 128];
        snprintf(args, sizeof args, "render %s --workers 0 --threads 2 --spp 4 --no-progress -v", scenes[k][0]);
        int rc = util_same_under_nehalem(harness_tessera(), args, "ico", out, sizeof out);
        CHECK(rc == 0, "%s", out);
        CHECK(rc != 0 || strstr(out, scenes[k][1]), "under qemu (Nehalem) %s: no \"%s\": %s", scenes[k][0], scenes[k][1], out);
    }
#endif
}

/* The OBJ reader's own number parser gives exactly strtod's doubles, on
 * numbers printed every way a writer might (%g, %f, %e at every precision,
 * signs, no leading digit, exponents, long mantissas that need strtod). */
TEST(mesh_obj_numbers_are_strtods) {
    enum { N = 30000 };
    size_t cap = (size_t)N * 100 + 64, n = 0;
    char *text = malloc(cap);
    double *want = malloc(sizeof(double) * 3 * N);
    for (int i = 0; i < N; i++) {
        rng_stream rng = rng_stream_start(21, (uint64_t)i, 0);
        n += (size_t)snprintf(text + n, cap - n, "v");
        for (int k = 0; k < 3; k++) {
            char num[64];
            double x = ldexp((double)rng_next(&rng) - 0.5, (int)(rng_next(&rng) * 60.0f) - 30);
            int style = (int)(rng_next(&rng) * 6.0f), prec = (int)(rng_next(&rng) * 19.0f);
            if (style == 0) snprintf(num, sizeof num, "%.*g", prec, x);
            else if (style == 1) snprintf(num, sizeof num, "%.*f", prec % 10, x);
            else if (style == 2) snprintf(num, sizeof num, "%.*e", prec, x);
            else if (style == 3) snprintf(num, sizeof num, "%+.*f", prec % 8, x);
            else if (style == 4) snprintf(num, sizeof num, "%.17g", x);
            else snprintf(num, sizeof num, "%s.%d", x < 0 ? "-" : "", (int)(rng_next(&rng) * 1e6f));
            want[3 * i + k] = strtod(num, NULL);
            n += (size_t)snprintf(text + n, cap - n, " %s", num);
        }
        n += (size_t)snprintf(text + n, cap - n, "%s", i % 7 ? "\n" : " \r\n");
    }
    n += (size_t)snprintf(text + n, cap - n, "f 1 2 3\n");
    obj_mesh m;
    char err[256];
    int rc = obj_parse(text, n, "numbers.obj", &m, err, sizeof err);
    CHECK(rc == 0 && m.vertex_count == N, "%s", err);
    int differ = 0;
    for (size_t i = 0; rc == 0 && i < 3 * (size_t)N; i++) differ += memcmp(&m.positions[i], &want[i], sizeof(double)) != 0;
    CHECK(differ == 0, "%d of %d coordinates differ from strtod's", differ, 3 * N);
    if (rc == 0) obj_mesh_free(&m);
    free(text);
    free(want);
}

/* Bad OBJ input: each a clear error naming the file and the line. */
TEST(mesh_obj_bad_input_names_file_and_line) {
    static const struct {
        const char *text, *want;
    } cases[] = {
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1//1 2//1 3//1\n", "bad.obj:4: face refers to a normal that does not exist"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2//2 3//1\n", "bad.obj:5: face refers to a normal"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//-2 2//1 3//1\n", "bad.obj:5: face refers to a normal"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/2 2/1 3/1\n", "bad.obj:5: face refers to a texture coordinate"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nf 1/0 2/1 3/1\n", "bad.obj:5: face refers to a texture coordinate"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvn 0 0 1\nf 1//1 2 3//1\n", "bad.obj:5: face mixes corners"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1// 2 3\n", "bad.obj:4: face corner's normal index is missing"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1/x 2 3\n", "bad.obj:4: face corner's texture index is missing"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nvt 0 0\nvn 0 0 1\nf 1/1/1/1 2 3\n", "bad.obj:6: face corner is not of the form"},
        {"v 0 0 0\nv nan 0 0\n", "bad.obj:2: vertex coordinate is not finite"},
        {"v 0 0 0\nvn 0 inf 1\n", "bad.obj:2: normal is not finite"},
        {"v 0 0 0\nvn 0 1\n", "bad.obj:2: normal needs three numbers"},
        {"vt 1e300\n", "bad.obj:1: texture coordinate is not finite"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2", "bad.obj:4: face needs at least three vertices"}, /* truncated */
        {"v 0 0 0\nv 1 0 0\nv 0 1", "bad.obj:3: vertex needs three numbers"},                /* truncated */
        /* Parsed in place: strtod and strtol skip any blank, '\n' too, so
         * they must not see past the line (the next one holds numbers). */
        {"v 1 2 \v\n3 4 5\n", "bad.obj:1: vertex needs three numbers"},
        {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 \v\n3\n", "bad.obj:4: face corner is not an index"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        obj_mesh m;
        char err[256] = "";
        int rc = obj_parse(cases[i].text, strlen(cases[i].text), "bad.obj", &m, err, sizeof err);
        CHECK(rc == -1 && strstr(err, cases[i].want), "case %zu: got %d \"%s\", want \"%s\"", i, rc, err, cases[i].want);
        if (rc == 0) obj_mesh_free(&m);
    }
}

/* The scene's centre is half the sum of the bounds, grown corner by corner
 * as fmin/fmax do: on a tie (-0 against +0) the first corner stays. So a
 * scene flat at y = 0 has its centre's y signed like its first corner's y,
 * whatever the later ones (the loader's bounds keep fmin's rule). */
TEST(mesh_bounds_keep_the_first_of_equal_corners) {
    static const char *const first_y[2] = {"-0.0", "0.0"}, *const later_y[2] = {"0.0", "-0.0"};
    for (int k = 0; k < 2; k++) {
        char json[1024], err[512];
        snprintf(json, sizeof json,
                 "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 3, -3], \"look_at\": [0, 0, 0], "
                 "\"fov\": 40}, \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, "
                 "\"shapes\": [{\"type\": \"triangle\", \"material\": \"m\", \"vertices\": [[0, %s, 0], [1, %s, 0], "
                 "[0, %s, 1]]}]}", first_y[k], later_y[k], later_y[k]);
        scene *s = scene_load(util_write_temp("flat-zero.json", json), NULL, err, sizeof err);
        CHECK(s != NULL, "%s", err);
        if (!s) continue;
        CHECK(signbit(s->world_center[1]) == (k == 0), "first corner y %s: centre y %g (sign %d)", first_y[k],
              s->world_center[1], signbit(s->world_center[1]) != 0);
        scene_free(s);
    }
}

/* Vertices no kept triangle uses (unreferenced, or only in a degenerate
 * face) neither move the scene's frame nor reach it: the same triangles,
 * bit for bit, as without them (one of them is beyond what a float holds). */
TEST(mesh_unused_vertices_change_nothing) {
    static const char *const objs[2] = {"v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
                                        "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1e300 0 0\nv 5 5 5\nf 1 2 3\nf 5 5 5\n"};
    scene *s[2];
    for (int k = 0; k < 2; k++) {
        char err[512];
        util_write_temp(k ? "unused-b.obj" : "unused-a.obj", objs[k]);
        const char *json = k ? "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -3], \"look_at\": [0, 0, 0], "
                               "\"fov\": 40}, \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, "
                               "\"shapes\": [{\"type\": \"mesh\", \"file\": \"unused-b.obj\", \"material\": \"m\"}]}"
                             : "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -3], \"look_at\": [0, 0, 0], "
                               "\"fov\": 40}, \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, "
                               "\"shapes\": [{\"type\": \"mesh\", \"file\": \"unused-a.obj\", \"material\": \"m\"}]}";
        s[k] = scene_load(util_write_temp(k ? "unused-b.json" : "unused-a.json", json), NULL, err, sizeof err);
        CHECK(s[k] != NULL, "%s", err);
    }
    if (s[0] && s[1]) {
        CHECK(s[1]->triangle_count == 1 && s[1]->degenerate_triangles == 1, "%u triangles, %zu degenerate",
              s[1]->triangle_count, s[1]->degenerate_triangles);
        CHECK(memcmp(s[0]->triangles, s[1]->triangles, sizeof(triangle)) == 0 &&
                  memcmp(s[0]->world_center, s[1]->world_center, sizeof s[0]->world_center) == 0 &&
                  s[0]->world_scale == s[1]->world_scale,
              "unused vertices moved the frame: centre x %g against %g, scale %g against %g", s[1]->world_center[0],
              s[0]->world_center[0], s[1]->world_scale, s[0]->world_scale);
    }
    scene_free(s[0]);
    scene_free(s[1]);
}

/* A face whose vertex lies beyond the scene's bound (SCENE_COORD_MAX),
 * in the file or once scaled and moved, is refused naming the shape's file,
 * the axis and the coordinate (it rendered black before); a vertex no face
 * uses is not (mesh_unused_vertices_change_nothing). */
TEST(mesh_faces_beyond_the_scene_bound_are_refused) {
    static const struct {
        const char *obj, *shape, *want;
    } cases[] = {
        {"v 0 0 0\nv 1 0 0\nv 0 -2e30 0\nf 1 2 3\n", "", "far.obj: a face's vertex lies at y = -2e+30, beyond +-1e+30"},
        {"v 0 0 0\nv 1 0 0\nv 0 0 1e25\nf 1 2 3\n", ", \"scale\": 1e6",
         "far.obj: a face's vertex lies at z = 1e+31, beyond +-1e+30 (after the shape's scale and translate)"},
        {"v 0 0 0\nv 1e25 0 0\nv 0 1 0\nf 1 2 3\n", ", \"translate\": [1e30, 0, 0]",
         "far.obj: a face's vertex lies at x = 1.00001e+30"},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        util_write_temp("far.obj", cases[i].obj);
        char json[1024], err[512] = "";
        snprintf(json, sizeof json,
                 "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -3], \"look_at\": [0, 0, 0], "
                 "\"fov\": 40}, \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, "
                 "\"shapes\": [{\"type\": \"mesh\", \"file\": \"far.obj\", \"material\": \"m\"%s}]}",
                 cases[i].shape);
        scene *s = scene_load(util_write_temp("far.json", json), NULL, err, sizeof err);
        CHECK(!s && strstr(err, "shapes[0].file: ") && strstr(err, cases[i].want), "case %zu: got \"%s\", want \"%s\"",
              i, s ? "a scene" : err, cases[i].want);
        scene_free(s);
    }
}

/* vn and vt reach the scene: unit normals and uvs with per-corner indices
 * (a quad's fan shares corner 1); a mesh without them leaves its triangles
 * SCENE_NONE, and a scene with none has NULL arrays. */
TEST(mesh_obj_normals_and_uvs_reach_the_scene) {
    util_write_temp("flat.obj", "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nf 1 3 2\n");
    util_write_temp("quad.obj", "v -1 0 -1\nv 1 0 -1\nv 1 0 1\nv -1 0 1\nvn 0 2 0\nvn 0 1 1\nvt 0 0\nvt 1 0\n"
                                "vt 1 1\nvt 0 1\nf 1/1/1 4/4/2 3/3/1 2/2/2\n");
    const char *json = "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 3, -3], \"look_at\": [0, 0, 0], "
                       "\"fov\": 40}, \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
                       " \"shapes\": [{\"type\": \"mesh\", \"file\": \"flat.obj\", \"material\": \"m\"},"
                       " {\"type\": \"mesh\", \"file\": \"quad.obj\", \"material\": \"m\", \"translate\": [0, 1, 0]}]}";
    char err[512];
    scene *s = scene_load(util_write_temp("attrs.json", json), NULL, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    CHECK(s->triangle_count == 3 && util_distinct_corner_normals(s) == 2 && s->uv_count == 4,
          "%u triangles, %zu normals, %u uvs", s->triangle_count, util_distinct_corner_normals(s), s->uv_count);
    CHECK(s->corner_normals && s->triangle_uvs, "no attribute arrays");
    CHECK(s->corner_normals_first == 1 && s->corner_normal_tris == 2, "corner normals over triangles %u + %u, want 1 + 2",
          s->corner_normals_first, s->corner_normal_tris);
    if (s->corner_normals && s->triangle_uvs && s->triangle_count == 3) {
        const uint32_t *t = s->triangle_uvs;
        vec3 c[2][3], a = {0, 1, 0}, b = {0, 0.70710678f, 0.70710678f};
        int has = 1;
        for (int k = 0; k < 3; k++) has &= util_corner_normal(s, 1, k, &c[0][k]) & util_corner_normal(s, 2, k, &c[1][k]);
        vec3 unused;
        CHECK(!util_corner_normal(s, 0, 0, &unused) && t[0] == SCENE_NONE, "flat mesh got attributes");
        /* f 1/1/1 4/4/2 3/3/1 2/2/2, fanned: (1, 4, 3) with normals (1, 2, 1), (1, 3, 2) with (1, 1, 2). */
        const vec3 *want[2][3] = {{&a, &b, &a}, {&a, &a, &b}};
        int right = has;
        for (int i = 0; i < 2 && has; i++)
            for (int k = 0; k < 3; k++)
                right &= c[i][k].x == want[i][k]->x && c[i][k].y == want[i][k]->y && fabsf(c[i][k].z - want[i][k]->z) < 1e-6f;
        CHECK(right, "corner normals (%g %g %g) (%g %g %g) (%g %g %g) / (%g %g %g) (%g %g %g) (%g %g %g)", c[0][0].x,
              c[0][0].y, c[0][0].z, c[0][1].x, c[0][1].y, c[0][1].z, c[0][2].x, c[0][2].y, c[0][2].z, c[1][0].x,
              c[1][0].y, c[1][0].z, c[1][1].x, c[1][1].y, c[1][1].z, c[1][2].x, c[1][2].y, c[1][2].z);
        CHECK(has && c[0][1].y == c[0][1].z && fabsf(c[0][1].y - 0.70710678f) < 1e-6f, "normals not unit");
        CHECK(t[3] == 0 && t[4] == 3 && t[5] == 2 && t[6] == 0 && t[7] == 2 && t[8] == 1, "uv indices");
        CHECK(s->uvs[2 * 2] == 1 && s->uvs[2 * 2 + 1] == 1, "uv 3 is (%g, %g)", s->uvs[4], s->uvs[5]);
    }
    scene_free(s);
    s = scene_load("scenes/cornell-box.json", NULL, err, sizeof err);
    CHECK(s && !s->corner_normals && !s->uvs && !s->triangle_uvs, "cornell box has attributes");
    scene_free(s);
}

/* White furnace: a diffuse sphere of albedo 0.8 under a uniform sky of 1,
 * the shape `type` ("mesh", or "model": through the importer) from file
 * `obj`. Every path that leaves the (convex) sphere returns exactly 0.8, so
 * a pixel covered by the sphere can only be 0.8 times the share of paths not
 * ended by the leak guard: never more (no energy gained, no light through
 * the surface), and not much less (no black facets where the shading and
 * geometric normals disagree, e.g. at the silhouette of a low-poly sphere
 * with vertex normals). Returns the mean of the covered pixels, -1 on
 * failure. */
static double furnace(const char *type, const char *obj, int level_poly, const char *extra, float *min_out) {
    char path[PATH_MAX], json[PATH_MAX + 1024], err[512];
    CHECK(realpath(obj, path) != NULL, "%s missing", obj);
    snprintf(json, sizeof json,
             "{\"render\": {\"width\": 40, \"height\": 40, \"spp\": 64, \"max_depth\": 8, \"seed\": 3},"
             " \"camera\": {\"type\": \"perspective\", \"position\": [0, 0.3, -4], \"look_at\": [0, 0, 0], \"fov\": 32},"
             " \"background\": [1, 1, 1], \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.8, 0.8, 0.8]}},"
             " \"shapes\": [{\"type\": \"%s\", \"file\": \"%s\", \"material\": \"m\"%s}]}",
             type, path, extra);
    scene *s = util_scene_from_text(json, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return -1;
    trace_stats st;
    float *img = util_render(s, 2, 16, 1, &st);
    double sum = 0;
    int covered = 0, gained = 0;
    float lo = 1;
    for (int i = 0; img && i < 40 * 40; i++) {
        float v = img[3 * i + 1];
        if (v > 1.0f + 1e-5f) gained++; /* brighter than the sky: energy from nowhere */
        if (v > 0.8f + 1e-4f) continue; /* sky, or a pixel the silhouette crosses */
        sum += v;
        covered++;
        lo = fminf(lo, v);
    }
    CHECK(img && covered > 300, "%s: only %d pixels on the sphere", obj, covered);
    CHECK(gained == 0, "%s: %d pixels brighter than the albedo allows (energy gained)", obj, gained);
    CHECK(s->corner_normals || level_poly < 0, "%s: no vertex normals loaded", obj);
    free(img);
    scene_free(s);
    *min_out = lo;
    return covered ? sum / covered : -1;
}

TEST(mesh_smooth_normals_white_furnace) {
    float lo;
    double smooth = furnace("mesh", "tests/scenes/icosphere3n.obj", 3, "", &lo); /* 1,280 triangles with vn */
    CHECK(smooth > 0.79 && lo > 0.7f, "smooth sphere: mean %.4f, darkest pixel %.4f of 0.8", smooth, lo);
    float lo_smooth = lo;
    double low = furnace("mesh", "tests/scenes/icosphere1n.obj", 1, "", &lo); /* 80 triangles with vn */
    CHECK(low > 0.74 && lo > 0.5f, "low-poly smooth sphere: mean %.4f, darkest pixel %.4f of 0.8", low, lo);
    float lo_low = lo;
    double flat = furnace("mesh", "tests/scenes/icosphere3.obj", -1, "", &lo); /* no vn: flat facets lose nothing */
    CHECK(flat > 0.7999, "flat-shaded sphere: mean %.5f", flat);
    double made = furnace("mesh", "tests/scenes/icosphere3.obj", 3, ", \"smooth_angle\": 30", &lo); /* normals from faces */
    CHECK(made > 0.79 && lo > 0.7f, "sphere with normals from faces: mean %.4f, darkest %.4f", made, lo);
    fprintf(stderr, "  furnace with normals made from faces (30 degrees): %.4f / %.4f\n", made, lo);
    fprintf(stderr, "  furnace (albedo 0.8), mean / darkest covered pixel: smooth %.4f / %.4f, low-poly smooth %.4f / %.4f, flat %.4f\n",
            smooth, lo_smooth, low, lo_low, flat);
}

/* A worker that cannot hold a scene says so with the figures and gives its
 * tiles back (here: the only worker, so the render fails with that reason)
 * instead of being killed by the kernel; the estimate counts instances. */
TEST(mesh_worker_refuses_a_scene_it_cannot_hold) {
    char cmd[2048], out[16384];
    const char *img = util_temp_path("refused.pfm");
    snprintf(cmd, sizeof cmd,
             "TESSERA_MEMORY_AVAILABLE_MB=0 timeout 120 %s render " ICO_SCENE
             " --workers 1 --width 8 --height 8 --worker-timeout 30 --no-progress -o %s", /* one tile */
             harness_tessera(), img);
    int rc = util_run(cmd, out, sizeof out);
    CHECK(rc != 0 && strstr(out, "cannot hold the scene: loading 2560 triangles needs about 0 MiB, only 0 MiB"),
          "%s (%d): %s", cmd, rc, out);
    scene_bundle b;
    char err[256];
    CHECK(scene_bundle_read(ICO_SCENE, &b, err, sizeof err) == 0, "%s", err);
    uint64_t tris = 0, bytes = scene_memory_estimate(&b, &tris);
    CHECK(tris == 2560 && bytes > 2560 * SCENE_MEMORY_BYTES_PER_TRIANGLE, "estimate: %llu triangles, %llu bytes",
          (unsigned long long)tris, (unsigned long long)bytes);
    scene_bundle_free(&b);
}

/* The estimate counts a mesh's faces on every core (ranges of at least 1
 * MiB, each counting the lines that start in it): the same count with 1,
 * 2, 3 and 7 threads over a 9 MB text whose faces, comments and blank
 * lines fall across the ranges' bounds. */
TEST(mesh_memory_estimate_counts_faces_on_any_threads) {
    size_t cap = 10u << 20, len = 0;
    char *obj = malloc(cap + 1);
    CHECK(obj != NULL, "out of memory");
    if (!obj) return;
    uint64_t want = 0;
    uint64_t x = 7;
    while (len < 9u << 20) {
        x = rng_mix64(x);
        uint32_t k = (uint32_t)(x % 6), n;
        if (k == 0) n = (uint32_t)snprintf(obj + len, cap - len, "# f 1 2 3 a comment\n");
        else if (k == 1) n = (uint32_t)snprintf(obj + len, cap - len, "\n");
        else if (k == 2) n = (uint32_t)snprintf(obj + len, cap - len, "v 0.5 1.25 -3\n");
        else {
            uint32_t corners = 3 + (uint32_t)(x >> 32) % 5; /* 3 to 7: corners - 2 triangles */
            n = (uint32_t)snprintf(obj + len, cap - len, "%sf", k == 3 ? "  " : "");
            for (uint32_t c = 0; c < corners; c++) n += (uint32_t)snprintf(obj + len + n, cap - len - n, " %u/1", c + 1);
            n += (uint32_t)snprintf(obj + len + n, cap - len - n, "\n");
            want += corners - 2;
        }
        len += n;
    }
    scene_bundle_file files[2] = {{(char *)"big.json", (char *)"{\"shapes\": [{\"file\": \"big.obj\"}]}", 34, NULL, 0},
                                  {(char *)"big.obj", obj, len, NULL, 0}};
    scene_bundle b = {files, 2};
    static const char *const threads[] = {"1", "2", "3", "7"};
    for (size_t t = 0; t < sizeof threads / sizeof threads[0]; t++) {
        setenv("TESSERA_LOAD_THREADS", threads[t], 1);
        uint64_t tris = 0;
        scene_memory_estimate(&b, &tris);
        CHECK(tris == want, "%s threads: %llu triangles counted, want %llu", threads[t], (unsigned long long)tris,
              (unsigned long long)want);
    }
    unsetenv("TESSERA_LOAD_THREADS");
    free(obj);
}

/* Rendering in this process, the scene's estimated load and build count
 * against --max-memory with the frame, checked before the build: a scene
 * too big is refused with the figures, not killed by the kernel halfway. */
TEST(mesh_render_in_process_refuses_a_scene_over_max_memory) {
    /* a grid of 50 x 50 quads: 5000 triangles, 1.2 MiB at 256 B each */
    static char obj[200000];
    size_t len = 0;
    for (int y = 0; y <= 50; y++)
        for (int x = 0; x <= 50; x++) len += (size_t)snprintf(obj + len, sizeof obj - len, "v %d %d 0\n", x, y);
    for (int y = 0; y < 50; y++)
        for (int x = 0; x < 50; x++)
            len += (size_t)snprintf(obj + len, sizeof obj - len, "f %d %d %d %d\n", y * 51 + x + 1, y * 51 + x + 2,
                                    (y + 1) * 51 + x + 2, (y + 1) * 51 + x + 1);
    CHECK(len < sizeof obj - 1 && util_write_temp("grid.obj", obj), "grid.obj not written");
    const char *scene = util_write_temp("grid.json",
        "{\"camera\": {\"type\": \"perspective\", \"position\": [25, 25, -60], \"look_at\": [25, 25, 0], \"fov\": 40},"
        " \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
        " \"shapes\": [{\"type\": \"mesh\", \"file\": \"grid.obj\", \"material\": \"m\"}],"
        " \"lights\": [{\"type\": \"point\", \"position\": [25, 25, -30], \"intensity\": [100, 100, 100]}]}");
    char cmd[2048], out[8192], scene_path[512];
    snprintf(scene_path, sizeof scene_path, "%s", scene ? scene : "");
    const char *img = util_temp_path("over-budget.pfm");
    unlink(img);
    snprintf(cmd, sizeof cmd, "%s render %s --workers 0 --width 8 --height 8 --max-memory 1M -o %s",
             harness_tessera(), scene_path, img);
    int rc = util_run(cmd, out, sizeof out);
    struct stat st;
    CHECK(rc != 0 && strstr(out, "the scene's 5000 triangles (their load and build, estimated) need") &&
              strstr(out, "--max-memory is 1.0 MiB") && stat(img, &st) != 0,
          "%s (%d): %s", cmd, rc, out);
    snprintf(cmd, sizeof cmd, "%s render %s --workers 0 --width 8 --height 8 --max-memory 64M -o %s",
             harness_tessera(), scene_path, img);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 0 && stat(img, &st) == 0, "%s (%d): %s", cmd, rc, out);
}

/* Bundle `path` and check its estimate: want_tris triangles, and exactly
 * the bundle's bytes + extra + want_tris * per_tri. */
static void check_estimate(const char *path, uint64_t want_tris, uint64_t per_tri, uint64_t extra) {
    scene_bundle b;
    char err[256];
    CHECK(scene_bundle_read(path, &b, err, sizeof err) == 0, "%s", err);
    uint64_t files = 0, tris = 0, bytes = scene_memory_estimate(&b, &tris);
    for (size_t i = 0; i < b.count; i++) files += b.files[i].len;
    CHECK(tris == want_tris && bytes == files + extra + want_tris * per_tri,
          "%s: %llu triangles, %llu bytes; want %llu and %llu", path, (unsigned long long)tris,
          (unsigned long long)bytes, (unsigned long long)want_tris,
          (unsigned long long)(files + extra + want_tris * per_tri));
    scene_bundle_free(&b);
}

/* Models count in the memory estimate (scene_memory.h): a glTF's
 * primitives times the nodes naming their mesh, at the imported rate (mode
 * 4 count / 3, strips and fans count - 2, lines nothing), PNG and JPEG
 * textures at 4 bytes per texel (bundle files, as a glTF's PNG here and an
 * MTL's JPEG, and a binary glTF's images in its BIN chunk);
 * a mesh OBJ at the mesh rate, the same OBJ imported at the imported rate.
 * A worker too small for a model gives its tile back naming the figures.
 * (Before, a model counted only its file's bytes: a worker took a 1.3M
 * triangle .glb of 36 MB that peaks at 410 MB.) */
TEST(mesh_memory_estimate_counts_models_and_textures) {
    /* suzanne.glb: mesh 0 (15,744 triangles) and mesh 1 (2), a node each */
    check_estimate("scenes/gltf/suzanne.glb", 15746, SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE, 0);
    /* arrow-plane.gltf: 2 triangles and arrow.png, 64 x 64 */
    check_estimate("scenes/gltf/arrow-plane.gltf", 2, SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE, 64 * 64 * 4);
    /* mesh 0 named by three nodes (one of them nested), mesh 1 by one:
     * 3 x (9 / 3 + (9 - 2) + 0) + (6 - 2) */
    const char *gltf = util_write_temp("counted.gltf",
        "{\"asset\": {\"version\": \"2.0\"}, \"scenes\": [{\"nodes\": [0, 1, 2, 3]}],"
        " \"nodes\": [{\"mesh\": 0}, {\"mesh\": 0, \"children\": [4]}, {\"mesh\": 1}, {}, {\"mesh\": 0}],"
        " \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0}, \"indices\": 1},"
        " {\"attributes\": {\"POSITION\": 0}, \"mode\": 5}, {\"attributes\": {\"POSITION\": 0}, \"mode\": 1}]},"
        " {\"primitives\": [{\"attributes\": {\"POSITION\": 2}, \"mode\": 6}]}],"
        " \"accessors\": [{\"count\": 9}, {\"count\": 9}, {\"count\": 6}]}");
    CHECK(gltf != NULL, "temp file not written");
    if (gltf) check_estimate(gltf, 3 * (3 + 7) + 4, SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE, 0);
    /* One OBJ, as a mesh and as an import */
    const char *obj = util_write_temp("counted.obj", "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 0\nf 1 2 4 3\nf 1 2 3\n");
    char json[512];
    snprintf(json, sizeof json,
             "{\"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
             " \"shapes\": [{\"type\": \"mesh\", \"file\": \"counted.obj\", \"material\": \"m\"}]}");
    const char *as_mesh = util_write_temp("counted-mesh.json", json); /* util's buffer: used before the next */
    CHECK(obj && as_mesh, "temp files not written");
    if (obj && as_mesh) check_estimate(as_mesh, 3, SCENE_MEMORY_BYTES_PER_TRIANGLE, 0);
    const char *as_model = util_write_temp("counted-model.json", "{\"import\": {\"file\": \"counted.obj\"}}");
    CHECK(as_model != NULL, "temp file not written");
    if (as_model) check_estimate(as_model, 3, SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE, 0);
    /* A binary glTF holding arrow.png (64 x 64) in its BIN chunk */
    static uint8_t glb[4096];
    FILE *png = fopen("scenes/gltf/arrow.png", "rb");
    size_t png_len = png ? fread(glb + 2048, 1, 2048, png) : 0;
    if (png) fclose(png);
    char gj[512];
    int jl = snprintf(gj, sizeof gj,
                      "{\"asset\": {\"version\": \"2.0\"}, \"images\": [{\"bufferView\": 0, \"mimeType\": "
                      "\"image/png\"}], \"bufferViews\": [{\"buffer\": 0, \"byteLength\": %zu}], \"buffers\": "
                      "[{\"byteLength\": %zu}]}",
                      png_len, png_len);
    while (jl % 4) gj[jl++] = ' ';
    size_t bl = (png_len + 3) / 4 * 4, total = 12 + 8 + (size_t)jl + 8 + bl;
    const uint32_t head[5] = {0x46546C67u, 2, (uint32_t)total, (uint32_t)jl, 0x4E4F534Au},
                   bin_head[2] = {(uint32_t)bl, 0x004E4942u};
    memmove(glb + 20 + jl + 8, glb + 2048, png_len);
    memset(glb + 20 + jl + 8 + png_len, 0, bl - png_len);
    memcpy(glb, head, sizeof head);
    memcpy(glb + 20, gj, (size_t)jl);
    memcpy(glb + 20 + jl, bin_head, sizeof bin_head);
    FILE *gf = png_len > 24 ? fopen(util_temp_path("image.glb"), "wb") : NULL;
    int written = gf && fwrite(glb, 1, total, gf) == total;
    if (gf) written &= fclose(gf) == 0;
    CHECK(written, "image.glb not written (arrow.png: %zu bytes)", png_len);
    if (written) check_estimate(util_temp_path("image.glb"), 0, SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE, 64 * 64 * 4);
    /* A JPEG texture (map_Kd of an imported OBJ), 40 x 24 */
    char cmd[2048], out[16384];
    snprintf(cmd, sizeof cmd, "%s render scenes/cornell-box.json --workers 0 --width 40 --height 24 --spp 1 -o %s",
             harness_tessera(), util_temp_path("counted.jpg"));
    CHECK(util_run(cmd, out, sizeof out) == 0, "%s: %s", cmd, out);
    const char *mtl = util_write_temp("counted.mtl", "newmtl a\nmap_Kd counted.jpg\n");
    const char *tobj = util_write_temp("textured.obj", "mtllib counted.mtl\nusemtl a\nv 0 0 0\nv 1 0 0\nv 0 1 0\n"
                                                         "vt 0 0\nvt 1 0\nvt 0 1\nf 1/1 2/2 3/3\n");
    const char *tscene = util_write_temp("textured.json", "{\"import\": {\"file\": \"textured.obj\"}}");
    CHECK(mtl && tobj && tscene, "temp files not written");
    if (tscene) check_estimate(tscene, 1, SCENE_MEMORY_BYTES_PER_IMPORTED_TRIANGLE, 40 * 24 * 4);
    snprintf(cmd, sizeof cmd,
             "TESSERA_MEMORY_AVAILABLE_MB=0 timeout 120 %s render scenes/gltf/suzanne.glb --workers 1 --width 8 "
             "--height 8 --worker-timeout 30 --no-progress -o %s",
             harness_tessera(), util_temp_path("refused-model.pfm"));
    int rc = util_run(cmd, out, sizeof out);
    CHECK(rc != 0 && strstr(out, "cannot hold the scene: loading 15746 triangles needs about 7 MiB, only 0 MiB"),
          "%s (%d): %s", cmd, rc, out);
}

/* The floor of the light-leak tests: one-sided, its vertex normals leaning
 * 60 degrees towards +x. */
#define TILTED_FLOOR_OBJ "v -2 0 -2\nv 2 0 -2\nv 2 0 2\nv -2 0 2\nvn 0.866 0.5 0\nf 1//1 4//1 3//1 2//1\n"

/* No light leaks: the tilted floor as shape `type` from `file` (in the temp
 * directory), lit only by a point light under it, seen from above. Light
 * directions below the surface but above the tilted shading hemisphere must
 * be refused: the picture is black (it is not without the guard). */
static void floor_does_not_leak(const char *type, const char *file) {
    char json[2048], err[512];
    snprintf(json, sizeof json,
             "{\"render\": {\"width\": 16, \"height\": 16, \"spp\": 16, \"max_depth\": 4, \"seed\": 1},"
             " \"camera\": {\"type\": \"perspective\", \"position\": [0, 3, -0.1], \"look_at\": [0, 0, 0], \"fov\": 40},"
             " \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.8, 0.8, 0.8]}},"
             " \"shapes\": [{\"type\": \"%s\", \"file\": \"%s\", \"material\": \"m\"}],"
             " \"lights\": [{\"type\": \"point\", \"position\": [3, -0.5, 0], \"intensity\": [50, 50, 50]}]}",
             type, file);
    scene *s = scene_load(util_write_temp("leak.json", json), NULL, err, sizeof err);
    CHECK(s && s->corner_normals, "%s: %s", file, s ? "no vertex normals" : err);
    if (!s) return;
    trace_stats st;
    float *img = util_render(s, 1, 16, 1, &st);
    int lit = 0;
    for (int i = 0; img && i < 16 * 16 * 3; i++) lit += img[i] != 0.0f;
    CHECK(img && lit == 0, "%s: %d channels lit through the floor", file, lit);
    free(img);
    scene_free(s);
}

TEST(mesh_smooth_normals_do_not_leak_light) {
    util_write_temp("tilted.obj", TILTED_FLOOR_OBJ);
    floor_does_not_leak("mesh", "tilted.obj");
}

/* Write the OBJ file `obj` as a binary glTF `name` in the temp directory:
 * one primitive without indices, a vertex per triangle corner with the
 * OBJ's position and vn (as written) as POSITION and NORMAL. Returns the
 * path, or NULL. */
static const char *glb_from_obj(const char *obj, const char *name) {
    obj_mesh m;
    char err[256];
    CHECK(obj_load(obj, &m, err, sizeof err) == 0, "%s", err);
    if (!m.normal_indices) return NULL;
    uint32_t v = 3 * (uint32_t)m.triangle_count, half = 12 * v;
    float *bin = malloc(2 * (size_t)half), lo[3] = {INFINITY, INFINITY, INFINITY}, hi[3] = {-INFINITY, -INFINITY, -INFINITY};
    for (uint32_t c = 0; c < v; c++)
        for (int a = 0; a < 3; a++) {
            float p = (float)m.positions[3 * m.indices[c] + a];
            bin[3 * c + a] = p;
            bin[3 * (v + c) + a] = m.normals[3 * m.normal_indices[c] + a];
            lo[a] = fminf(lo[a], p);
            hi[a] = fmaxf(hi[a], p);
        }
    obj_mesh_free(&m);
    char json[2048];
    int jl = snprintf(json, sizeof json,
                      "{\"asset\": {\"version\": \"2.0\"}, \"scenes\": [{\"nodes\": [0]}], \"nodes\": [{\"mesh\": 0}],"
                      " \"meshes\": [{\"primitives\": [{\"attributes\": {\"POSITION\": 0, \"NORMAL\": 1}}]}],"
                      " \"buffers\": [{\"byteLength\": %u}], \"bufferViews\": [{\"buffer\": 0, \"byteLength\": %u},"
                      " {\"buffer\": 0, \"byteOffset\": %u, \"byteLength\": %u}],"
                      " \"accessors\": [{\"bufferView\": 0, \"componentType\": 5126, \"count\": %u, \"type\": \"VEC3\","
                      " \"min\": [%.9g, %.9g, %.9g], \"max\": [%.9g, %.9g, %.9g]},"
                      " {\"bufferView\": 1, \"componentType\": 5126, \"count\": %u, \"type\": \"VEC3\"}]}",
                      2 * half, half, half, half, v, lo[0], lo[1], lo[2], hi[0], hi[1], hi[2], v);
    while (jl % 4) json[jl++] = ' '; /* chunks are 4-byte aligned */
    uint32_t head[5] = {0x46546C67u /* glTF */, 2, 12 + 8 + (uint32_t)jl + 8 + 2 * half, (uint32_t)jl, 0x4E4F534Au /* JSON */};
    uint32_t bin_head[2] = {2 * half, 0x004E4942u /* BIN */};
    const char *path = util_temp_path(name);
    FILE *f = fopen(path, "wb");
    int ok = f && fwrite(head, sizeof head, 1, f) == 1 && fwrite(json, (size_t)jl, 1, f) == 1 &&
             fwrite(bin_head, sizeof bin_head, 1, f) == 1 && fwrite(bin, 2 * (size_t)half, 1, f) == 1;
    if (f) ok &= fclose(f) == 0;
    free(bin);
    CHECK(ok, "cannot write %s", path);
    return ok ? path : NULL;
}

/* Imported models shade by the same rules as meshes (shading_normal.h): the
 * low-poly smooth sphere as a glTF with normals passes the furnace with no
 * black facets (the mesh test's bounds), its corners sharing the sphere's
 * 42 normals (stored once each although the file repeats them per
 * triangle); the smooth sphere, and the same sphere flat (no normals in
 * the file, through Assimp's OBJ reader) lose nothing. */
TEST(mesh_imported_smooth_normals_white_furnace) {
    float lo = 0;
    const char *glb = glb_from_obj("tests/scenes/icosphere1n.obj", "ico1n.glb");
    double low = glb ? furnace("model", glb, 1, "", &lo) : -1;
    CHECK(low > 0.74 && lo > 0.5f, "imported low-poly smooth sphere: mean %.4f, darkest pixel %.4f of 0.8", low, lo);
    fprintf(stderr, "  imported (glTF) low-poly smooth sphere: mean %.4f, darkest %.4f\n", low, lo);
    char err[512];
    scene *s = glb ? util_scene_from_text("{\"import\": {\"file\": \"ico1n.glb\"}}", err, sizeof err) : NULL;
    CHECK(s && s->triangle_count == 80 && util_smooth_triangles(s) == 80 && util_distinct_corner_normals(s) == 42,
          "%u triangles, %zu with normals, %zu distinct normals (want 80, 80, 42): %s", s ? s->triangle_count : 0,
          s ? util_smooth_triangles(s) : 0, s ? util_distinct_corner_normals(s) : 0, s ? "" : err);
    scene_free(s);
    glb = glb_from_obj("tests/scenes/icosphere3n.obj", "ico3n.glb");
    double smooth = glb ? furnace("model", glb, 3, "", &lo) : -1;
    CHECK(smooth > 0.79 && lo > 0.7f, "imported smooth sphere: mean %.4f, darkest pixel %.4f of 0.8", smooth, lo);
    double flat = furnace("model", "tests/scenes/icosphere3.obj", -1, "", &lo);
    CHECK(flat > 0.7999, "imported flat sphere: mean %.5f", flat);
}

/* The tilted floor as a glTF with normals leaks no light either. */
TEST(mesh_imported_smooth_normals_do_not_leak_light) {
    const char *glb = glb_from_obj(util_write_temp("tilted.obj", TILTED_FLOOR_OBJ), "tilted.glb");
    if (glb) floor_does_not_leak("model", "tilted.glb");
}

/* Normals made from faces follow the angle threshold: every corner of an
 * icosphere (faces 10 degrees apart at level 2... 2.6 at level 3) is
 * smoothed at 30 degrees, no corner of a tetrahedron (faces 109 degrees
 * apart) is: its corner normals are its face normals. */
TEST(mesh_normals_from_faces_follow_the_angle) {
    obj_mesh m;
    char err[256];
    const char *tet = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 0 0 1\nf 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n";
    CHECK(obj_parse(tet, strlen(tet), "tet.obj", &m, err, sizeof err) == 0, "%s", err);
    CHECK(mesh_normals_from_faces(&m, 30) == 0 && m.normal_count == 12, "normals");
    int off = 0;
    for (size_t t = 0; t < 4; t++) {
        const double *a = m.positions + 3 * m.indices[3 * t], *b = m.positions + 3 * m.indices[3 * t + 1],
                     *c = m.positions + 3 * m.indices[3 * t + 2];
        double e1[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, e2[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
        double n[3] = {e1[1] * e2[2] - e1[2] * e2[1], e1[2] * e2[0] - e1[0] * e2[2], e1[0] * e2[1] - e1[1] * e2[0]};
        double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
        for (int k = 0; k < 3; k++)
            for (int x = 0; x < 3; x++) off += fabs(m.normals[3 * m.normal_indices[3 * t + k] + x] - n[x] / l) > 1e-6;
    }
    CHECK(off == 0, "%d tetrahedron normal components differ from the face normals", off);
    obj_mesh_free(&m);
    CHECK(obj_load("tests/scenes/icosphere3.obj", &m, err, sizeof err) == 0, "%s", err);
    CHECK(mesh_normals_from_faces(&m, 30) == 0, "normals");
    int flat = 0;
    for (size_t i = 0; i < m.triangle_count * 3; i++) { /* a smoothed corner normal points along its vertex */
        const double *p = m.positions + 3 * m.indices[i];
        const float *n = m.normals + 3 * m.normal_indices[i];
        flat += n[0] * p[0] + n[1] * p[1] + n[2] * p[2] < 0.9995;
    }
    CHECK(flat == 0, "%d of %zu icosphere corners not smoothed", flat, m.triangle_count * 3);
    obj_mesh_free(&m);
}

/* Corner normals (scene.h) over the triangles that have them: an
 * octahedron smoothed by "smooth_angle" after a flat quad gets them from
 * its first triangle on, each corner the same bits as when it is loaded
 * alone, and the quad none. */
TEST(mesh_corner_normals_cover_the_smooth_triangles) {
    util_write_temp("octa2.obj", "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                                 "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n");
    util_write_temp("floor2.obj", "v -5 -2 -5\nv 5 -2 -5\nv 5 -2 5\nv -5 -2 5\nf 1 3 2\nf 1 4 3\n");
    char json[1024], err[512];
    scene *s[2];
    for (int i = 0; i < 2; i++) {
        snprintf(json, sizeof json,
                 "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 1, 4], \"look_at\": [0, 0, 0], \"fov\": 40},"
                 " \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.8, 0.8, 0.8]}},"
                 " \"shapes\": [%s{\"type\": \"mesh\", \"file\": \"octa2.obj\", \"material\": \"m\", \"smooth_angle\": 80}]}",
                 i ? "{\"type\": \"mesh\", \"file\": \"floor2.obj\", \"material\": \"m\"}, " : "");
        s[i] = scene_load(util_write_temp("corners.json", json), NULL, err, sizeof err);
        CHECK(s[i] != NULL, "%s", err);
    }
    if (s[0] && s[1]) {
        CHECK(s[0]->corner_normals_first == 0 && s[0]->corner_normal_tris == 8 && s[1]->corner_normals_first == 2 &&
                  s[1]->corner_normal_tris == 8,
              "corner normals over %u + %u alone, %u + %u after the quad (want 0 + 8, 2 + 8)",
              s[0]->corner_normals_first, s[0]->corner_normal_tris, s[1]->corner_normals_first, s[1]->corner_normal_tris);
        vec3 a, b;
        CHECK(!util_corner_normal(s[1], 0, 0, &a) && !util_corner_normal(s[1], 1, 0, &a), "the flat quad has normals");
        int same = 1, have = 1;
        for (uint32_t t = 0; t < 8; t++)
            for (int k = 0; k < 3; k++) {
                have &= util_corner_normal(s[0], t, k, &a) & util_corner_normal(s[1], t + 2, k, &b);
                same &= memcmp(&a, &b, sizeof a) == 0;
            }
        CHECK(have && same, "the octahedron's corner normals differ after the quad (have %d)", have);
        CHECK(util_distinct_corner_normals(s[1]) == 24, "%zu distinct made normals, want 24 (one per corner)",
              util_distinct_corner_normals(s[1]));
    }
    scene_free(s[0]);
    scene_free(s[1]);
}

/* A mesh's own vertex normals survive in a scene that also imports a model:
 * an octahedron smoothed by "smooth_angle", lit directly by a point light,
 * renders the same (to rounding: the scene's bounds differ) with and
 * without an imported triangle far out of view (a "model" shape with a
 * normal: the scene gets the importer's shading data, corner uvs, and the
 * model's normal joins the mesh's in the corner normals). Once, a separate
 * per-corner normal array gave triangles that were not imported their
 * geometric normal, which replaced the mesh's smooth normal: the
 * octahedron came out faceted. */
TEST(mesh_smooth_normals_survive_an_imported_model) {
    util_write_temp("octa.obj", "v 1 0 0\nv -1 0 0\nv 0 1 0\nv 0 -1 0\nv 0 0 1\nv 0 0 -1\n"
                                "f 1 3 5\nf 3 2 5\nf 2 4 5\nf 4 1 5\nf 3 1 6\nf 2 3 6\nf 4 2 6\nf 1 4 6\n");
    util_write_temp("far.obj", "v -1 0 -1\nv 1 0 -1\nv 0 0 1\nvn 0 1 0\nf 1//1 3//1 2//1\n");
    char json[2048], err[1024];
    float *img[2] = {NULL, NULL};
    for (int i = 0; i < 2; i++) {
        snprintf(json, sizeof json,
                 "{\"render\": {\"width\": 24, \"height\": 24, \"spp\": 4, \"max_depth\": 1, \"seed\": 1},"
                 " \"camera\": {\"type\": \"perspective\", \"position\": [0.5, 1, 4], \"look_at\": [0, 0, 0], \"fov\": 40},"
                 " \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.8, 0.8, 0.8]}},"
                 " \"shapes\": [{\"type\": \"mesh\", \"file\": \"octa.obj\", \"material\": \"m\", \"smooth_angle\": 80}%s],"
                 " \"lights\": [{\"type\": \"point\", \"position\": [3, 3, 3], \"intensity\": [20, 20, 20]}]}",
                 i ? ", {\"type\": \"model\", \"file\": \"far.obj\", \"translate\": [0, -40, 0]}" : "");
        scene *s = scene_load(util_write_temp("mixed.json", json), NULL, err, sizeof err);
        CHECK(s && s->corner_normals && (i == 0 || s->corner_uvs), "%s", s ? "no normals" : err);
        /* Made normals are each corner's own sum of its faces: 24 of them. */
        CHECK(!s || (util_smooth_triangles(s) == 8u + (unsigned)i && util_distinct_corner_normals(s) == 24u + (unsigned)i),
              "%zu triangles with normals, %zu distinct normals (want %u, %u)", s ? util_smooth_triangles(s) : 0,
              s ? util_distinct_corner_normals(s) : 0, 8u + (unsigned)i, 24u + (unsigned)i);
        if (!s) return;
        trace_stats st;
        img[i] = util_render(s, 1, 24, 1, &st);
        scene_free(s);
    }
    float worst = 0, top = 0;
    for (int k = 0; img[0] && img[1] && k < 24 * 24 * 3; k++) {
        worst = fmaxf(worst, fabsf(img[0][k] - img[1][k]));
        top = fmaxf(top, img[0][k]);
    }
    CHECK(img[0] && img[1] && top > 0.05f && worst < 1e-3f * top, "images differ by up to %g (brightest %g)", worst, top);
    free(img[0]);
    free(img[1]);
}

/* A scene of 2^19 primitives or more: `tessera render` with its defaults
 * renders it in its own process (it has loaded it already) instead of
 * handing it to a local worker, and the picture is the farm's, byte for
 * byte. The mesh: a 512 x 512 grid of quads, 2^19 triangles. */
TEST(mesh_big_scene_renders_in_process_with_the_farms_bytes) {
    enum { N = 512 };
    char *obj = malloc((size_t)(N + 1) * (N + 1) * 32 + (size_t)N * N * 48), *p = obj;
    CHECK(obj != NULL, "out of memory");
    if (!obj) return;
    for (int i = 0; i <= N; i++)
        for (int k = 0; k <= N; k++) p += sprintf(p, "v %d %g %d\n", k, 0.25 * ((i * 7 + k * 3) % 5), i);
    for (int i = 0; i < N; i++)
        for (int k = 0; k < N; k++) {
            int a = i * (N + 1) + k + 1;
            p += sprintf(p, "f %d %d %d %d\n", a, a + N + 1, a + N + 2, a + 1);
        }
    util_write_temp("grid.obj", obj);
    free(obj);
    const char *json = "{\"render\": {\"width\": 12, \"height\": 12, \"spp\": 2}, \"camera\": {\"type\": \"perspective\", "
                       "\"position\": [256, 400, -200], \"look_at\": [256, 0, 256], \"fov\": 50}, \"materials\": {\"m\": "
                       "{\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, \"shapes\": [{\"type\": \"mesh\", \"file\": "
                       "\"grid.obj\", \"material\": \"m\"}, {\"type\": \"quad\", \"emission\": [5, 5, 5], \"vertices\": "
                       "[[100, 300, 100], [400, 300, 100], [400, 300, 400], [100, 300, 400]]}]}";
    char scene_path[512], img_own[512], img_farm[512], cmd[2048], out[8192];
    snprintf(scene_path, sizeof scene_path, "%s", util_write_temp("grid.json", json));
    snprintf(img_own, sizeof img_own, "%s", util_temp_path("grid-own.pfm"));
    snprintf(img_farm, sizeof img_farm, "%s", util_temp_path("grid-farm.pfm"));
    snprintf(cmd, sizeof cmd, "%s render %s -v --no-progress -o %s", harness_tessera(), scene_path, img_own);
    int st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "no local farm: 524290 primitives are rendered in this process") &&
              strstr(out, "intersector: ") && !strstr(out, "built by each worker"),
          "defaults: status %d: %s", st, out);
    snprintf(cmd, sizeof cmd, "TESSERA_LOCAL_FORK=0 %s render %s --workers 1 --threads 2 -v --no-progress -o %s",
             harness_tessera(), scene_path, img_farm);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0, "one spawned worker: status %d: %s", st, out);
    /* With -v a spawned local worker says which intersector it built (the
     * choice is the scene's: the same as in process). */
    CHECK(strstr(out, "built by each worker") && strstr(out, "loaded, 524290 triangles, intersector wide"),
          "one spawned worker, -v: no line naming the worker's intersector: %s", out);
    CHECK(util_same_file(img_own, img_farm), "in process and on a one-worker farm: the images differ");
    /* A forked worker (the default) renders with this process's tree. */
    snprintf(cmd, sizeof cmd, "%s render %s --workers 1 --threads 2 -v --no-progress -o %s", harness_tessera(),
             scene_path, img_farm);
    st = util_run(cmd, out, sizeof out);
    CHECK(st == 0 && strstr(out, "intersector: wide") && strstr(out, "local workers: 1 forked") &&
              !strstr(out, "built by each worker") && !strstr(out, "loaded, 524290 triangles"),
          "one forked worker: status %d: %s", st, out);
    CHECK(util_same_file(img_own, img_farm), "in process and on a one-forked-worker farm: the images differ");
}

/* The wide BVH's arena (render/bump_arena.h) under threads: blocks from
 * several threads at once, across many chunk changes (2 MiB chunks), are
 * 64-byte aligned and never overlap (each thread fills its blocks with its
 * own bytes and finds them intact after all have finished); a block bigger
 * than a chunk is refused; the byte count covers what was handed out. Run
 * under ThreadSanitizer by `make test-tsan` (the name has "thread"). */
enum { ARENA_THREADS = 4, ARENA_BLOCKS = 6000 };
typedef struct {
    bump_arena *a;
    int id;
    unsigned char *blocks[ARENA_BLOCKS];
    size_t sizes[ARENA_BLOCKS];
} arena_worker;

static void *arena_worker_main(void *arg) {
    arena_worker *w = arg;
    static const size_t sizes[] = {256, 320, 160, 1, 640, 64};
    for (int i = 0; i < ARENA_BLOCKS; i++) {
        size_t n = sizes[(size_t)(i + w->id) % (sizeof sizes / sizeof sizes[0])];
        unsigned char *p = bump_arena_alloc(w->a, n);
        w->blocks[i] = p, w->sizes[i] = n;
        if (p) memset(p, (int)(1 + w->id * 37 + i % 5), n);
    }
    return NULL;
}

/* A chunk hint (bump_arena_hint_fn) that counts its calls, checks what it
 * is given, and says "huge pages" for all but the chunk numbered
 * arena_hint_refuse (counting from 1; 0: none). */
static atomic_int arena_hints, arena_hint_bad;
static int arena_hint_refuse;
static int arena_hint(void *chunk, size_t bytes) {
    int k = atomic_fetch_add(&arena_hints, 1) + 1;
    if ((uintptr_t)chunk % (2u << 20) || bytes != (2u << 20)) atomic_fetch_add(&arena_hint_bad, 1);
    return k != arena_hint_refuse;
}

TEST(mesh_bump_arena_threads_get_disjoint_blocks) {
    atomic_store(&arena_hints, 0), atomic_store(&arena_hint_bad, 0), arena_hint_refuse = 0;
    bump_arena *a = bump_arena_new(2u << 20, arena_hint);
    CHECK(a != NULL, "bump_arena_new failed");
    if (!a) return;
    CHECK(bump_arena_alloc(a, (2u << 20) + 1) == NULL, "a block bigger than a chunk was handed out");
    static arena_worker ws[ARENA_THREADS];
    pthread_t th[ARENA_THREADS];
    for (int t = 0; t < ARENA_THREADS; t++) {
        ws[t].a = a, ws[t].id = t;
        pthread_create(&th[t], NULL, arena_worker_main, &ws[t]);
    }
    for (int t = 0; t < ARENA_THREADS; t++) pthread_join(th[t], NULL);
    size_t total = 0, bad_align = 0, missing = 0, overwritten = 0;
    for (int t = 0; t < ARENA_THREADS; t++)
        for (int i = 0; i < ARENA_BLOCKS; i++) {
            unsigned char *p = ws[t].blocks[i];
            size_t n = ws[t].sizes[i];
            if (!p) {
                missing++;
                continue;
            }
            if ((uintptr_t)p % BUMP_ARENA_ALIGN) bad_align++;
            total += (n + BUMP_ARENA_ALIGN - 1) / BUMP_ARENA_ALIGN * BUMP_ARENA_ALIGN;
            for (size_t k = 0; k < n; k++)
                if (p[k] != (unsigned char)(1 + t * 37 + i % 5)) {
                    overwritten++;
                    break;
                }
        }
    CHECK(missing == 0, "%zu blocks refused", missing);
    CHECK(bad_align == 0, "%zu blocks not %d-byte aligned", bad_align, BUMP_ARENA_ALIGN);
    CHECK(overwritten == 0, "%zu blocks overwritten by another's", overwritten);
    size_t counted = bump_arena_bytes(a);
    CHECK(counted >= total && counted < total + 64 * (size_t)(2u << 20) / 8,
          "arena counts %zu bytes for %zu handed out", counted, total);
    int hints = atomic_load(&arena_hints);
    CHECK(hints >= 2 && (size_t)hints == (counted + (2u << 20) - 1) / (2u << 20) && atomic_load(&arena_hint_bad) == 0,
          "%d hints (%d with a wrong chunk) for %zu bytes of 2 MiB chunks", hints, atomic_load(&arena_hint_bad),
          counted);
    CHECK(bump_arena_on_huge_pages(a) == 1, "every chunk's hint said huge pages, the arena says not");
    bump_arena_free(a);
    /* One chunk's hint refused: the arena is no longer on huge pages. */
    atomic_store(&arena_hints, 0), arena_hint_refuse = 2;
    a = bump_arena_new(2u << 20, arena_hint);
    CHECK(a && bump_arena_on_huge_pages(a) == 1, "a new arena with a hint: not on huge pages");
    for (int i = 0; a && i < 3; i++) CHECK(bump_arena_alloc(a, 2u << 20) != NULL, "a whole chunk refused");
    CHECK(a && atomic_load(&arena_hints) == 3 && bump_arena_on_huge_pages(a) == 0,
          "%d hints, the second refused: on huge pages %d", atomic_load(&arena_hints), a ? bump_arena_on_huge_pages(a) : -1);
    bump_arena_free(a);
    a = bump_arena_new(2u << 20, NULL);
    CHECK(a && bump_arena_alloc(a, 64) && bump_arena_on_huge_pages(a) == 0, "an arena without a hint on huge pages");
    bump_arena_free(a);
}

/* Every triangle's prim_info as shading looks it up (scene_triangle_info:
 * the runs of scene.info_runs) equals triangle_info's, on the shipped
 * scenes, the icospheres, 40 emitting quads (80 lights in a row: one
 * run) and 80 quads of alternating materials (more runs than
 * SCENE_INFO_RUNS_MAX: none kept, the array read). */
TEST(mesh_triangle_info_runs_give_every_triangles_info) {
    static const char *const paths[] = {"scenes/cornell-box.json", "scenes/cornell-phong.json", "scenes/features.json",
                                        "scenes/cornell-spheres.json", ICO_SCENE};
    scene *sc[7] = {NULL};
    char err[512];
    for (size_t p = 0; p < 5; p++) {
        sc[p] = scene_load(paths[p], NULL, err, sizeof err);
        CHECK(sc[p] != NULL, "%s", err);
    }
    for (int alternate = 0; alternate < 2; alternate++) {
        size_t cap = 64 * 1024, len = 0;
        char *json = malloc(cap);
        if (!json) break;
        len += (size_t)snprintf(json + len, cap - len,
                                "{\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -50], \"look_at\": [0, 0, 0],"
                                " \"fov\": 40}, \"materials\": {\"a\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]},"
                                " \"b\": {\"type\": \"diffuse\", \"albedo\": [0.2, 0.5, 0.5]}}, \"shapes\": [");
        int quads = alternate ? 80 : 40;
        for (int q = 0; q < quads; q++)
            len += (size_t)snprintf(json + len, cap - len,
                                    "%s{\"type\": \"quad\", \"vertices\": [[%d, 0, 0], [%d, 0, 0], [%d, 1, 0], [%d, 1, 0]], %s}",
                                    q ? ", " : "", q, q + 1, q + 1, q,
                                    alternate ? (q % 2 ? "\"material\": \"a\"" : "\"material\": \"b\"")
                                              : "\"material\": \"a\", \"emission\": [1, 1, 1]");
        snprintf(json + len, cap - len, "]}");
        sc[5 + alternate] = util_scene_from_text(json, err, sizeof err);
        CHECK(sc[5 + alternate] != NULL, "%s", err);
        free(json);
    }
    for (size_t p = 0; p < 7; p++) {
        const scene *s = sc[p];
        if (!s) continue;
        uint32_t wrong = 0;
        for (uint32_t k = 0; k < s->triangle_count; k++) {
            prim_info a = scene_triangle_info(s, k), b = s->triangle_info[k];
            wrong += a.material != b.material || a.light != b.light;
        }
        CHECK(wrong == 0, "scene %zu: %u of %u triangles' info differ from the runs'", p, wrong, s->triangle_count);
    }
    CHECK(sc[0] && sc[0]->info_run_count > 1 && sc[0]->info_run_count < 16, "the box: %u runs",
          sc[0] ? sc[0]->info_run_count : 0);
    CHECK(sc[5] && sc[5]->light_count == 80 && sc[5]->info_run_count == 1, "80 emitting triangles: %u lights, %u runs",
          sc[5] ? sc[5]->light_count : 0, sc[5] ? sc[5]->info_run_count : 0);
    CHECK(sc[6] && sc[6]->info_run_count == 0 && !sc[6]->info_runs, "80 alternating quads: %u runs kept",
          sc[6] ? sc[6]->info_run_count : 0);
    for (size_t p = 0; p < 7; p++) scene_free(sc[p]);
}

/* ---- the wide tree's quality, counted (make walk-count) ---- */

/* One walk-count round's counts, from its "walks W, node tests N (...),
 * leaf tests L (...)" line. */
typedef struct {
    unsigned long long walks, nodes, leaves;
} walk_counts;

/* The counts of round `round` (1-based) in walk-count's output out into
 * *c. Returns 0 (and zero counts) when that round's line is missing. */
static int parse_walk_counts(const char *out, int round, walk_counts *c) {
    char key[64];
    snprintf(key, sizeof key, "round %d wide    walks ", round);
    const char *p = strstr(out, key);
    memset(c, 0, sizeof *c);
    return p && sscanf(p + strlen(key), "%llu, node tests %llu (%*[^)]), leaf tests %llu", &c->walks, &c->nodes,
                       &c->leaves) == 3;
}

/* walk-count (the binary beside the tessera under test, built by make test
 * and make test-asan) over ICO_SCENE's wide tree: two rounds count the same
 * (the counts depend on the tree and the rays alone) and make the same
 * picture, every walk tests at least the root (a node, not a leaf), and the
 * SAH tree stays within 10% of the node and leaf tests per walk it takes
 * since its nodes hold up to 16 children (thirty-second session: 1.360
 * and 2.036 for the 8-lane walks' leaves of 8, 1.456 and 2.197 for the SSE
 * walk's leaves of 4; with 8 children a node, 1.599 and 2.031, 1.884 and
 * 2.037), so a change that makes the builder's trees worse fails here
 * although every answer stays right. The Morton-built tree of the same
 * scene (4.43 node tests per walk) must count more node tests than the
 * SAH tree: the counters see the difference between two trees. */
TEST(mesh_walk_count_bounds_the_wide_tree_quality) {
    char bin[PATH_MAX], cmd[2 * PATH_MAX], out[8192];
    snprintf(bin, sizeof bin, "%s", harness_tessera());
    char *slash = strrchr(bin, '/');
    snprintf(slash ? slash + 1 : bin, sizeof bin - (size_t)(slash ? slash + 1 - bin : 0), "walk-count");
    CHECK(access(bin, X_OK) == 0, "%s: not built (make test builds it)", bin);
    if (access(bin, X_OK) != 0) return;
    const char *args = " " ICO_SCENE " --width 32 --height 32 --spp 4 --rounds 2 wide";
    snprintf(cmd, sizeof cmd, "env -u TESSERA_WIDE_BUILDER %s%s", bin, args);
    int rc = util_run(cmd, out, sizeof out);
    walk_counts sah[2], morton;
    int parsed = parse_walk_counts(out, 1, &sah[0]) & parse_walk_counts(out, 2, &sah[1]);
    CHECK(rc == 0 && parsed, "%s (%d): %s", cmd, rc, out);
    if (rc != 0 || !parsed) return;
    CHECK(!strstr(out, "PICTURE DIFFERS"), "%s: the second round's picture is not the first's: %s", cmd, out);
    CHECK(sah[0].walks == sah[1].walks && sah[0].nodes == sah[1].nodes && sah[0].leaves == sah[1].leaves,
          "two rounds counted differently: walks %llu/%llu, nodes %llu/%llu, leaves %llu/%llu", sah[0].walks,
          sah[1].walks, sah[0].nodes, sah[1].nodes, sah[0].leaves, sah[1].leaves);
    CHECK(sah[0].walks > 4096 && sah[0].nodes >= sah[0].walks && sah[0].leaves > 0,
          "implausible counts: %llu walks for 4096 samples, %llu node tests, %llu leaf tests", sah[0].walks,
          sah[0].nodes, sah[0].leaves);
    int sse = strstr(out, "sse2 walk") != NULL;
    double nodes = (double)sah[0].nodes / (double)(sah[0].walks ? sah[0].walks : 1);
    double leaves = (double)sah[0].leaves / (double)(sah[0].walks ? sah[0].walks : 1);
    double max_nodes = 1.10 * (sse ? 1.456 : 1.360), max_leaves = 1.10 * (sse ? 2.197 : 2.036);
    CHECK(nodes <= max_nodes && leaves <= max_leaves,
          "the SAH tree's walks got worse: %.3f node tests per walk (at most %.3f), %.3f leaf tests (at most %.3f)", nodes,
          max_nodes, leaves, max_leaves);

    snprintf(cmd, sizeof cmd, "TESSERA_WIDE_BUILDER=morton %s%s", bin, args);
    rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 0 && parse_walk_counts(out, 1, &morton), "%s (%d): %s", cmd, rc, out);
    CHECK(morton.walks == sah[0].walks && morton.nodes > sah[0].nodes,
          "Morton tree: %llu walks (SAH %llu), %llu node tests (SAH %llu): the counters do not tell the trees apart",
          morton.walks, sah[0].walks, morton.nodes, sah[0].nodes);
}

/* ---- spare memory for the tree's arena (bump_arena_take_spare) ---- */

/* Spare blocks become an arena's first chunks, whole and zeroed, in the
 * order given, before any chunk is mapped: a 3 MiB block filled with 0xab
 * and a 1 MiB one, then fresh 2 MiB chunks. The arena frees the blocks
 * (ASan's leak check in make test-asan fails otherwise); a spare nobody
 * takes frees its own; an arena takes no more than max_bytes. */
TEST(mesh_bump_arena_takes_spare_blocks_first) {
    size_t big = 3u << 20, small = 1u << 20;
    unsigned char *b1 = malloc(big), *b2 = malloc(small);
    CHECK(b1 && b2, "out of memory");
    if (!b1 || !b2) return free(b1), free(b2);
    memset(b1, 0xab, big);
    memset(b2, 0xcd, small);
    bump_spare *sp = NULL;
    bump_spare_add(&sp, b1, big);
    bump_spare_add(&sp, b2, small);
    CHECK(bump_spare_bytes(sp) == big + small, "the spare holds %zu bytes, not %zu", bump_spare_bytes(sp), big + small);
    bump_arena *a = bump_arena_new(2u << 20, NULL);
    CHECK(a != NULL, "bump_arena_new failed");
    if (!a) return bump_spare_free(sp);
    bump_arena_take_spare(a, sp, SIZE_MAX);
    CHECK(bump_spare_bytes(sp) == 0, "the spare still holds %zu bytes after the arena took them", bump_spare_bytes(sp));
    bump_spare_free(sp);
    size_t in_b1 = 0, in_b2 = 0, elsewhere = 0, not_zero = 0, order_bad = 0, bad_align = 0;
    int phase = 0; /* 0: b1, 1: b2, 2: mapped */
    for (int i = 0; i < 200; i++) {
        unsigned char *p = bump_arena_alloc(a, 64 * 1024);
        CHECK(p != NULL, "allocation %d refused", i);
        if (!p) break;
        if ((uintptr_t)p % BUMP_ARENA_ALIGN) bad_align++;
        int where = p >= b1 && p + 64 * 1024 <= b1 + big ? 0 : p >= b2 && p + 64 * 1024 <= b2 + small ? 1 : 2;
        if (where < phase) order_bad++;
        phase = where;
        in_b1 += where == 0, in_b2 += where == 1, elsewhere += where == 2;
        for (size_t k = 0; k < 64 * 1024; k += 4096)
            if (p[k]) not_zero++;
        memset(p, 0x11, 64 * 1024);
    }
    /* 3 MiB less the block's alignment to 64 bytes: 47 or 48 blocks. */
    CHECK(in_b1 >= 47 && in_b1 <= 48 && in_b2 >= 15 && in_b2 <= 16 && elsewhere == 200 - in_b1 - in_b2,
          "blocks: %zu in the first spare block, %zu in the second, %zu mapped", in_b1, in_b2, elsewhere);
    CHECK(order_bad == 0, "%zu blocks came from a chunk before the one already in use", order_bad);
    CHECK(not_zero == 0 && bad_align == 0, "%zu blocks not zeroed, %zu misaligned", not_zero, bad_align);
    CHECK(bump_arena_on_huge_pages(a) == 0, "an arena with spare chunks claims huge pages");
    bump_arena_free(a);

    unsigned char *b3 = malloc(small);
    CHECK(b3 != NULL, "out of memory");
    bump_spare *left = NULL;
    bump_spare_add(&left, b3, small);
    bump_spare_free(left); /* frees b3 */

    /* At most max_bytes taken: the first block only, the second freed at
     * once (ASan's leak check sees it otherwise). */
    unsigned char *b4 = malloc(small), *b5 = malloc(small);
    CHECK(b4 && b5, "out of memory");
    bump_spare *two = NULL;
    bump_spare_add(&two, b4, small);
    bump_spare_add(&two, b5, small);
    bump_arena *a2 = bump_arena_new(2u << 20, NULL);
    CHECK(a2 != NULL, "bump_arena_new failed");
    if (!a2) return bump_spare_free(two);
    bump_arena_take_spare(a2, two, 1);
    bump_spare_free(two);
    size_t in_b4 = 0;
    for (int i = 0; i < 20; i++) {
        unsigned char *p = bump_arena_alloc(a2, 64 * 1024);
        in_b4 += p && p >= b4 && p + 64 * 1024 <= b4 + small;
    }
    CHECK(in_b4 >= 15 && in_b4 <= 16, "%zu of 20 blocks in the one spare block taken (15 or 16 expected)", in_b4);
    bump_arena_free(a2);
}

/* The loader's freed buffers as the wide tree's chunks
 * (TESSERA_ARENA_SPARE_MIN low enough for ICO_SCENE's few KiB; a short
 * render, 8x8x1 against 2,573 primitives): -v says they were offered, and
 * the picture is the one without them (TESSERA_ARENA_SPARE=0), in process
 * and on a local farm of forked workers. A long render offers none. */
TEST(mesh_spare_buffers_give_the_same_picture) {
    char ref[512], img[512], cmd[2048], out[8192];
    snprintf(ref, sizeof ref, "%s", util_temp_path("spare-ref.pfm"));
    snprintf(img, sizeof img, "%s", util_temp_path("spare.pfm"));
    const char *const runs[] = {"--workers 0", "--workers 2"};
    for (int k = 0; k < 2; k++) {
        snprintf(cmd, sizeof cmd,
                 "TESSERA_ARENA_SPARE=0 %s render " ICO_SCENE " %s --width 8 --height 8 --spp 1 --no-progress -v -o %s",
                 harness_tessera(), runs[k], ref);
        int rc = util_run(cmd, out, sizeof out);
        CHECK(rc == 0 && !strstr(out, "freed buffers offered"), "%s (%d): %s", cmd, rc, out);
        snprintf(cmd, sizeof cmd,
                 "TESSERA_ARENA_SPARE_MIN=1 %s render " ICO_SCENE " %s --width 8 --height 8 --spp 1 --no-progress -v -o %s",
                 harness_tessera(), runs[k], img);
        rc = util_run(cmd, out, sizeof out);
        CHECK(rc == 0 && (k == 1 || strstr(out, "freed buffers offered")), "%s (%d): no spare offered: %s", cmd, rc,
              out);
        CHECK(util_same_file(img, ref), "%s: the picture differs from the one without spare buffers", cmd);
    }
    snprintf(cmd, sizeof cmd,
             "TESSERA_ARENA_SPARE_MIN=1 %s render " ICO_SCENE " --workers 0 --width 32 --height 32 --spp 4 --no-progress "
             "-v -o %s",
             harness_tessera(), img);
    int rc = util_run(cmd, out, sizeof out);
    CHECK(rc == 0 && !strstr(out, "freed buffers offered"), "a long render offered spare buffers: %s (%d): %s", cmd,
          rc, out);
}
