/* shading.c - textures, normal maps and cutouts at hits on imported
 * triangles (see shading.h). */
#include "shading.h"

#include "accel.h"
#include "offset.h"
#include "texture.h"

static void corner_uv(const scene *s, const hit *h, const material *m, float *u, float *v) {
    const float *c = &s->corner_uvs[6 * (size_t)h->prim];
    float b0 = 1.0f - h->b1 - h->b2;
    *u = b0 * c[0] + h->b1 * c[2] + h->b2 * c[4];
    *v = b0 * c[1] + h->b1 * c[3] + h->b2 * c[5];
    if (m->has_uv_xform) {
        const float *x = m->uv_xform;
        float uu = x[0] * *u + x[1] * *v + x[2], vv = x[3] * *u + x[4] * *v + x[5];
        *u = uu;
        *v = vv;
    }
}

static const texture *tex(const scene *s, uint32_t slot) {
    return slot && slot <= s->texture_count ? &s->textures[slot - 1] : NULL;
}

int shading_cut_out(const scene *s, uint32_t prim, float b1, float b2) {
    if (prim >= s->triangle_count || !s->corner_uvs) return 0;
    const material *m = &s->materials[s->triangle_info[prim].material];
    if (!(m->alpha_cutoff > 0.0f)) return 0;
    hit h = {0.0f, prim, b1, b2, NULL, 0};
    float u, v, a = m->base_alpha;
    corner_uv(s, &h, m, &u, &v);
    const texture *t = tex(s, m->tex_base);
    if (t) a *= texture_lookup(t, u, v).a;
    return a < m->alpha_cutoff;
}

/* Tangent frame of the normal map from the triangle's uv parametrisation:
 * T = dP/du, B = -dP/dv (glTF's v runs down the image, the map's +Y up). */
static vec3 normal_mapped(const scene *s, const hit *h, vec3 nsm, vec3 texn, float scale) {
    const triangle *tr = &s->triangles[h->prim];
    const float *c = &s->corner_uvs[6 * (size_t)h->prim];
    vec3 dp1 = vec3_sub(tr->v1, tr->v0), dp2 = vec3_sub(tr->v2, tr->v0);
    float du1 = c[2] - c[0], dv1 = c[3] - c[1], du2 = c[4] - c[0], dv2 = c[5] - c[1];
    float det = du1 * dv2 - du2 * dv1;
    if (!(fabsf(det) > 1e-20f)) return nsm;
    float inv = 1.0f / det;
    vec3 T = vec3_scale(vec3_sub(vec3_scale(dp1, dv2), vec3_scale(dp2, dv1)), inv);
    vec3 Bv = vec3_scale(vec3_sub(vec3_scale(dp2, du1), vec3_scale(dp1, du2)), inv); /* dP/dv */
    T = vec3_sub(T, vec3_scale(nsm, vec3_dot(nsm, T)));
    float tl = vec3_length(T);
    if (!(tl > 0.0f)) return nsm;
    T = vec3_scale(T, 1.0f / tl);
    vec3 B = vec3_cross(nsm, T);
    if (vec3_dot(B, Bv) > 0.0f) B = vec3_neg(B); /* B along -dP/dv */
    float x = (2.0f * texn.x - 1.0f) * scale, y = (2.0f * texn.y - 1.0f) * scale, z = 2.0f * texn.z - 1.0f;
    vec3 n = vec3_add(vec3_add(vec3_scale(T, x), vec3_scale(B, y)), vec3_scale(nsm, z));
    float nl = vec3_length(n);
    return nl > 0.0f && isfinite(nl) ? vec3_scale(n, 1.0f / nl) : nsm;
}

const material *shading_resolve(const scene *s, const hit *h, const material *m, vec3 n, vec3 wo,
                                 material *scratch, vec3 *ns, int *bent) {
    *ns = n;
    if (h->prim >= s->triangle_count) return m;
    int textured = m->tex_base || m->tex_mr || m->tex_normal;
    if (textured || m->alpha_cutoff > 0.0f) {
        *scratch = *m;
        float u, v, alpha = m->base_alpha;
        corner_uv(s, h, m, &u, &v);
        const texture *t;
        if ((t = tex(s, m->tex_base))) {
            texel c = texture_lookup(t, u, v);
            scratch->base_color = vec3_mul(scratch->base_color, c.rgb);
            scratch->kd = vec3_mul(scratch->kd, c.rgb);
            alpha *= c.a;
        }
        if (m->alpha_cutoff > 0.0f && alpha < m->alpha_cutoff) return NULL;
        if ((t = tex(s, m->tex_mr))) {
            texel c = texture_lookup(t, u, v);
            scratch->roughness *= c.rgb.y;
            scratch->metallic *= c.rgb.z;
        }
        if ((t = tex(s, m->tex_normal)) && m->kind != MATERIAL_GLASS) {
            vec3 sn = normal_mapped(s, h, n, texture_lookup(t, u, v).rgb, m->normal_scale);
            if (vec3_dot(sn, wo) > 0.0f) { /* else a black facet: keep n */
                *ns = sn;
                *bent = 1;
            }
        }
        m = scratch;
    }
    return m;
}

int shading_occluded(const scene *s, const ray *r, float tmax) {
    ray cur = *r;
    for (int pass = 0; pass < 64; pass++) {
        hit h;
        if (!accel_intersect(s->accel, s, &cur, tmax, &h)) return 0;
        if (!shading_cut_out(s, h.prim, h.b1, h.b2)) return 1;
        const triangle *t = &s->triangles[h.prim];
        float b0 = 1.0f - h.b1 - h.b2;
        vec3 p = vec3_add(vec3_add(vec3_scale(t->v0, b0), vec3_scale(t->v1, h.b1)), vec3_scale(t->v2, h.b2));
        vec3 ng = s->triangle_normals[h.prim];
        vec3 o = offset_ray_origin(p, vec3_dot(cur.d, ng) > 0.0f ? ng : vec3_neg(ng));
        tmax -= vec3_length(vec3_sub(o, cur.o));
        if (!(tmax > 0.0f)) return 0;
        cur.o = o;
        cur.skip = h.prim;
    }
    return 1;
}
