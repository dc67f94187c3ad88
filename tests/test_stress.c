/* test_stress.c - numerical stress (`make stress` runs these alone): scenes
 * built to break a renderer - extreme radiances, tiny spheres, a camera
 * inside a closed box, coincident and edge-on surfaces, slivers - must
 * give finite, non-negative pixels with no NaN/Inf sample, and
 * energy-conserving materials must pass a furnace in a uniform sky. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include <cjson/cJSON.h>

#include "fileio.h"
#include "harness.h"
#include "util.h"

#define CAM "\"camera\": {\"type\": \"perspective\", \"position\": [0, 0.5, -3], \"look_at\": [0, 0.5, 0], \"fov\": 50}"

typedef struct {
    double mean, min, max;
    int bad; /* non-finite or negative values */
} pixel_stats;

/* Render json at w x h, spp; check finiteness and the NaN/Inf counter. */
static float *render_checked(const char *name, const char *json, int w, int h, int spp, pixel_stats *ps) {
    char err[1024], full[8192];
    snprintf(full, sizeof full, "{\"render\": {\"width\": %d, \"height\": %d, \"spp\": %d, \"max_depth\": 64, \"seed\": 11}, %s}",
             w, h, spp, json);
    scene *s = util_scene_from_text(full, err, sizeof err);
    CHECK(s != NULL, "%s: %s", name, err);
    if (!s) return NULL;
    trace_stats st;
    float *rgb = util_render(s, 2, 8, 1, &st);
    scene_free(s);
    memset(ps, 0, sizeof *ps);
    ps->min = INFINITY;
    ps->max = -INFINITY;
    for (int i = 0; rgb && i < w * h * 3; i++) {
        double v = rgb[i];
        if (!isfinite(v) || v < 0) ps->bad++;
        ps->mean += v / (w * h * 3);
        ps->min = fmin(ps->min, v);
        ps->max = fmax(ps->max, v);
    }
    CHECK(rgb && ps->bad == 0, "%s: %d non-finite or negative values", name, ps->bad);
    CHECK(st.bad_samples == 0, "%s: %llu NaN/Inf samples", name, (unsigned long long)st.bad_samples);
    return rgb;
}

static const char *box(double emission) {
    static char json[4096];
    snprintf(json, sizeof json,
             "\"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.7, 0.7, 0.7]}},"
             " \"shapes\": ["
             "{\"type\": \"quad\", \"vertices\": [[-1,0,-1],[-1,0,1],[1,0,1],[1,0,-1]], \"material\": \"w\"},"
             "{\"type\": \"quad\", \"vertices\": [[-1,2,-1],[1,2,-1],[1,2,1],[-1,2,1]], \"material\": \"w\"},"
             "{\"type\": \"quad\", \"vertices\": [[-1,0,1],[-1,2,1],[1,2,1],[1,0,1]], \"material\": \"w\"},"
             "{\"type\": \"quad\", \"vertices\": [[-1,0,-1],[-1,2,-1],[-1,2,1],[-1,0,1]], \"material\": \"w\"},"
             "{\"type\": \"quad\", \"vertices\": [[1,0,-1],[1,0,1],[1,2,1],[1,2,-1]], \"material\": \"w\"},"
             "{\"type\": \"quad\", \"vertices\": [[-1,0,-1],[1,0,-1],[1,2,-1],[-1,2,-1]], \"material\": \"w\"},"
             "{\"type\": \"quad\", \"vertices\": [[-0.2,1.99,-0.2],[0.2,1.99,-0.2],[0.2,1.99,0.2],[-0.2,1.99,0.2]],"
             " \"emission\": [%g, %g, %g]}]",
             emission, emission, emission);
    return json;
}

