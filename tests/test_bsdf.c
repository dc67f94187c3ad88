/* test_bsdf.c - every non-delta BSDF: sampling agrees with its pdf
 * (chi-square), reciprocity, albedo never above 1; glass: Fresnel sums. */
#include <math.h>
#include <stdlib.h>
#include <string.h>

#include "render/bsdf.h"
#include "render/bsdf_pbr.h"
#include "render/rng.h"
#include "render/warp.h"
#include "harness.h"

#define THETA_BINS 20
#define PHI_BINS 40
#define CHI_SAMPLES 200000

typedef float (*pdf_fn)(const material *m, vec3 wo, vec3 wi);

static vec3 dir_from(double cos_t, double phi) {
    double s = sqrt(fmax(0.0, 1.0 - cos_t * cos_t));
    return vec3_make((float)(s * cos(phi)), (float)(s * sin(phi)), (float)cos_t);
}

/* Chi-square statistic of bsdf_sample_wi against `pdf` over a (cos theta,
 * phi) grid of the whole sphere. The returned samples are compared with the
 * pdf normalised over the sphere; the fraction of lost samples (below the
 * surface) is checked against 1 - integral(pdf) separately, since its
 * expected count is too sensitive to quadrature error for a chi-square bin.
 * Bins expecting fewer than 5 samples are pooled. Returns 1 if the
 * hypothesis "samples follow pdf" survives at significance 1e-4
 * (Wilson-Hilferty quantile). */
static int chi2_agrees(const material *m, vec3 wo, pdf_fn pdf, double *stat_out) {
    static double observed[THETA_BINS * PHI_BINS], expected[THETA_BINS * PHI_BINS];
    memset(observed, 0, sizeof observed);
    int nb = THETA_BINS * PHI_BINS, returned = 0;
    for (int i = 0; i < CHI_SAMPLES; i++) {
        rng_stream r = rng_stream_start(11, 0, (uint64_t)i);
        float u1 = rng_next(&r), u2 = rng_next(&r), u3 = rng_next(&r);
        bsdf_sample bs;
        if (!bsdf_sample_wi(m, wo, u1, u2, u3, &bs)) continue;
        returned++;
        int ti = (int)((bs.wi.z + 1.0) * 0.5 * THETA_BINS), pi;
        double phi = atan2(bs.wi.y, bs.wi.x);
        if (phi < 0) phi += 2 * M_PI;
        pi = (int)(phi / (2 * M_PI) * PHI_BINS);
        ti = ti < 0 ? 0 : ti >= THETA_BINS ? THETA_BINS - 1 : ti;
        pi = pi < 0 ? 0 : pi >= PHI_BINS ? PHI_BINS - 1 : pi;
        observed[ti * PHI_BINS + pi]++;
    }
    /* Integrate the pdf over each bin by the midpoint rule in (cos theta,
     * phi), where d(omega) = d(cos theta) d(phi); fine in cos theta, where
     * the lobes are steep. */
    double total = 0;
    const int sc = 32, sp = 4;
    for (int ti = 0; ti < THETA_BINS; ti++)
        for (int pi = 0; pi < PHI_BINS; pi++) {
            double sum = 0, dc = 2.0 / THETA_BINS / sc, dp = 2 * M_PI / PHI_BINS / sp;
            for (int a = 0; a < sc; a++)
                for (int b = 0; b < sp; b++) {
                    double c = -1 + (ti * sc + a + 0.5) * dc, p = (pi * sp + b + 0.5) * dp;
                    sum += pdf(m, wo, dir_from(c, p)) * dc * dp;
                }
            expected[ti * PHI_BINS + pi] = sum;
            total += sum;
        }
    double lost = 1.0 - (double)returned / CHI_SAMPLES, want_lost = fmax(0.0, 1.0 - total);
    if (fabs(lost - want_lost) > 0.005 + 5 * sqrt(want_lost * (1 - want_lost) / CHI_SAMPLES)) {
        *stat_out = INFINITY;
        return 0;
    }
    double stat = 0, pool_o = 0, pool_e = 0;
    int dof = -1;
    for (int i = 0; i < nb; i++) {
        double e = total > 0 ? expected[i] / total * returned : 0;
        if (e < 5) {
            pool_o += observed[i];
            pool_e += e;
            continue;
        }
        stat += (observed[i] - e) * (observed[i] - e) / e;
        dof++;
    }
    if (pool_e >= 5) {
        stat += (pool_o - pool_e) * (pool_o - pool_e) / pool_e;
        dof++;
    } else if (pool_o > 20) {
        stat += 1e9; /* many samples where the pdf says almost none */
    }
    double z = 3.719, k = dof > 0 ? dof : 1; /* z of the 1e-4 upper tail */
    double crit = k * pow(1 - 2 / (9 * k) + z * sqrt(2 / (9 * k)), 3);
    *stat_out = stat;
    return stat < crit;
}

