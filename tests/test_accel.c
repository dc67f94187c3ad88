/* test_accel.c - the flat intersector against the BVH: the same hits, bit
 * for bit, on random rays, on rays leaving surfaces and on rays aimed at
 * shared edges and vertices; the automatic choice; and identical images. */
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>

#include "render/accel.h"
#include "render/rng.h"
#include "render/scene.h"
#include "harness.h"
#include "util.h"

static float uniform(rng_stream *r) { return rng_next(r); }

static vec3 random_direction(rng_stream *r) {
    float z = 1.0f - 2.0f * uniform(r), phi = 6.2831853f * uniform(r), s = sqrtf(fmaxf(0.0f, 1.0f - z * z));
    return vec3_make(s * cosf(phi), s * sinf(phi), z);
}

/* Cast ray r through both intersectors and compare everything they say.
 * Returns 1 if they agree; describes the difference in why otherwise. Two
 * primitives hit at the same point up to rounding (a ray through a shared
 * edge or vertex) are a tie that either may win, depending on which was
 * tested first: counted in *ties. */
static int same_answers(const scene *s, const accel *flat, const accel *tree, const ray *r, float tmax, char *why,
                        size_t why_len, int *ties) {
    hit a, b;
    int ha = accel_intersect(flat, s, r, tmax, &a), hb = accel_intersect(tree, s, r, tmax, &b);
    if (ha != hb) return snprintf(why, why_len, "flat %s, bvh %s", ha ? "hit" : "missed", hb ? "hit" : "missed"), 0;
    if (ha && a.prim != b.prim && fabsf(a.t - b.t) <= 1e-6f * a.t) {
        (*ties)++;
        b = a;
    }
    if (ha && (a.prim != b.prim || memcmp(&a.t, &b.t, sizeof a.t) || memcmp(&a.b1, &b.b1, sizeof a.b1) ||
               memcmp(&a.b2, &b.b2, sizeof a.b2)))
        return snprintf(why, why_len, "flat prim %u t %.9g, bvh prim %u t %.9g", a.prim, a.t, b.prim, b.t), 0;
    int oa = accel_occluded(flat, s, r, tmax), ob = accel_occluded(tree, s, r, tmax);
    if (oa != ob || oa != ha) return snprintf(why, why_len, "occluded: flat %d, bvh %d, hit %d", oa, ob, ha), 0;
    return 1;
}