TEST(stress_camera_inside_a_closed_box_and_extreme_lights) {
    pixel_stats a, b, c;
    char json[8192];
    /* The camera sits inside a closed box lit from the ceiling. */
    snprintf(json, sizeof json,
             "\"camera\": {\"type\": \"perspective\", \"position\": [0, 1, -0.5], \"look_at\": [0, 1, 1], \"fov\": 60}, %s",
             box(1));
    float *one = render_checked("box, radiance 1", json, 16, 16, 64, &a);
    CHECK(a.mean > 0.01, "the inside of the box is black (mean %g)", a.mean);
    /* Radiance 1e20 and 1e-20: the same paths, so the same picture scaled. */
    snprintf(json, sizeof json,
             "\"camera\": {\"type\": \"perspective\", \"position\": [0, 1, -0.5], \"look_at\": [0, 1, 1], \"fov\": 60}, %s",
             box(1e20));
    float *big = render_checked("box, radiance 1e20", json, 16, 16, 64, &b);
    snprintf(json, sizeof json,
             "\"camera\": {\"type\": \"perspective\", \"position\": [0, 1, -0.5], \"look_at\": [0, 1, 1], \"fov\": 60}, %s",
             box(1e-20));
    float *tiny = render_checked("box, radiance 1e-20", json, 16, 16, 64, &c);
    double worst = 0;
    for (int i = 0; one && big && tiny && i < 16 * 16 * 3; i++) {
        if (one[i] <= 1e-6f) continue;
        worst = fmax(worst, fabs(big[i] / 1e20 - one[i]) / one[i]);
        worst = fmax(worst, fabs(tiny[i] / 1e-20 - one[i]) / one[i]);
    }
    CHECK(worst < 1e-4, "scaling the light by 1e20 or 1e-20 does not scale the picture (worst %.3g)", worst);
    free(one);
    free(big);
    free(tiny);
}

TEST(stress_tiny_sphere_coincident_and_edge_on_surfaces) {
    pixel_stats p;
    char json[4096];
    /* A sphere of radius 1e-6 (lit, and as the only light) next to a unit
     * floor: the scene spans six orders of magnitude. */
    snprintf(json, sizeof json,
             CAM ", \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
             " \"shapes\": [{\"type\": \"quad\", \"vertices\": [[-1,0,-1],[-1,0,1],[1,0,1],[1,0,-1]], \"material\": \"w\"},"
             " {\"type\": \"sphere\", \"center\": [0, 0.5, 0], \"radius\": 1e-6, \"emission\": [1e12, 1e12, 1e12]},"
             " {\"type\": \"sphere\", \"center\": [0.3, 0.3, 0], \"radius\": 1e-6, \"material\": \"w\"}]");
    free(render_checked("sphere of radius 1e-6", json, 16, 16, 32, &p));
    CHECK(p.mean > 0, "the tiny light lights nothing");
    /* Two coincident quads with different materials, and the camera in the
     * plane of a third (every primary ray grazes it edge-on). */
    snprintf(json, sizeof json,
             "\"camera\": {\"type\": \"perspective\", \"position\": [0, 0, -3], \"look_at\": [0, 0, 0], \"fov\": 50},"
             " \"background\": [0.2, 0.2, 0.2],"
             " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]},"
             "  \"m\": {\"type\": \"mirror\", \"reflectance\": [0.9, 0.9, 0.9]},"
             "  \"g\": {\"type\": \"glass\", \"ior\": 1.5, \"transmission\": [1, 1, 1]}},"
             " \"shapes\": [{\"type\": \"quad\", \"vertices\": [[-1,-1,1],[1,-1,1],[1,1,1],[-1,1,1]], \"material\": \"w\"},"
             " {\"type\": \"quad\", \"vertices\": [[-1,-1,1],[1,-1,1],[1,1,1],[-1,1,1]], \"material\": \"m\"},"
             " {\"type\": \"quad\", \"vertices\": [[-1,0,-1],[-1,0,1],[1,0,1],[1,0,-1]], \"material\": \"g\"},"
             " {\"type\": \"sphere\", \"center\": [0, 0.5, 0], \"radius\": 0.2, \"material\": \"g\"},"
             " {\"type\": \"quad\", \"vertices\": [[-0.3,1.5,-0.3],[0.3,1.5,-0.3],[0.3,1.5,0.3],[-0.3,1.5,0.3]],"
             " \"emission\": [5, 5, 5], \"two_sided\": true}]");
    free(render_checked("coincident and edge-on surfaces", json, 16, 16, 32, &p));
}