static material diffuse(void) {
    material m = {.kind = MATERIAL_DIFFUSE, .kd = {0.8f, 0.5f, 0.2f}};
    return m;
}
static material glossy(float kd, float ks, float n) {
    material m = {.kind = MATERIAL_GLOSSY, .kd = vec3_splat(kd), .ks = vec3_splat(ks), .exponent = n};
    m.p_specular = ks / (kd + ks);
    return m;
}

static const vec3 wos[] = {{0, 0, 1}, {0.5f, 0.1f, 0.860233f}, {0.9f, 0.0f, 0.43589f}, {0.99f, 0.05f, 0.131909f}};

TEST(bsdf_chi2_diffuse_and_glossy) {
    material ms[] = {diffuse(), glossy(0.4f, 0.5f, 5), glossy(0.1f, 0.8f, 40), glossy(0.7f, 0.2f, 200)};
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++)
        for (size_t w = 0; w < sizeof wos / sizeof wos[0]; w++) {
            double stat;
            vec3 wo = vec3_normalize(wos[w]);
            CHECK(chi2_agrees(&ms[i], wo, bsdf_pdf, &stat), "material %zu, wo %zu: chi2 %.1f too large", i, w, stat);
        }
}

/* A wrong pdf must be caught: cosine-distributed samples against a uniform
 * hemisphere density. Proves the test above can fail. */
static float wrong_pdf(const material *m, vec3 wo, vec3 wi) {
    (void)m;
    (void)wo;
    return wi.z > 0 ? (float)(0.5 / M_PI) : 0.0f;
}
TEST(bsdf_chi2_detects_wrong_pdf) {
    material m = diffuse();
    double stat;
    CHECK(!chi2_agrees(&m, vec3_make(0, 0, 1), wrong_pdf, &stat), "a wrong pdf passed (chi2 %.1f)", stat);
}

TEST(bsdf_reciprocity) {
    material ms[] = {diffuse(), glossy(0.3f, 0.6f, 12)};
    for (size_t i = 0; i < 2; i++)
        for (int k = 0; k < 1000; k++) {
            rng_stream r = rng_stream_start(3, i, (uint64_t)k);
            vec3 a = dir_from(rng_next(&r), 2 * M_PI * rng_next(&r));
            vec3 b = dir_from(rng_next(&r), 2 * M_PI * rng_next(&r));
            vec3 fab = bsdf_eval(&ms[i], a, b), fba = bsdf_eval(&ms[i], b, a);
            CHECK(fabsf(fab.x - fba.x) <= 1e-5f * fmaxf(1.0f, fab.x) && fabsf(fab.y - fba.y) <= 1e-5f * fmaxf(1.0f, fab.y),
                  "material %zu: f(a,b)=%g f(b,a)=%g", i, fab.x, fba.x);
        }
}

/* The albedo E[f cos / pdf] of m seen from wo, from 20000 samples of the
 * streams (seed, stream, k); its standard error into *se. */
static double albedo_estimate(const material *m, vec3 wo, uint64_t seed, uint64_t stream, double *se) {
    double sum = 0, sum2 = 0;
    const int n = 20000;
    for (int k = 0; k < n; k++) {
        rng_stream r = rng_stream_start(seed, stream, (uint64_t)k);
        float u1 = rng_next(&r), u2 = rng_next(&r), u3 = rng_next(&r);
        bsdf_sample bs;
        double v = bsdf_sample_wi(m, wo, u1, u2, u3, &bs) ? vec3_max_comp(bs.weight) : 0;
        sum += v;
        sum2 += v * v;
    }
    double mean = sum / n;
    *se = sqrt(fmax(0, sum2 / n - mean * mean) / n);
    return mean;
}

/* Albedo = E[f cos / pdf] over the sampled directions, for many wo including
 * grazing ones: never above 1 (within the estimate's noise). */
