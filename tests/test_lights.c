/* test_lights.c - light sampling against a numerical integral: the direct
 * irradiance from a rectangular (two-triangle) light at points below it, next
 * to it at a grazing angle and far from it, estimated by solid-angle sampling
 * of its triangles (spherical.h), by area sampling (what lights_sample does)
 * and by a midpoint-rule integral over the light. */
#include <math.h>
#include <stdio.h>
#include <stdint.h>

#include "harness.h"
#include "render/scene.h"
#include "render/spherical.h"
#include "render/warp.h"
#include "util.h"

/* The Cornell box's light (one-sided, facing down) over a floor. */
static const char *light_scene =
    "{\"camera\": {\"type\": \"perspective\", \"position\": [278, 273, -800], \"look_at\": [278, 273, 0], \"fov\": 40},"
    " \"materials\": {\"w\": {\"type\": \"diffuse\", \"albedo\": [0.5, 0.5, 0.5]}},"
    " \"shapes\": ["
    "  {\"type\": \"quad\", \"material\": \"w\", \"vertices\": [[552.8, 0, 0], [0, 0, 0], [0, 0, 559.2], [549.6, 0, 559.2]]},"
    "  {\"type\": \"quad\", \"emission\": [17, 12, 4],"
    "   \"vertices\": [[343, 548.7, 227], [343, 548.7, 332], [213, 548.7, 332], [213, 548.7, 227]]}]}";

typedef struct {
    double mean, stderr_;
} estimate;

/* Deterministic jitter: a 64-bit LCG's top bits. */
static float next_u(uint64_t *state) {
    *state = *state * 6364136223846793005ull + 1442695040888963407ull;
    return (float)((*state >> 40) * 0x1p-24);
}

static estimate finish(double sum, double sum2, int n) {
    estimate e;
    e.mean = sum / n;
    e.stderr_ = sqrt(fmax(0.0, sum2 / n - e.mean * e.mean) / n);
    return e;
}

/* Irradiance (red channel) at ref with normal nr, with N x N stratified
 * samples, the light picked by select_pdf as lights_sample does. With
 * angle, by solid-angle sampling (spherical.h) where
 * spherical_triangle_use picks it, *used counting those samples; else (and
 * without angle) by area: point uniform on the light, pdf = select d^2 /
 * (|cos_l| A). */
static estimate estimate_irradiance(const scene *s, vec3 ref, vec3 nr, int n, int angle, int *used) {
    double sum = 0, sum2 = 0;
    uint64_t st = 7;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            float u1 = (i + next_u(&st)) / n, u2 = (j + next_u(&st)) / n;
            uint32_t k = u1 < s->light_cdf[1] ? 0 : 1;
            const light *l = &s->lights[k];
            float w = s->light_cdf[k + 1] - s->light_cdf[k];
            u1 = fminf((u1 - s->light_cdf[k]) / w, 0x1.fffffep-1f);
            const triangle *t = &s->triangles[l->prim];
            float b1, b2, omega;
            int by_angle = angle && spherical_triangle_use(t->v0, t->v1, t->v2, ref, &omega);
            double v = 0;
            if (by_angle ? spherical_triangle_sample(t->v0, t->v1, t->v2, ref, u1, u2, &b1, &b2)
                         : (warp_uniform_triangle(u1, u2, &b1, &b2), 1)) {
                vec3 p = vec3_add(vec3_add(vec3_scale(t->v0, 1 - b1 - b2), vec3_scale(t->v1, b1)),
                                  vec3_scale(t->v2, b2));
                vec3 d = vec3_sub(p, ref);
                double dist = vec3_length(d);
                vec3 wi = vec3_scale(d, 1.0f / (float)dist);
                double cos_l = -vec3_dot(s->triangle_normals[l->prim], wi);
                if (cos_l > 0) {
                    double pdf = by_angle ? l->select_pdf / omega : l->select_pdf * dist * dist / (cos_l * l->area);
                    v = l->radiance.x * fmax(0.0, vec3_dot(nr, wi)) / pdf;
                }
            }
            if (used) *used += by_angle;
            sum += v, sum2 += v * v;
        }
    return finish(sum, sum2, n * n);
}

static estimate by_solid_angle(const scene *s, vec3 ref, vec3 nr, int n, int *used) {
    return estimate_irradiance(s, ref, nr, n, 1, used);
}

static estimate by_area(const scene *s, vec3 ref, vec3 nr, int n) {
    return estimate_irradiance(s, ref, nr, n, 0, NULL);
}