TEST(stress_sliver_triangles_in_a_mesh) {
    /* Slivers (1e-9 wide) and a fan of triangles meeting at one vertex. */
    util_write_temp("slivers.obj", "v 0 0 0\nv 1 0 0\nv 0.5 1e-9 0\nv 0 1 0\nv 1 1 0\nv 0.5 0.5 1e-9\n"
                                   "f 1 2 3\nf 1 2 6\nf 2 5 6\nf 5 4 6\nf 4 1 6\nf 1 3 2\n");
    char json[2048];
    snprintf(json, sizeof json,
             "\"camera\": {\"type\": \"perspective\", \"position\": [0.5, 0.5, -2], \"look_at\": [0.5, 0.5, 0], \"fov\": 40},"
             " \"background\": [0.5, 0.5, 0.5],"
             " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.6, 0.6, 0.6]}},"
             " \"shapes\": [{\"type\": \"mesh\", \"file\": \"slivers.obj\", \"material\": \"w\"}]");
    pixel_stats p;
    free(render_checked("sliver triangles", json, 16, 16, 32, &p));
    CHECK(p.mean > 0, "slivers: black image");
}

/* A sphere of material m in a uniform sky of radiance 1 seen by an
 * environment camera from outside: a material that conserves energy leaves
 * every pixel at 1 (on average over its samples). Returns the mean. */
static double sky_furnace(const char *material, int spp, double *worst_pixel) {
    char json[2048];
    snprintf(json, sizeof json,
             "\"camera\": {\"type\": \"environment\", \"position\": [0, 0, -1.05]}, \"background\": [1, 1, 1],"
             " \"materials\": {\"m\": %s},"
             " \"shapes\": [{\"type\": \"sphere\", \"center\": [0, 0, 0], \"radius\": 1, \"material\": \"m\"}]",
             material);
    pixel_stats p;
    float *rgb = render_checked(material, json, 16, 8, spp, &p);
    *worst_pixel = 0;
    for (int i = 0; rgb && i < 16 * 8 * 3; i++) *worst_pixel = fmax(*worst_pixel, fabs(rgb[i] - 1.0));
    free(rgb);
    return p.mean;
}

TEST(stress_furnace_for_energy_conserving_materials) {
    double worst;
    /* Control: a black sphere must show, or the furnace proves nothing. */
    double m = sky_furnace("{\"type\": \"diffuse\", \"albedo\": [0, 0, 0]}", 4, &worst);
    CHECK(m < 0.8, "a black sphere covers too little of the view (mean %g)", m);
    m = sky_furnace("{\"type\": \"mirror\", \"reflectance\": [1, 1, 1]}", 4, &worst);
    CHECK(worst < 1e-5, "mirror of reflectance 1: a pixel is %g away from 1", worst);
    m = sky_furnace("{\"type\": \"glass\", \"ior\": 1.5, \"transmission\": [1, 1, 1]}", 256, &worst);
    CHECK(fabs(m - 1) < 0.01 && worst < 0.1, "clear glass: mean %g, worst pixel %g away from 1", m, worst);
    m = sky_furnace("{\"type\": \"diffuse\", \"albedo\": [1, 1, 1]}", 1024, &worst);
    CHECK(fabs(m - 1) < 0.01 && worst < 0.05, "white diffuse: mean %g, worst pixel %g away from 1", m, worst);
    /* Normalised Phong loses the part of its lobe below the horizon: it may
     * only lose energy, never gain it. */
    m = sky_furnace("{\"type\": \"glossy\", \"diffuse\": [0.5, 0.5, 0.5], \"specular\": [0.5, 0.5, 0.5], \"exponent\": 20}",
                    1024, &worst);
    CHECK(m <= 1.005 && m > 0.8, "glossy kd + ks = 1: mean %g (must not exceed 1)", m);
}

/* Multiply every coordinate of the scene tree by scale and add offset:
 * shape vertices, sphere centres and radii, camera position and target. */