TEST(bsdf_albedo_at_most_one) {
    material ms[] = {diffuse(), glossy(0.0f, 1.0f, 1), glossy(0.0f, 1.0f, 100), glossy(0.5f, 0.5f, 10),
                     {.kind = MATERIAL_MIRROR, .ks = {0.95f, 0.95f, 0.95f}}};
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++)
        for (int w = 0; w <= 10; w++) {
            vec3 wo = dir_from(w == 0 ? 0.01 : w / 10.0, 0.3);
            double se, mean = albedo_estimate(&ms[i], wo, 17, (uint64_t)w, &se);
            CHECK(mean <= 1.0 + 4 * se + 1e-6, "material %zu, cos(wo)=%.2f: albedo %.4f", i, wo.z, mean);
        }
}

TEST(bsdf_glass_fresnel) {
    CHECK(fabsf(bsdf_fresnel_dielectric(1.0f, 1.5f) - 0.04f) < 1e-6f, "normal incidence must be 0.04");
    CHECK(bsdf_fresnel_dielectric(-0.3f, 1.5f) == 1.0f, "total internal reflection beyond the critical angle");
    for (int k = 1; k <= 10; k++) {
        float F = bsdf_fresnel_dielectric(k / 10.0f, 1.5f);
        CHECK(F >= 0 && F <= 1, "F out of range");
    }
    /* Refraction obeys Snell's law and leaves on the other side. */
    material g = {.kind = MATERIAL_GLASS, .ior = 1.5f, .kt = {1, 1, 1}};
    vec3 wo = vec3_normalize(vec3_make(0.5f, 0, 0.8f));
    bsdf_sample bs;
    CHECK(bsdf_sample_wi(&g, wo, 0, 0, 0.999f, &bs) && bs.wi.z < 0, "transmission must go inside");
    float sin_i = sqrtf(1 - wo.z * wo.z), sin_t = sqrtf(1 - bs.wi.z * bs.wi.z);
    CHECK(fabsf(sin_i - 1.5f * sin_t) < 1e-5f, "Snell: %g vs %g", sin_i, 1.5f * sin_t);
    CHECK(fabsf(bs.weight.x - 1 / 2.25f) < 1e-5f, "radiance scales by (1/eta)^2 entering: %g", bs.weight.x);
}

/* ---- glTF metallic-roughness (render/bsdf_pbr.h) ------------------------- */

static material pbr(float r, float g, float b, float metallic, float roughness) {
    material m = {.kind = MATERIAL_PBR, .base_color = {r, g, b}, .metallic = metallic, .roughness = roughness,
                  .base_alpha = 1};
    return m;
}

TEST(bsdf_pbr_chi2) {
    /* Roughness from 0.35 up: sharper lobes are narrower than the
     * quadrature of the expected counts can resolve (as for Phong above). */
    material ms[] = {pbr(0.8f, 0.5f, 0.2f, 0, 0.5f), pbr(1, 0.8f, 0.4f, 1, 0.35f), pbr(0.9f, 0.9f, 0.9f, 1, 0.4f),
                     pbr(0.5f, 0.5f, 0.5f, 0.5f, 0.8f), pbr(0.2f, 0.6f, 0.3f, 0, 1), pbr(1, 1, 1, 1, 1),
                     pbr(0.9f, 0.9f, 0.9f, 0, 0.4f)};
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++)
        for (size_t w = 0; w < sizeof wos / sizeof wos[0]; w++) {
            double stat;
            vec3 wo = vec3_normalize(wos[w]);
            CHECK(chi2_agrees(&ms[i], wo, bsdf_pdf, &stat), "pbr material %zu, wo %zu: chi2 %.1f too large", i, w,
                  stat);
        }
}

