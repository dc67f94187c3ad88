/* punctual.c - point, spot and directional lights (see punctual.h). */
#include "punctual.h"

#include "intersect.h"

int punctual_sample(const light *l, vec3 ref, light_sample *out) {
    out->is_delta = 1;
    out->prim = PRIM_NONE;
    out->pdf = l->select_pdf;
    if (l->kind == LIGHT_DIRECTIONAL) {
        out->wi = vec3_neg(l->direction);
        out->dist = PUNCTUAL_FAR;
        out->p = vec3_add(ref, vec3_scale(out->wi, PUNCTUAL_FAR));
        out->n = l->direction;
        out->radiance = l->intensity;
        return !vec3_is_zero(out->radiance);
    }
    vec3 d = vec3_sub(l->position, ref);
    out->dist = vec3_length(d);
    if (!(out->dist > 0.0f)) return 0;
    out->wi = vec3_scale(d, 1.0f / out->dist);
    out->p = l->position;
    out->n = vec3_neg(out->wi);
    if (l->kind == LIGHT_POINT) { /* I / d^2 in every direction */
        out->radiance = vec3_scale(l->intensity, 1.0f / (out->dist * out->dist));
        return 1;
    }
    float cd = -vec3_dot(out->wi, l->direction); /* cosine from the spot's axis */
    float span = max_f(l->cos_inner - l->cos_outer, 1e-4f);
    float a = min_f(max_f((cd - l->cos_outer) / span, 0.0f), 1.0f);
    out->radiance = vec3_scale(l->intensity, a * a / (out->dist * out->dist));
    return !vec3_is_zero(out->radiance);
}
