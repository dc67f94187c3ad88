/* bsdf_pbr.c - glTF metallic-roughness BRDF: GGX, Smith, Schlick, Lambert;
 * see bsdf_pbr.h for the formulas and the sampling densities. */
#include "bsdf_pbr.h"

#include "warp.h"

static float pbr_alpha(const material *m) {
    float r = min_f(max_f(m->roughness, 0.0f), 1.0f);
    return max_f(r * r, PBR_ALPHA_MIN);
}

float pbr_ggx_d(float alpha, float cos_h) {
    if (cos_h <= 0.0f) return 0.0f;
    float a2 = alpha * alpha, c2 = cos_h * cos_h;
    float k = c2 * (a2 - 1.0f) + 1.0f;
    return a2 / (TS_PI * k * k);
}

float pbr_smith_lambda(float alpha, float cos_w) {
    float c2 = cos_w * cos_w;
    if (c2 <= 0.0f) return INFINITY;
    float tan2 = max_f(0.0f, 1.0f - c2) / c2;
    return 0.5f * (sqrtf(1.0f + alpha * alpha * tan2) - 1.0f);
}

static vec3 f0_of(const material *m) {
    float mt = min_f(max_f(m->metallic, 0.0f), 1.0f);
    return vec3_add(vec3_scale(vec3_splat(0.04f), 1.0f - mt), vec3_scale(m->base_color, mt));
}

static vec3 schlick(vec3 f0, float cos_d) {
    float c = 1.0f - min_f(max_f(cos_d, 0.0f), 1.0f);
    float c5 = c * c * c * c * c;
    return vec3_add(f0, vec3_scale(vec3_sub(vec3_splat(1.0f), f0), c5));
}

/* Probability of sampling the specular lobe: its Fresnel weight at wo
 * against the diffuse albedo, never quite 0 or 1 unless a lobe is absent. */
static float p_specular(const material *m, vec3 wo) {
    float mt = min_f(max_f(m->metallic, 0.0f), 1.0f);
    float s = vec3_luminance(schlick(f0_of(m), wo.z));
    float d = (1.0f - mt) * vec3_luminance(m->base_color) * (1.0f - s);
    if (!(d > 0.0f)) return 1.0f;
    return min_f(max_f(s / (s + d), 0.05f), 0.95f);
}

vec3 bsdf_pbr_eval(const material *m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3_splat(0.0f);
    vec3 h = vec3_add(wo, wi);
    float hl = vec3_length(h);
    if (!(hl > 0.0f)) return vec3_splat(0.0f);
    h = vec3_scale(h, 1.0f / hl);
    float alpha = pbr_alpha(m), mt = min_f(max_f(m->metallic, 0.0f), 1.0f);
    vec3 F = schlick(f0_of(m), vec3_dot(wo, h));
    float G2 = 1.0f / (1.0f + pbr_smith_lambda(alpha, wo.z) + pbr_smith_lambda(alpha, wi.z));
    float spec = pbr_ggx_d(alpha, h.z) * G2 / (4.0f * wo.z * wi.z);
    vec3 diff = vec3_scale(vec3_mul(vec3_sub(vec3_splat(1.0f), F), m->base_color), (1.0f - mt) * TS_INV_PI);
    return vec3_add(vec3_scale(F, spec), diff);
}

/* Density of the VNDF-sampled reflection: G1(wo) D(h) / (4 wo.z). */
static float spec_pdf(float alpha, vec3 wo, vec3 wi) {
    vec3 h = vec3_add(wo, wi);
    float hl = vec3_length(h);
    if (!(hl > 0.0f)) return 0.0f;
    h = vec3_scale(h, 1.0f / hl);
    float G1 = 1.0f / (1.0f + pbr_smith_lambda(alpha, wo.z));
    return G1 * pbr_ggx_d(alpha, h.z) / (4.0f * wo.z);
}

float bsdf_pbr_pdf(const material *m, vec3 wo, vec3 wi) {
    if (wi.z <= 0.0f || wo.z <= 0.0f) return 0.0f;
    float ps = p_specular(m, wo);
    return ps * spec_pdf(pbr_alpha(m), wo, wi) + (1.0f - ps) * warp_cosine_hemisphere_pdf(wi.z);
}

/* Heitz 2018: a visible normal for wo (upper hemisphere), isotropic alpha. */
static vec3 sample_vndf(float alpha, vec3 wo, float u1, float u2) {
    vec3 vh = vec3_normalize(vec3_make(alpha * wo.x, alpha * wo.y, wo.z));
    float lensq = vh.x * vh.x + vh.y * vh.y;
    vec3 t1 = lensq > 0.0f ? vec3_scale(vec3_make(-vh.y, vh.x, 0.0f), 1.0f / sqrtf(lensq)) : vec3_make(1, 0, 0);
    vec3 t2 = vec3_cross(vh, t1);
    float r = sqrtf(u1), phi = 2.0f * TS_PI * u2;
    float p1 = r * cosf(phi), p2 = r * sinf(phi);
    float s = 0.5f * (1.0f + vh.z);
    p2 = (1.0f - s) * sqrtf(max_f(0.0f, 1.0f - p1 * p1)) + s * p2;
    vec3 nh = vec3_add(vec3_add(vec3_scale(t1, p1), vec3_scale(t2, p2)),
                       vec3_scale(vh, sqrtf(max_f(0.0f, 1.0f - p1 * p1 - p2 * p2))));
    return vec3_normalize(vec3_make(alpha * nh.x, alpha * nh.y, max_f(1e-6f, nh.z)));
}

int bsdf_pbr_sample(const material *m, vec3 wo, float u1, float u2, float u3, bsdf_sample *out) {
    if (wo.z <= 0.0f) return 0;
    vec3 wi;
    if (u3 < p_specular(m, wo)) {
        vec3 h = sample_vndf(pbr_alpha(m), wo, u1, u2);
        /* Made unit: built from wo, it would carry wo's rounding on down a
         * chain of glossy reflections (the integrator does not normalise
         * sampled directions again). */
        wi = vec3_normalize(vec3_sub(vec3_scale(h, 2.0f * vec3_dot(wo, h)), wo));
    } else {
        wi = warp_cosine_hemisphere(u1, u2);
    }
    if (wi.z <= 0.0f) return 0;
    float pdf = bsdf_pbr_pdf(m, wo, wi);
    if (!(pdf > 0.0f) || !isfinite(pdf)) return 0;
    out->wi = wi;
    out->pdf = pdf;
    out->is_delta = 0;
    out->weight = vec3_scale(bsdf_pbr_eval(m, wo, wi), wi.z / pdf);
    return 1;
}