TEST(bsdf_pbr_reciprocity_and_albedo) {
    material ms[] = {pbr(0.8f, 0.5f, 0.2f, 0, 0.5f), pbr(1, 0.8f, 0.4f, 1, 0.2f), pbr(0.5f, 0.5f, 0.5f, 0.5f, 0.8f)};
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++) {
        for (int k = 0; k < 1000; k++) {
            rng_stream r = rng_stream_start(5, i, (uint64_t)k);
            vec3 a = dir_from(rng_next(&r), 2 * M_PI * rng_next(&r));
            vec3 b = dir_from(rng_next(&r), 2 * M_PI * rng_next(&r));
            vec3 fab = bsdf_eval(&ms[i], a, b), fba = bsdf_eval(&ms[i], b, a);
            CHECK(fabsf(fab.x - fba.x) <= 1e-4f * fmaxf(1.0f, fab.x) && fabsf(fab.z - fba.z) <= 1e-4f * fmaxf(1.0f, fab.z),
                  "pbr %zu: f(a,b)=%g f(b,a)=%g", i, fab.x, fba.x);
        }
        for (int w = 0; w <= 10; w++) {
            vec3 wo = dir_from(w == 0 ? 0.02 : w / 10.0, 0.3);
            double se, mean = albedo_estimate(&ms[i], wo, 19, (uint64_t)w, &se);
            CHECK(mean <= 1.0 + 4 * se + 1e-6, "pbr %zu, cos(wo)=%.2f: albedo %.4f", i, wo.z, mean);
        }
    }
}

/* Directional albedo of f cos by quadrature over the hemisphere (midpoint
 * rule in cos theta and phi, fine enough for the lobes tested). */
static double albedo_quadrature(const material *m, vec3 wo) {
    const int nc = 2000, np = 400;
    double sum = 0;
    for (int a = 0; a < nc; a++)
        for (int b = 0; b < np; b++) {
            double c = (a + 0.5) / nc, p = (b + 0.5) * 2 * M_PI / np;
            sum += bsdf_eval(m, wo, dir_from(c, p)).x * c;
        }
    return sum * (1.0 / nc) * (2 * M_PI / np);
}

/* White furnace of a rough metal of reflectance 1 (F = 1 everywhere): a
 * single-scattering microfacet BRDF loses the energy of the paths that
 * would bounce between microfacets, and nothing else. So the sampled
 * estimate E[f cos / pdf] must equal the BRDF's own directional albedo (by
 * quadrature), and the loss 1 - albedo must be 0 for a smooth surface and
 * grow with roughness. Figures (printed): the loss at normal incidence and
 * at cos = 0.2. */
TEST(bsdf_pbr_white_furnace) {
    const float rough[] = {0.05f, 0.25f, 0.5f, 0.75f, 1.0f};
    double prev_loss = -1;
    for (size_t i = 0; i < sizeof rough / sizeof rough[0]; i++) {
        material m = pbr(1, 1, 1, 1, rough[i]);
        double loss[2];
        const double cosines[2] = {1.0, 0.2};
        for (int w = 0; w < 2; w++) {
            vec3 wo = dir_from(cosines[w], 0.0);
            double sum = 0, sum2 = 0;
            const int n = 200000;
            for (int k = 0; k < n; k++) {
                rng_stream r = rng_stream_start(23, i * 2 + (uint64_t)w, (uint64_t)k);
                float u1 = rng_next(&r), u2 = rng_next(&r), u3 = rng_next(&r);
                bsdf_sample bs;
                double v = bsdf_sample_wi(&m, wo, u1, u2, u3, &bs) ? bs.weight.x : 0;
                sum += v;
                sum2 += v * v;
            }
            double mc = sum / n, se = sqrt(fmax(0, sum2 / n - mc * mc) / n), q = albedo_quadrature(&m, wo);
            /* The quadrature misses part of a very sharp lobe: compare
             * only where it resolves the lobe (roughness >= 0.25). */
            if (rough[i] >= 0.25f)
                CHECK(fabs(mc - q) <= 4 * se + 0.003, "roughness %.2f cos %.1f: sampled albedo %.4f, quadrature %.4f",
                      rough[i], cosines[w], mc, q);
            CHECK(mc <= 1 + 4 * se, "roughness %.2f: albedo %.4f above 1", rough[i], mc);
            loss[w] = 1 - mc;
        }
        printf("    furnace: metal, reflectance 1, roughness %.2f: energy lost %.4f at normal incidence, "
               "%.4f at cos 0.2\n", rough[i], loss[0], loss[1]);
        if (rough[i] <= 0.05f) CHECK(loss[0] < 0.005, "a smooth metal loses %.4f", loss[0]);
        CHECK(loss[0] >= prev_loss - 0.002, "loss must grow with roughness: %.4f after %.4f", loss[0], prev_loss);
        prev_loss = loss[0];
    }
    CHECK(prev_loss > 0.02 && prev_loss < 0.8, "roughness 1 loses %.4f at normal incidence", prev_loss);
}