static void transform_tree(cJSON *node, const char *key, double scale, double offset) {
    if (cJSON_IsArray(node) && key &&
        (!strcmp(key, "vertices") || !strcmp(key, "position") || !strcmp(key, "look_at") || !strcmp(key, "center"))) {
        cJSON *v;
        cJSON_ArrayForEach(v, node) {
            if (cJSON_IsArray(v)) transform_tree(v, key, scale, offset);
            else if (cJSON_IsNumber(v)) cJSON_SetNumberValue(v, v->valuedouble * scale + offset);
        }
        return;
    }
    if (cJSON_IsNumber(node) && key && !strcmp(key, "radius")) {
        cJSON_SetNumberValue(node, node->valuedouble * scale);
        return;
    }
    cJSON *child;
    cJSON_ArrayForEach(child, node) transform_tree(child, child->string ? child->string : key, scale, offset);
}

/* The Cornell box, scaled and moved, as a scene at 48x48 and `spp` with
 * `seed`; NULL on failure (reported). */
static float *render_cornell(double scale, double offset, int spp, int seed) {
    size_t len;
    char err[1024];
    char *text = file_read_all("scenes/cornell-box.json", 1 << 20, &len, err, sizeof err);
    cJSON *root = text ? cJSON_Parse(text) : NULL;
    free(text);
    CHECK(root != NULL, "cannot read the Cornell box: %s", err);
    if (!root) return NULL;
    transform_tree(root, NULL, scale, offset);
    cJSON *r = cJSON_GetObjectItemCaseSensitive(root, "render");
    cJSON_ReplaceItemInObject(r, "width", cJSON_CreateNumber(48));
    cJSON_ReplaceItemInObject(r, "height", cJSON_CreateNumber(48));
    cJSON_ReplaceItemInObject(r, "spp", cJSON_CreateNumber(spp));
    cJSON_ReplaceItemInObject(r, "seed", cJSON_CreateNumber(seed));
    char *json = cJSON_PrintUnformatted(root);
    cJSON_Delete(root);
    scene *s = util_scene_from_text(json, err, sizeof err);
    free(json);
    CHECK(s != NULL, "scale %g offset %g: %s", scale, offset, err);
    if (!s) return NULL;
    trace_stats st;
    float *rgb = util_render(s, 2, 8, 1, &st);
    CHECK(st.bad_samples == 0, "scale %g offset %g: %llu NaN/Inf samples", scale, offset,
          (unsigned long long)st.bad_samples);
    scene_free(s);
    return rgb;
}

static double rel_mse(const float *a, const float *b, int n) {
    double sum = 0;
    for (int i = 0; i < n; i++) sum += (double)(a[i] - b[i]) * (a[i] - b[i]) / ((double)b[i] * b[i] + 0.01);
    return sum / n;
}

/* The Cornell box scaled by 1e-4 and 1e4, and moved 1e5 units away, is the
 * same picture: against the original (same seed) it differs by far less
 * than the original differs from itself under another seed, and it has no
 * black pixel where the original has light (acne, leaks). */
TEST(stress_scale_invariance_of_the_cornell_box) {
    const int n = 48 * 48 * 3;
    float *orig = render_cornell(1, 0, 64, 5), *other = render_cornell(1, 0, 64, 6);
    if (!orig || !other) return;
    double noise = rel_mse(other, orig, n);
    static const double cases[][2] = {{1e-4, 0}, {1e4, 0}, {1, 1e5}, {1e-4, 1e5 * 1e-4}};
    for (size_t c = 0; c < sizeof cases / sizeof cases[0]; c++) {
        float *img = render_cornell(cases[c][0], cases[c][1], 64, 5);
        if (!img) continue;
        double d = rel_mse(img, orig, n);
        int black = 0;
        for (int i = 0; i < n; i += 3)
            black += img[i] + img[i + 1] + img[i + 2] == 0.0f && orig[i] + orig[i + 1] + orig[i + 2] > 0.0f;
        CHECK(d < 0.01 * noise, "scale %g, offset %g: relMSE %g against the original; another seed differs by %g",
              cases[c][0], cases[c][1], d, noise);
        CHECK(black == 0, "scale %g, offset %g: %d pixels black that are lit in the original", cases[c][0],
              cases[c][1], black);
        free(img);
    }
    free(orig);
    free(other);
}