/* Midpoint rule over m^2 sub-triangles of each light triangle, in double. */
static double by_integral(const scene *s, vec3 ref, vec3 nr, int m) {
    double total = 0;
    for (uint32_t k = 0; k < s->light_count; k++) {
        const light *l = &s->lights[k];
        const triangle *t = &s->triangles[l->prim];
        vec3 nl = s->triangle_normals[l->prim];
        double da = l->area / ((double)m * m);
        for (int i = 0; i < m; i++)
            for (int j = 0; i + j < m; j++)
                for (int up = 0; up < 2 && i + j + up < m; up++) {
                    /* centroid of the sub-triangle, in barycentrics */
                    double b1 = up ? (i + 2.0 / 3) / m : (i + 1.0 / 3) / m;
                    double b2 = up ? (j + 2.0 / 3) / m : (j + 1.0 / 3) / m;
                    double b0 = 1 - b1 - b2;
                    double p[3] = {b0 * t->v0.x + b1 * t->v1.x + b2 * t->v2.x, b0 * t->v0.y + b1 * t->v1.y + b2 * t->v2.y,
                                   b0 * t->v0.z + b1 * t->v1.z + b2 * t->v2.z};
                    double d[3] = {p[0] - ref.x, p[1] - ref.y, p[2] - ref.z};
                    double d2 = d[0] * d[0] + d[1] * d[1] + d[2] * d[2], dl = sqrt(d2);
                    double cos_r = (nr.x * d[0] + nr.y * d[1] + nr.z * d[2]) / dl;
                    double cos_l = -(nl.x * d[0] + nl.y * d[1] + nl.z * d[2]) / dl;
                    if (cos_r > 0 && cos_l > 0) total += l->radiance.x * cos_r * cos_l / d2 * da;
                }
    }
    return total;
}

/* light_scene loaded, its quad light as 2 triangle lights; NULL after a
 * failed check. The caller frees it (scene_free). */
static scene *quad_light_scene(void) {
    char err[512];
    scene *s = util_scene_from_text(light_scene, err, sizeof err);
    CHECK(s != NULL, "%s", err);
    if (s && s->light_count != 2) {
        CHECK(0, "expected the quad light as 2 triangles, got %u lights", s->light_count);
        scene_free(s);
        return NULL;
    }
    return s;
}

