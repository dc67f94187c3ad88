/* bsdf.c - Lambert, normalised Phong, ideal mirror, smooth dielectric.
 *
 * Normalised (modified) Phong, after Lafortune and Willems 1994:
 *   f(wo, wi) = kd / pi + ks (n + 2) / (2 pi) cos^n(alpha),
 * alpha the angle between wi and the mirror direction of wo. With
 * kd + ks <= 1 (checked at load) its albedo is at most 1 for every wo. It is
 * sampled as a mixture: the specular lobe (density (n + 1)/(2 pi) cos^n alpha)
 * with probability p_specular, the cosine hemisphere otherwise. */
#include "bsdf.h"

#include "bsdf_pbr.h"
#include "warp.h"

static inline vec3 reflect_local(vec3 wo) { return vec3_make(-wo.x, -wo.y, wo.z); }

/* A sampled mirror direction, made unit: the integrator does not normalise
 * sampled directions again, and a reflection built from wo would carry
 * wo's rounding on from bounce to bounce down a chain of mirrors
 * (bsdf_path_directions_stay_unit_without_renormalising). */
static inline vec3 reflect_unit(vec3 wo) { return vec3_normalize(reflect_local(wo)); }

static float phong_cos_alpha(vec3 wo, vec3 wi) { return vec3_dot(reflect_local(wo), wi); }

/* f(wo, wi) and, into *pdf, the density bsdf_sample_wi gives wi, for a
 * material of the given kind (a constant where this is inlined, so that
 * only that kind's code remains). The Phong lobe's powf serves both: f's
 * lobe is ks (n + 2) / (2 pi) cos^n and the density's (n + 1) / (2 pi)
 * cos^n, with the same cos^n. */
static inline __attribute__((always_inline)) vec3 eval_pdf(material_kind kind, const material *m, vec3 wo, vec3 wi,
                                                           float *pdf) {
    *pdf = 0.0f;
    if (wi.z <= 0.0f || wo.z <= 0.0f) return vec3_splat(0.0f);
    switch (kind) {
    case MATERIAL_DIFFUSE:
        *pdf = warp_cosine_hemisphere_pdf(wi.z);
        return vec3_scale(m->kd, TS_INV_PI);
    case MATERIAL_GLOSSY: {
        float ca = phong_cos_alpha(wo, wi), pw = ca > 0.0f ? powf(ca, m->exponent) : 0.0f;
        float lobe = ca > 0.0f ? (m->exponent + 2.0f) * (0.5f * TS_INV_PI) * pw : 0.0f;
        float lobe_pdf = ca > 0.0f ? (m->exponent + 1.0f) * (0.5f * TS_INV_PI) * pw : 0.0f;
        *pdf = (1.0f - m->p_specular) * warp_cosine_hemisphere_pdf(wi.z) + m->p_specular * lobe_pdf;
        return vec3_add(vec3_scale(m->kd, TS_INV_PI), vec3_scale(m->ks, lobe));
    }
    case MATERIAL_PBR:
        *pdf = bsdf_pbr_pdf(m, wo, wi);
        return bsdf_pbr_eval(m, wo, wi);
    default:
        return vec3_splat(0.0f);
    }
}

vec3 bsdf_eval(const material *m, vec3 wo, vec3 wi) {
    if (m->kind == MATERIAL_PBR) return wi.z <= 0.0f || wo.z <= 0.0f ? vec3_splat(0.0f) : bsdf_pbr_eval(m, wo, wi);
    float pdf;
    return eval_pdf(m->kind, m, wo, wi, &pdf);
}

float bsdf_pdf(const material *m, vec3 wo, vec3 wi) {
    if (m->kind == MATERIAL_PBR) return wi.z <= 0.0f || wo.z <= 0.0f ? 0.0f : bsdf_pbr_pdf(m, wo, wi);
    float pdf;
    eval_pdf(m->kind, m, wo, wi, &pdf);
    return pdf;
}

vec3 bsdf_eval_pdf(const material *m, vec3 wo, vec3 wi, float *pdf) { return eval_pdf(m->kind, m, wo, wi, pdf); }