/* f and pdf by the formulas as written before bsdf.c shared the Phong
 * lobe's powf between them (bsdf.c's header comment; warp.h's densities),
 * and by bsdf_pbr.h's two functions for PBR. */
static vec3 reference_eval(const material *m, vec3 wo, vec3 wi, float *pdf) {
    *pdf = 0.0f;
    if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3_splat(0.0f);
    if (m->kind == MATERIAL_PBR) {
        *pdf = bsdf_pbr_pdf(m, wo, wi);
        return bsdf_pbr_eval(m, wo, wi);
    }
    if (m->kind == MATERIAL_DIFFUSE) {
        *pdf = warp_cosine_hemisphere_pdf(wi.z);
        return vec3_scale(m->kd, TS_INV_PI);
    }
    float ca = vec3_dot(vec3_make(-wo.x, -wo.y, wo.z), wi);
    float lobe = ca > 0.0f ? (m->exponent + 2.0f) * (0.5f * TS_INV_PI) * powf(ca, m->exponent) : 0.0f;
    *pdf = (1.0f - m->p_specular) * warp_cosine_hemisphere_pdf(wi.z) +
           m->p_specular * warp_power_cosine_pdf(ca, m->exponent);
    return vec3_add(vec3_scale(m->kd, TS_INV_PI), vec3_scale(m->ks, lobe));
}

/* bsdf_eval, bsdf_pdf and bsdf_eval_pdf give the reference's f and pdf bit
 * for bit for every non-delta kind, over directions on both sides of the
 * surface, grazing ones and wi = -wo (a zero half vector) included; and
 * bsdf_sample_wi's pdf and weight are the reference's at the direction it
 * drew (Lambert's weight: kd exactly, f cos / pdf in closed form). */
TEST(bsdf_eval_pdf_matches_eval_and_pdf) {
    material ms[] = {diffuse(), glossy(0.4f, 0.5f, 5), glossy(0.1f, 0.8f, 40), pbr(0.8f, 0.5f, 0.2f, 0, 0.5f),
                     pbr(1, 0.8f, 0.4f, 1, 0.2f), pbr(0.5f, 0.5f, 0.5f, 0.5f, 0.0f)};
    int bad = 0, sampled = 0;
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++)
        for (int k = 0; k < 20000; k++) {
            rng_stream r = rng_stream_start(23, i, (uint64_t)k);
            vec3 wo = dir_from(k % 5 == 0 ? 1e-4 : rng_next(&r), 2 * M_PI * rng_next(&r));
            vec3 wi = k % 97 == 0 ? vec3_neg(wo) : dir_from(2.0 * rng_next(&r) - 1.0, 2 * M_PI * rng_next(&r));
            float pdf, want_pdf, one_pdf = bsdf_pdf(&ms[i], wo, wi);
            vec3 f = bsdf_eval_pdf(&ms[i], wo, wi, &pdf), want_f = reference_eval(&ms[i], wo, wi, &want_pdf);
            vec3 one_f = bsdf_eval(&ms[i], wo, wi);
            bad += memcmp(&f, &want_f, sizeof f) != 0 || memcmp(&pdf, &want_pdf, sizeof pdf) != 0 ||
                   memcmp(&one_f, &want_f, sizeof f) != 0 || memcmp(&one_pdf, &want_pdf, sizeof pdf) != 0;
            bsdf_sample bs;
            if (!bsdf_sample_wi(&ms[i], wo, rng_next(&r), rng_next(&r), rng_next(&r), &bs)) continue;
            sampled++;
            float sp;
            vec3 sf = reference_eval(&ms[i], wo, bs.wi, &sp), w = vec3_scale(sf, bs.wi.z / sp);
            if (ms[i].kind == MATERIAL_DIFFUSE) w = ms[i].kd; /* f cos / pdf in closed form */
            bad += memcmp(&sp, &bs.pdf, sizeof sp) != 0 || memcmp(&w, &bs.weight, sizeof w) != 0;
        }
    CHECK(bad == 0 && sampled > 50000, "%d evaluations differ (%d samples)", bad, sampled);
}

