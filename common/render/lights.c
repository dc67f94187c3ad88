/* lights.c - next-event estimation: pick a light, pick a point, give pdfs. */
#include "lights.h"

#include "intersect.h"
#include "punctual.h"
#include "warp.h"

/* Index i with cdf[i] <= u < cdf[i+1], skipping lights of zero weight. */
static uint32_t pick_light(const scene *s, float u) {
    uint32_t lo = 0, hi = s->light_count; /* invariant: cdf[lo] <= u < cdf[hi] */
    while (hi - lo > 1) {
        uint32_t mid = (lo + hi) / 2;
        if (s->light_cdf[mid] <= u)
            lo = mid;
        else
            hi = mid;
    }
    /* The weight first: it is almost never 0, so the loop's branch is
     * predicted, where lo > 0 is a coin toss with two lights. */
    while (s->lights[lo].select_pdf == 0.0f && lo > 0) lo--;
    return lo;
}

vec3 lights_emitted(const light *l, vec3 n, vec3 w) {
    if (!l->two_sided && vec3_dot(n, w) <= 0.0f) return vec3_splat(0.0f);
    return l->radiance;
}

/* Sphere seen from ref: 1 - cos of the half-angle it subtends, computed
 * without cancellation for distant spheres; 0 when ref is inside. */
static float sphere_cone(const sphere *sp, vec3 ref, float *dc_out) {
    vec3 to_c = vec3_sub(sp->center, ref);
    float dc2 = vec3_dot(to_c, to_c), r2 = sp->radius * sp->radius;
    *dc_out = sqrtf(dc2);
    if (dc2 <= r2) return 0.0f;
    float sin2 = r2 / dc2;
    float cos_max = sqrt_clamped(1.0f - sin2);
    return sin2 / (1.0f + cos_max);
}

static int sample_sphere(const scene *s, const light *l, vec3 ref, float u1, float u2, light_sample *out) {
    const sphere *sp = &s->spheres[l->prim];
    float dc, one_minus_cos = sphere_cone(sp, ref, &dc);
    if (one_minus_cos > 0.0f) {
        vec3 axis = vec3_scale(vec3_sub(sp->center, ref), 1.0f / dc);
        frame f = frame_from_normal(axis);
        vec3 w = frame_to_world(&f, warp_uniform_cone(u1, u2, 1.0f - one_minus_cos));
        /* Distance along w to the near side of the sphere (clamped for rays
         * that graze the silhouette through rounding). */
        float cos_t = vec3_dot(w, axis), sin2_t = max_f(1.0f - cos_t * cos_t, 0.0f);
        float r2 = sp->radius * sp->radius;
        float ds = dc * cos_t - sqrt_clamped(r2 - dc * dc * sin2_t);
        out->wi = w;
        out->dist = ds;
        out->p = vec3_add(ref, vec3_scale(w, ds));
        out->n = vec3_normalize(vec3_sub(out->p, sp->center));
        out->pdf = l->select_pdf / (2.0f * TS_PI * one_minus_cos);
    } else { /* inside: uniform on the whole sphere */
        vec3 n = warp_uniform_sphere(u1, u2);
        out->p = vec3_add(sp->center, vec3_scale(n, sp->radius));
        out->n = n;
        vec3 d = vec3_sub(out->p, ref);
        out->dist = vec3_length(d);
        if (!(out->dist > 0.0f)) return 0;
        out->wi = vec3_scale(d, 1.0f / out->dist);
        float cos_l = fabsf(vec3_dot(n, out->wi));
        if (!(cos_l > 0.0f)) return 0;
        out->pdf = l->select_pdf * out->dist * out->dist / (cos_l * l->area);
    }
    out->radiance = lights_emitted(l, out->n, vec3_neg(out->wi));
    return 1;
}

static int sample_triangle(const scene *s, const light *l, vec3 ref, float u1, float u2, light_sample *out) {
    const triangle *t = &s->triangles[l->prim];
    float b1, b2;
    warp_uniform_triangle(u1, u2, &b1, &b2);
    out->p = vec3_add(vec3_add(vec3_scale(t->v0, 1.0f - b1 - b2), vec3_scale(t->v1, b1)), vec3_scale(t->v2, b2));
    out->n = s->triangle_normals[l->prim];
    vec3 d = vec3_sub(out->p, ref);
    out->dist = vec3_length(d);
    if (!(out->dist > 0.0f)) return 0;
    out->wi = vec3_scale(d, 1.0f / out->dist);
    float cos_l = fabsf(vec3_dot(out->n, out->wi));
    if (!(cos_l > 0.0f)) return 0;
    out->pdf = l->select_pdf * out->dist * out->dist / (cos_l * l->area);
    out->radiance = lights_emitted(l, out->n, vec3_neg(out->wi));
    return 1;
}

int lights_sample(const scene *s, vec3 ref, float u1, float u2, light_sample *out) {
    if (s->light_count == 0) return 0;
    uint32_t i = pick_light(s, u1);
    const light *l = &s->lights[i];
    if (!(l->select_pdf > 0.0f)) return 0;
    float width = s->light_cdf[i + 1] - s->light_cdf[i];
    if (width > 0.0f) u1 = min_f((u1 - s->light_cdf[i]) / width, 0x1.fffffep-1f);
    int ok;
    out->is_delta = 0;
    switch (l->kind) {
    case LIGHT_POINT:
    case LIGHT_SPOT:
    case LIGHT_DIRECTIONAL:
        return punctual_sample(l, ref, out);
    case LIGHT_TRIANGLE:
        ok = sample_triangle(s, l, ref, u1, u2, out);
        out->prim = l->prim;
        break;
    default:
        ok = sample_sphere(s, l, ref, u1, u2, out);
        out->prim = scene_sphere_base(s) + l->prim;
        break;
    }
    return ok && out->pdf > 0.0f && isfinite(out->pdf) && !vec3_is_zero(out->radiance);
}

float lights_pdf(const scene *s, const light *l, vec3 ref, vec3 p, vec3 n, float dist) {
    if (l->kind >= LIGHT_POINT) return 0.0f; /* point, spot, directional: deltas */
    if (l->kind == LIGHT_SPHERE) {
        float dc, one_minus_cos = sphere_cone(&s->spheres[l->prim], ref, &dc);
        if (one_minus_cos > 0.0f) return l->select_pdf / (2.0f * TS_PI * one_minus_cos);
    }
    vec3 w = vec3_scale(vec3_sub(p, ref), 1.0f / dist);
    float cos_l = fabsf(vec3_dot(n, w));
    if (!(cos_l > 0.0f)) return 0.0f;
    return l->select_pdf * dist * dist / (cos_l * l->area);
}