static void compare_on_scene(const char *path) {
    char err[512], why[256];
    scene *s = scene_load(path, NULL, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    accel *flat = accel_build(s, ACCEL_FLAT), *tree = accel_build(s, ACCEL_BVH);
    CHECK(flat && tree && accel_get_kind(flat) == ACCEL_FLAT && accel_get_kind(tree) == ACCEL_BVH, "build");
    int failures = 0, hits = 0, ties = 0, aimed = 0;
    for (uint64_t i = 0; i < 200000 && failures < 5 && flat && tree; i++) {
        rng_stream rng = rng_stream_start(11, i, 0);
        ray r;
        float tmax = INFINITY;
        if (i % 3 == 0 && s->triangle_count) { /* leaving a triangle, as a bounce does */
            uint32_t t = (uint32_t)(uniform(&rng) * (float)s->triangle_count) % s->triangle_count;
            float b1 = uniform(&rng), b2 = uniform(&rng) * (1 - b1);
            const triangle *tr = &s->triangles[t];
            vec3 p = vec3_add(tr->v0, vec3_add(vec3_scale(vec3_sub(tr->v1, tr->v0), b1),
                                               vec3_scale(vec3_sub(tr->v2, tr->v0), b2)));
            r = (ray){p, random_direction(&rng), t};
        } else if (i % 3 == 1 && s->triangle_count) { /* at a vertex or an edge point of some triangle */
            uint32_t t = (uint32_t)(uniform(&rng) * (float)s->triangle_count) % s->triangle_count;
            const triangle *tr = &s->triangles[t];
            vec3 target = (i / 3) % 2 ? tr->v1 : vec3_scale(vec3_add(tr->v0, tr->v2), 0.5f);
            vec3 o = vec3_scale(random_direction(&rng), 0.3f);
            r = (ray){o, vec3_normalize(vec3_sub(target, o)), PRIM_NONE};
            aimed++;
        } else {
            r = (ray){vec3_scale(random_direction(&rng), 1.5f * uniform(&rng)), random_direction(&rng), PRIM_NONE};
            if (i % 2) tmax = 2.0f * uniform(&rng);
        }
        if (!same_answers(s, flat, tree, &r, tmax, why, sizeof why, &ties)) {
            failures++;
            CHECK(0, "%s ray %llu: %s", path, (unsigned long long)i, why);
        }
        hit h;
        hits += accel_intersect(flat, s, &r, tmax, &h);
    }
    CHECK(ties < aimed / 2, "%s: %d ties in %d rays aimed at edges and vertices", path, ties, aimed);
    CHECK(hits > 50000, "%s: only %d of 200000 rays hit anything (test rays not aimed at the scene?)", path, hits);
    accel_free(flat);
    accel_free(tree);
    scene_free(s);
}

TEST(accel_flat_matches_bvh_cornell_box) { compare_on_scene("scenes/cornell-box.json"); }
TEST(accel_flat_matches_bvh_spheres_and_mesh) { compare_on_scene("scenes/features.json"); }

/* AUTO: flat up to ACCEL_FLAT_MAX_TRIANGLES triangles, a tree above; the
 * scene file can insist on either, and a wrong name is an error naming the
 * field. */
TEST(accel_choice_follows_scene) {
    char err[512];
    scene *s = scene_load("scenes/cornell-box.json", NULL, err, sizeof err);
    CHECK(s && accel_get_kind(s->accel) == ACCEL_FLAT, "cornell box (32 triangles) should be flat");
    scene_free(s);
    char json[32768] = "{\"render\": {\"accel\": \"bvh\"}, \"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -5], \"look_at\": [0, 0, 0], \"fov\": 40},"
                      " \"materials\": {\"m\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}}, \"shapes\": [";
    for (int i = 0; i <= ACCEL_FLAT_MAX_TRIANGLES; i++)
        snprintf(json + strlen(json), sizeof json - strlen(json),
                 "%s{\"type\": \"triangle\", \"vertices\": [[%d, 0, 0], [%d, 1, 0], [%d.5, 0, 1]], \"material\": \"m\"}",
                 i ? "," : "", i, i, i);
    strcat(json, "]}");
    s = util_scene_from_text(json, err, sizeof err);
    CHECK(s && accel_get_kind(s->accel) == ACCEL_BVH, "render.accel = bvh ignored: %s", s ? "" : err);
    scene_free(s);
    char *auto_json = malloc(strlen(json) + 64); /* json with another render.accel */
    sprintf(auto_json, "{\"render\": {\"accel\": \"auto\"}%s", strchr(json, ','));
    s = util_scene_from_text(auto_json, err, sizeof err);
    CHECK(s && accel_get_kind(s->accel) == ACCEL_BVH, "%d triangles should get a BVH: %s",
          ACCEL_FLAT_MAX_TRIANGLES + 1, s ? "" : err);
    scene_free(s);
    sprintf(auto_json, "{\"render\": {\"accel\": \"kd-tree\"}%s", strchr(json, ','));
    s = util_scene_from_text(auto_json, err, sizeof err);
    CHECK(!s && strstr(err, "render.accel") && strstr(err, "kd-tree"), "bad accel accepted or unclear: %s", err);
    scene_free(s);
    free(auto_json);
}

/* The whole point of determinism across machines: the Cornell box rendered
 * through either intersector is the same image, bit for bit (it has no two
 * surfaces at exactly the same distance along any ray). */
TEST(accel_flat_and_bvh_render_the_same_image) {
    char err[512];
    scene *s = scene_load("scenes/cornell-box.json", NULL, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    s->settings.width = s->settings.height = 48;
    trace_stats st;
    accel_free(s->accel);
    s->accel = accel_build(s, ACCEL_BVH);
    float *tree = util_render(s, 4, 16, 1, &st);
    /* Every flat kernel width this CPU runs (16, 8, 4 lanes), forced down
     * by the environment, against the tree. */
    const char *caps[3] = {NULL, "TESSERA_NO_AVX512", "TESSERA_NO_AVX2"};
    for (int w = 0; w < 3; w++) {
        if (caps[w]) setenv(caps[w], "1", 1);
        accel_free(s->accel);
        s->accel = accel_build(s, ACCEL_FLAT);
        if (caps[w]) unsetenv(caps[w]);
        float *flat = util_render(s, 4, 16, 1, &st);
        CHECK(flat && tree && memcmp(flat, tree, 48 * 48 * 3 * sizeof(float)) == 0,
              "images differ (flat kernel of %d lanes against the BVH)", accel_flat_lanes(s->accel));
        free(flat);
    }
    free(tree);
    scene_free(s);
}

/* The 4-lane (SSE), 8-lane (AVX2) and 16-lane (AVX-512F) kernels, each
 * where the CPU has it, return the same hit, bit for bit, on every ray, for
 * closest and any hit: all equal the scalar loop over the triangles in index
 * order, so machines with and without AVX2 or AVX-512 make the same image. */
static void widths_agree_on(const char *path) {
    char err[512];
    scene *s = scene_load(path, NULL, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (!s) return;
    accel *k16 = accel_build(s, ACCEL_FLAT);
    setenv("TESSERA_NO_AVX512", "1", 1);
    accel *k8 = accel_build(s, ACCEL_FLAT);
    unsetenv("TESSERA_NO_AVX512");
    setenv("TESSERA_NO_AVX2", "1", 1);
    accel *k4 = accel_build(s, ACCEL_FLAT);
    unsetenv("TESSERA_NO_AVX2");
    CHECK(k16 && k8 && k4 && accel_flat_lanes(k4) == 4 && accel_flat_lanes(k8) <= 8, "widths not forced");
    fprintf(stderr, "  (%s: kernel widths compared: %d, %d, %d lanes)\n", path, accel_flat_lanes(k16),
            accel_flat_lanes(k8), accel_flat_lanes(k4));
    int differ = 0;
    for (uint64_t i = 0; i < 100000 && k16 && k8 && k4; i++) {
        rng_stream rng = rng_stream_start(5, i, 1);
        ray r = {vec3_scale(random_direction(&rng), 1.2f * uniform(&rng)), random_direction(&rng), PRIM_NONE};
        float tmax = i % 2 ? INFINITY : 2.0f * uniform(&rng);
        hit h[3];
        accel *k[3] = {k16, k8, k4};
        int got[3], any[3];
        for (int w = 0; w < 3; w++) {
            got[w] = accel_intersect(k[w], s, &r, tmax, &h[w]);
            any[w] = accel_occluded(k[w], s, &r, tmax);
        }
        for (int w = 1; w < 3; w++)
            if (got[w] != got[0] || any[w] != any[0] ||
                (got[0] && (h[w].prim != h[0].prim || memcmp(&h[w].t, &h[0].t, 4) || memcmp(&h[w].b1, &h[0].b1, 4) ||
                            memcmp(&h[w].b2, &h[0].b2, 4))))
                differ++;
    }
    CHECK(differ == 0, "%s: %d of 2 x 100000 ray comparisons differ between the kernel widths", path, differ);
    accel_free(k16);
    accel_free(k8);
    accel_free(k4);
    scene_free(s);
}

/* On 9 triangles with spheres (one group of 16, half padding) and on the
 * Cornell box's 32 (two full groups). */
TEST(accel_flat_kernel_widths_agree) {
    widths_agree_on("scenes/features.json");
    widths_agree_on("scenes/cornell-box.json");
}

/* The whole program under qemu emulating a Nehalem (SSE4.2, no AVX): the
 * flat intersector takes its 4-lane kernel there and the widest this CPU
 * has (16 lanes with AVX-512) natively, and the Cornell box is the same
 * bytes. Fails without qemu-x86_64 (unless TESSERA_TESTS_WITHOUT_QEMU, see
 * util_have_qemu); skipped under the sanitizers (their runtimes do not run
 * under qemu-user). */
TEST(accel_flat_same_image_under_qemu_nehalem) {
#if defined(__SANITIZE_ADDRESS__) || defined(__SANITIZE_THREAD__)
    return;
#else
    if (!util_have_qemu()) return;
    char out[8192];
    const char *args = "render scenes/cornell-box.json --workers 0 --threads 2 --width 64 --spp 4 --no-progress -v";
    int rc = util_same_under_nehalem(harness_tessera(), args, "box", out, sizeof out);
    CHECK(rc == 0, "%s", out);
    CHECK(rc != 0 || strstr(out, "4 at a time"), "under qemu (Nehalem) the flat kernel did not take 4 lanes: %s", out);
#endif
}