float bsdf_fresnel_dielectric(float cos_i, float eta) {
    if (cos_i < 0.0f) { /* inside: swap the media */
        eta = 1.0f / eta;
        cos_i = -cos_i;
    }
    float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    if (sin2_t >= 1.0f) return 1.0f;
    float cos_t = sqrtf(1.0f - sin2_t);
    float rs = (cos_i - eta * cos_t) / (cos_i + eta * cos_t);
    float rp = (eta * cos_i - cos_t) / (eta * cos_i + cos_t);
    return 0.5f * (rs * rs + rp * rp);
}

/* Smooth dielectric: reflect with probability F, refract otherwise; the
 * estimator's weight is then 1 (reflection) or kt (eta_i/eta_t)^2. */
static int sample_glass(const material *m, vec3 wo, float u, bsdf_sample *out) {
    float F = bsdf_fresnel_dielectric(wo.z, m->ior);
    out->pdf = 0.0f;
    out->is_delta = 1;
    if (u < F) {
        out->wi = reflect_unit(wo);
        out->weight = vec3_splat(1.0f);
        return 1;
    }
    int entering = wo.z > 0.0f;
    float eta = entering ? m->ior : 1.0f / m->ior; /* eta_t / eta_i */
    float cos_i = fabsf(wo.z); /* sin_i^2 = 1 - cos_i^2 */
    float sin2_t = (1.0f - cos_i * cos_i) / (eta * eta);
    float cos_t = sqrt_clamped(1.0f - sin2_t);
    float inv_eta = 1.0f / eta;
    /* Snell: the tangential part scales by 1/eta and flips; the normal part
     * is cos_t on the far side of the interface. */
    vec3 wi = vec3_make(-wo.x * inv_eta, -wo.y * inv_eta, entering ? -cos_t : cos_t);
    out->wi = vec3_normalize(wi);
    out->weight = vec3_scale(m->kt, inv_eta * inv_eta);
    out->eta = eta;
    return 1;
}

/* Lambert or Phong (kind, a constant where inlined): the lobe by u3, the
 * direction by (u1, u2), f and the density once each. */
static inline __attribute__((always_inline)) int sample_lambert_phong(material_kind kind, const material *m, vec3 wo,
                                                                      float u1, float u2, float u3,
                                                                      bsdf_sample *out) {
    if (wo.z <= 0.0f) return 0;
    vec3 wi;
    if (u3 < m->p_specular) {
        frame lobe = frame_from_normal(reflect_local(wo));
        wi = frame_to_world(&lobe, warp_power_cosine(u1, u2, m->exponent));
    } else {
        wi = warp_cosine_hemisphere(u1, u2);
    }
    float pdf;
    vec3 f = eval_pdf(kind, m, wo, wi, &pdf);
    if (!(pdf > 0.0f)) return 0;
    out->wi = wi;
    out->pdf = pdf;
    out->is_delta = 0;
    /* Lambert: f cos / pdf = (kd / pi) cos / (cos / pi) = kd, without the
     * division and its rounding. */
    out->weight = kind == MATERIAL_DIFFUSE ? m->kd : vec3_scale(f, wi.z / pdf);
    return 1;
}

int bsdf_sample_wi(const material *m, vec3 wo, float u1, float u2, float u3, bsdf_sample *out) {
    out->eta = 1.0f;
    switch (m->kind) {
    case MATERIAL_DIFFUSE:
        return sample_lambert_phong(MATERIAL_DIFFUSE, m, wo, u1, u2, u3, out);
    case MATERIAL_GLOSSY:
        return sample_lambert_phong(MATERIAL_GLOSSY, m, wo, u1, u2, u3, out);
    case MATERIAL_MIRROR:
        if (wo.z <= 0.0f) return 0;
        out->wi = reflect_unit(wo);
        out->pdf = 0.0f;
        out->is_delta = 1;
        out->weight = m->ks;
        return 1;
    case MATERIAL_GLASS:
        return sample_glass(m, wo, u3, out);
    case MATERIAL_PBR:
        return bsdf_pbr_sample(m, wo, u1, u2, u3, out);
    default:
        return 0;
    }
}