/* The cosine warp's sin and cos (warp_sincos_quarter) against double
 * precision over [-pi/4, pi/4], 2^20 + 1 points with the ends: within 2
 * ulp of the float nearest the true value, and the warp's directions of
 * unit length within 4e-7 (a coefficient off in its fourth digit fails the first). */
TEST(warp_sincos_quarter_is_accurate) {
    const int n = 1 << 20;
    float worst_s = 0, worst_c = 0;
    for (int i = 0; i <= n; i++) {
        float x = (float)(-M_PI / 4 + (M_PI / 2) * i / n), s, c;
        warp_sincos_quarter(x, &s, &c);
        float ts = (float)sin((double)x), tc = (float)cos((double)x);
        float es = fabsf(s - ts) / (nextafterf(fabsf(ts), INFINITY) - fabsf(ts));
        float ec = fabsf(c - tc) / (nextafterf(fabsf(tc), INFINITY) - fabsf(tc));
        if (x != 0.0f && es > worst_s) worst_s = es;
        if (ec > worst_c) worst_c = ec;
        if (x == 0.0f) CHECK(s == 0.0f && c == 1.0f, "sincos(0) = %g, %g", s, c);
    }
    CHECK(worst_s <= 2.0f && worst_c <= 2.0f, "sin off by %.2f ulp, cos by %.2f ulp", worst_s, worst_c);
    float worst_len = 0;
    for (int i = 0; i < 4096; i++) {
        rng_stream r = rng_stream_start(11, 0, (uint64_t)i);
        vec3 w = warp_cosine_hemisphere(rng_next(&r), rng_next(&r));
        worst_len = fmaxf(worst_len, fabsf(vec3_length(w) - 1.0f));
        CHECK(w.z >= 0.0f, "direction %d below the horizon: z = %g", i, w.z);
    }
    CHECK(worst_len <= 4e-7f, "a cosine-warped direction's length is off by %g", worst_len);
}

/* The integrator takes each sampled direction to world space without
 * normalising it again (integrator.c), and the next vertex's wo is that
 * direction reversed: a direction must stay unit along a whole path, also
 * through chains of reflections, which build wi from wo and so would carry
 * its rounding on. Paths of 64 bounces through every material kind
 * (Lambert, Phong, PBR rough and nearly smooth, mirror, glass), each vertex
 * with a random unit normal turned towards wo (as the integrator turns ng),
 * 2000 paths per kind: every direction unit within 1e-6. (Without the
 * reflections' own normalisation: 2.6e-6 off; with only the PBR lobe's,
 * the mirror and glass 1.3e-6.) */
TEST(bsdf_path_directions_stay_unit_without_renormalising) {
    material ms[] = {diffuse(), glossy(0.4f, 0.5f, 5), pbr(0.8f, 0.5f, 0.2f, 0, 0.5f), pbr(1, 0.8f, 0.4f, 1, 0.05f),
                     {.kind = MATERIAL_MIRROR, .ks = {0.95f, 0.95f, 0.95f}},
                     {.kind = MATERIAL_GLASS, .ior = 1.5f, .kt = {1, 1, 1}}};
    float worst = 0;
    int steps = 0;
    for (size_t i = 0; i < sizeof ms / sizeof ms[0]; i++)
        for (int k = 0; k < 2000; k++) {
            rng_stream r = rng_stream_start(29, i, (uint64_t)k);
            vec3 wo = dir_from(rng_next(&r), 2 * M_PI * rng_next(&r)); /* unit, towards the viewer */
            for (int depth = 0; depth < 64; depth++) {
                vec3 n = dir_from(2.0 * rng_next(&r) - 1.0, 2 * M_PI * rng_next(&r));
                if (ms[i].kind != MATERIAL_GLASS && vec3_dot(n, wo) < 0.0f) n = vec3_neg(n);
                frame f = frame_from_normal(n);
                bsdf_sample bs;
                float u1 = rng_next(&r), u2 = rng_next(&r), u3 = rng_next(&r);
                if (!bsdf_sample_wi(&ms[i], frame_to_local(&f, wo), u1, u2, u3, &bs)) break;
                vec3 wi = frame_to_world(&f, bs.wi);
                worst = fmaxf(worst, fabsf(vec3_length(wi) - 1.0f));
                wo = vec3_neg(wi);
                steps++;
            }
        }
    CHECK(worst <= 1e-6f && steps > 100000, "a path's direction is off unit length by %g (%d bounces)", worst, steps);
}