TEST(lights_solid_angle_matches_integral) {
    scene *s = quad_light_scene();
    if (!s) return;
    const triangle *t0 = &s->triangles[s->lights[0].prim];
    const triangle *t1 = &s->triangles[s->lights[1].prim];
    /* Light frame in internal units: centre, down normal, size. */
    vec3 c = vec3_scale(vec3_add(vec3_add(t0->v0, t0->v1), vec3_add(t0->v2, t1->v0)), 0.25f);
    vec3 nl = s->triangle_normals[s->lights[0].prim];
    float size = vec3_length(vec3_sub(t0->v0, t0->v2));
    vec3 side = vec3_normalize(vec3_sub(t0->v1, t0->v0));
    struct {
        const char *what;
        vec3 ref, nr;
        int solid_angle; /* expected to be sampled by solid angle */
    } cases[] = {
        {"below the light", vec3_add(c, vec3_scale(nl, 0.4f * size)), vec3_neg(nl), 1},
        {"beside it, grazing", vec3_add(vec3_add(c, vec3_scale(side, 0.75f * size)), vec3_scale(nl, 0.02f * size)),
         vec3_neg(side), 1},
        {"far below", vec3_add(c, vec3_scale(nl, 200.0f * size)), vec3_neg(nl), 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        float omega;
        int used = spherical_triangle_use(t0->v0, t0->v1, t0->v2, cases[i].ref, &omega);
        CHECK(used == cases[i].solid_angle, "%s: solid-angle sampling %s (omega %g)", cases[i].what,
              used ? "used" : "not used", omega);
        int n_angle = 0;
        estimate a = by_solid_angle(s, cases[i].ref, cases[i].nr, 256, &n_angle);
        estimate b = by_area(s, cases[i].ref, cases[i].nr, 256);
        double ref = by_integral(s, cases[i].ref, cases[i].nr, 400);
        printf("    %-20s integral %.6g  solid angle %.6g +- %.2g  area %.6g +- %.2g\n", cases[i].what, ref, a.mean,
               a.stderr_, b.mean, b.stderr_);
        CHECK((n_angle > 0) == cases[i].solid_angle, "%s: %d solid-angle samples", cases[i].what, n_angle);
        /* Within 4 standard errors (stratified, so the bound is loose) and
         * the integral's own 0.2%. */
        CHECK(fabs(a.mean - ref) < 4 * a.stderr_ + 2e-3 * ref, "%s: solid-angle sampling gives %g, the integral %g",
              cases[i].what, a.mean, ref);
        CHECK(fabs(b.mean - ref) < 4 * b.stderr_ + 2e-3 * ref, "%s: area sampling gives %g, the integral %g",
              cases[i].what, b.mean, ref);
        if (cases[i].solid_angle)
            CHECK(a.stderr_ < b.stderr_, "%s: solid-angle sampling is noisier than area sampling (%g vs %g)",
                  cases[i].what, a.stderr_, b.stderr_);
    }
    scene_free(s);
}

/* Solid angle of a known configuration: a square of side 2 at distance 1
 * seen from its centre's normal subtends 4 asin(1/2) = 2 pi / 3 (two triangles). */
TEST(lights_spherical_solid_angle) {
    vec3 p = vec3_make(0, 0, 0);
    vec3 a = vec3_make(-1, -1, 1), b = vec3_make(1, -1, 1), c = vec3_make(1, 1, 1), d = vec3_make(-1, 1, 1);
    double omega = (double)spherical_triangle_solid_angle(a, b, c, p) + spherical_triangle_solid_angle(a, c, d, p);
    double want = 4 * asin(0.5);
    CHECK(fabs(omega - want) < 1e-5 * want, "square: omega %.8g, want %.8g", omega, want);
    /* Every sampled point lies on the triangle, and the directions cover
     * equal solid angles: the mean direction matches the integral's. */
    int off = 0;
    for (int i = 0; i < 64; i++)
        for (int j = 0; j < 64; j++) {
            float b1, b2;
            if (!spherical_triangle_sample(a, b, c, p, (i + 0.5f) / 64, (j + 0.5f) / 64, &b1, &b2) || b1 < 0 || b2 < 0 ||
                b1 + b2 > 1.0f + 1e-6f)
                off++;
        }
    CHECK(off == 0, "%d samples fell off the triangle or failed", off);
}

/* Solid-angle sampling of the rectangle corner + a ex + b ey from p
 * (spherical_rect_sample, Urena et al. 2013), chi-square test: n
 * independent samples binned into an 8 x 8 grid of cells of the rectangle
 * against the expected counts n Omega(cell) / Omega, each cell's solid angle
 * from Van Oosterom and Strackee's formula (spherical_triangle_solid_angle,
 * two triangles), independently of Urena's. Returns the statistic (63
 * degrees of freedom); *sum_omega gets the cells' total solid angle. */
static double rect_chi_square(const spherical_rect *r, vec3 corner, vec3 ex, vec3 ey, int n, double *sum_omega) {
    enum { G = 8 };
    double expect[G][G], count[G][G] = {{0}};
    *sum_omega = 0;
    for (int i = 0; i < G; i++)
        for (int j = 0; j < G; j++) {
            vec3 c00 = vec3_add(corner, vec3_add(vec3_scale(ex, (float)i / G), vec3_scale(ey, (float)j / G)));
            vec3 c10 = vec3_add(c00, vec3_scale(ex, 1.0f / G)), c01 = vec3_add(c00, vec3_scale(ey, 1.0f / G));
            vec3 c11 = vec3_add(c10, vec3_scale(ey, 1.0f / G));
            double w = (double)spherical_triangle_solid_angle(c00, c10, c11, r->p) +
                       spherical_triangle_solid_angle(c00, c11, c01, r->p);
            expect[i][j] = w;
            *sum_omega += w;
        }
    uint64_t st = 11;
    for (int k = 0; k < n; k++) {
        float u1 = next_u(&st), u2 = next_u(&st);
        vec3 q = vec3_sub(spherical_rect_sample(r, u1, u2), corner);
        double a = vec3_dot(q, ex) / vec3_dot(ex, ex), b = vec3_dot(q, ey) / vec3_dot(ey, ey);
        int i = (int)(a * G), j = (int)(b * G);
        i = i < 0 ? 0 : (i >= G ? G - 1 : i), j = j < 0 ? 0 : (j >= G ? G - 1 : j);
        count[i][j] += 1;
    }
    double chi2 = 0;
    for (int i = 0; i < G; i++)
        for (int j = 0; j < G; j++) {
            double e = n * expect[i][j] / *sum_omega;
            chi2 += (count[i][j] - e) * (count[i][j] - e) / e;
        }
    return chi2;
}

/* Irradiance at ref (normal nr) from the light scene's rectangle by
 * solid-angle sampling, N x N stratified samples: Omega * mean(L cos_r). */
static estimate by_rect(const scene *s, const spherical_rect *r, vec3 nl, vec3 nr, int n) {
    double sum = 0, sum2 = 0;
    uint64_t st = 7;
    for (int i = 0; i < n; i++)
        for (int j = 0; j < n; j++) {
            vec3 q = spherical_rect_sample(r, (i + next_u(&st)) / n, (j + next_u(&st)) / n);
            vec3 wi = vec3_normalize(vec3_sub(q, r->p));
            double v = 0;
            if (-vec3_dot(nl, wi) > 0) v = s->lights[0].radiance.x * fmax(0.0, vec3_dot(nr, wi)) * r->omega;
            sum += v, sum2 += v * v;
        }
    return finish(sum, sum2, n * n);
}

TEST(lights_spherical_rect) {
    scene *s = quad_light_scene();
    if (!s) return;
    /* The quad's corners v0 v1 v2 (first triangle) in internal units. */
    const triangle *t0 = &s->triangles[s->lights[0].prim];
    vec3 corner = t0->v1, ex = vec3_sub(t0->v0, t0->v1), ey = vec3_sub(t0->v2, t0->v1);
    CHECK(fabsf(vec3_dot(ex, ey)) < 1e-6f * vec3_dot(ex, ex), "the light is not a rectangle");
    vec3 nl = s->triangle_normals[s->lights[0].prim], c = vec3_add(corner, vec3_scale(vec3_add(ex, ey), 0.5f));
    float size = vec3_length(ex);
    vec3 side = vec3_normalize(ex);
    struct {
        const char *what;
        vec3 ref, nr;
        int usable;
    } cases[] = {
        {"below the light", vec3_add(c, vec3_scale(nl, 0.4f * size)), vec3_neg(nl), 1},
        {"beside it, grazing", vec3_add(vec3_add(c, vec3_scale(side, 0.75f * size)), vec3_scale(nl, 0.02f * size)),
         vec3_neg(side), 1},
        {"off a corner", vec3_add(vec3_add(corner, vec3_scale(side, -0.3f * size)), vec3_scale(nl, 0.5f * size)),
         vec3_normalize(vec3_sub(c, corner)), 1},
        {"far below", vec3_add(c, vec3_scale(nl, 30.0f * size)), vec3_neg(nl), 1},
        {"very far below", vec3_add(c, vec3_scale(nl, 1e4f * size)), vec3_neg(nl), 0},
        {"on its plane", vec3_add(c, vec3_scale(side, 2.0f * size)), vec3_neg(side), 0},
    };
    for (size_t i = 0; i < sizeof cases / sizeof cases[0]; i++) {
        spherical_rect r;
        int ok = spherical_rect_init(&r, corner, ex, ey, cases[i].ref);
        CHECK(ok == cases[i].usable, "%s: spherical_rect_init gives %d (omega %g)", cases[i].what, ok, r.omega);
        if (!ok) continue;
        double sum_omega, chi2 = rect_chi_square(&r, corner, ex, ey, 1 << 17, &sum_omega);
        estimate a = by_rect(s, &r, nl, cases[i].nr, 256), b = by_area(s, cases[i].ref, cases[i].nr, 256);
        double ref = by_integral(s, cases[i].ref, cases[i].nr, 400);
        printf("    %-20s omega %.6g (cells %.6g)  chi2 %.1f  irradiance: integral %.6g  rect %.6g +- %.2g  area "
               "%.6g +- %.2g\n",
               cases[i].what, r.omega, sum_omega, chi2, ref, a.mean, a.stderr_, b.mean, b.stderr_);
        CHECK(fabs(r.omega - sum_omega) < 1e-3 * sum_omega, "%s: omega %g, the cells sum to %g", cases[i].what,
              r.omega, sum_omega);
        /* 63 degrees of freedom: P(chi2 > 130) < 1e-6. */
        CHECK(chi2 < 130, "%s: chi-square %.1f over 64 cells: not uniform in solid angle", cases[i].what, chi2);
        CHECK(fabs(a.mean - ref) < 4 * a.stderr_ + 2e-3 * ref, "%s: rectangle sampling gives %g, the integral %g",
              cases[i].what, a.mean, ref);
    }
    scene_free(s);
}
