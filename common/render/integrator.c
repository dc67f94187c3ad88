/* integrator.c - unidirectional path tracing with NEE and MIS.
 *
 * The estimator, for a path x0 (camera) x1 x2 ...:
 *   L = sum over vertices k of beta_k [ w_bsdf Le(x_k)            (hit)
 *                                      + w_light f Le cos / p_l ]  (NEE)
 * where beta_k is the product of f cos / p over the earlier bounces and the
 * weights are the power heuristic between the two densities that could have
 * produced the same emitter point. Delta vertices (mirror, glass) and point
 * lights take weight 1, as only one strategy can reach them. */
#include "integrator.h"

#include <string.h>

#include "bsdf.h"
#include "accel.h"
#include "lights.h"
#include "offset.h"
#include "shading.h"
#include "shading_normal.h"
#include "warp.h"

/* Where each random decision of a bounce lives, relative to the bounce's
 * first dimension. Numbers that are used together sit in one pair of
 * dimensions (an even offset and the next), which the Sobol sampler
 * stratifies jointly. */
enum {
    DIM_LIGHT_POINT = 0, /* and 1: the point on the light */
    DIM_BSDF_DIR = 2,    /* and 3: the BSDF's direction */
    DIM_LOBE = 4,        /* which BSDF lobe */
    DIM_ROULETTE = 5     /* Russian roulette */
};

/* Geometry at a hit: precise position and unit geometric normal (front face
 * for triangles by winding order, outward for spheres; with vertex normals,
 * the side they point to), and the shading normal ns: the vertex normals
 * interpolated (shading_normal.h), else ng. */
typedef struct {
    vec3 p, ng, ns;
    int smooth; /* ns comes from vertex normals, or a normal map bent it: the leak guard applies */
    prim_info info;
} surface;

static void surface_at(const scene *s, const ray *r, const hit *h, surface *out) {
    if (h->prim < s->triangle_count) {
        vec3 v0, v1, v2;
        hit_corners(s, h, &v0, &v1, &v2);
        float b0 = 1.0f - h->b1 - h->b2;
        /* From the barycentrics, not o + t d: the error is then relative to
         * the triangle's coordinates, not to the ray's length. */
        out->p = vec3_add(vec3_add(vec3_scale(v0, b0), vec3_scale(v1, h->b1)), vec3_scale(v2, h->b2));
        /* Recomputed from corners the walk has just read rather than
         * fetched: scene.triangle_normals' bits without its cache miss. */
        out->ng = h->corners ? triangle_geometric_normal(v0, v1, v2) : s->triangle_normals[h->prim];
        out->info = scene_triangle_info(s, h->prim);
        out->ns = out->ng;
        out->smooth = shading_normal_at(s, h->prim, b0, h->b1, h->b2, &out->ng, &out->ns);
    } else {
        uint32_t i = h->prim - s->triangle_count;
        const sphere *sp = &s->spheres[i];
        vec3 p = vec3_add(r->o, vec3_scale(r->d, h->t));
        out->ng = vec3_normalize(vec3_sub(p, sp->center));
        out->p = vec3_add(sp->center, vec3_scale(out->ng, sp->radius)); /* back onto the surface */
        out->info = s->sphere_info[i];
        out->ns = out->ng;
        out->smooth = 0;
    }
}

/* A ray leaving surface point p of primitive prim in direction d. Always
 * inlined: as a call, its vec3 arguments and the ray it returns went through
 * the stack in pieces that the loads could not forward from (a store-forwarding
 * stall per bounce, the hottest instructions of the box's profile). */
static inline __attribute__((always_inline)) ray spawn(vec3 p, vec3 ng, uint32_t prim, vec3 d) {
    ray r;
    r.o = offset_ray_origin(p, vec3_dot(d, ng) > 0.0f ? ng : vec3_neg(ng));
    r.d = d;
    r.skip = prim;
    return r;
}

/* A shadow ray waiting to be traced, and what its vertex adds to L:
 * beta * (visible ? f Le cos w / p : 0), as the product the vertex made. */
typedef struct {
    ray r;
    float len;
    vec3 beta, value;
} shadow_query;

/* Light sampling at a non-delta vertex, with (u1, u2) for the point on the
 * light: the direct-light term with its MIS weight. wo and the frame are in
 * world / local space as the caller has them. Returns 1 with the shadow ray
 * still to trace in *q (q->value is the term if it turns out unoccluded;
 * the caller sets q->beta), or 0 with the term, already final (zero), in
 * *value. Cut-out scenes' shadow rays are traced here, through the
 * cut-outs (shading_occluded). */
static int direct_light(const scene *s, const integrator_options *opt, const material *m, const surface *sf,
                        uint32_t prim, const frame *fr, vec3 wo, vec3 wo_local, float u1, float u2, trace_stats *st,
                        shadow_query *q, vec3 *value) {
    *value = vec3_splat(0.0f);
    light_sample ls;
    if (!lights_sample(s, sf->p, u1, u2, &ls)) return 0;
    vec3 wi_local = frame_to_local(fr, ls.wi);
    if (sf->smooth && !shading_sides_agree(sf->ng, fr->n, wo, ls.wi)) return 0; /* no leaks */
    float bsdf_density;
    vec3 f = bsdf_eval_pdf(m, wo_local, wi_local, &bsdf_density);
    if (vec3_is_zero(f)) return 0;
    /* Shadow ray between the two offset end points, so it neither starts
     * inside this surface nor ends inside the light's. */
    ray sh = spawn(sf->p, sf->ng, prim, ls.wi);
    vec3 target = ls.p;
    if (!ls.is_delta) target = offset_ray_origin(ls.p, vec3_dot(ls.n, ls.wi) < 0.0f ? ls.n : vec3_neg(ls.n));
    vec3 to = vec3_sub(target, sh.o);
    float len = vec3_length(to);
    if (!(len > 0.0f)) return 0;
    sh.d = vec3_scale(to, 1.0f / len);
    st->shadow_rays++;
    float w = (ls.is_delta || opt->no_mis) ? 1.0f : mis_power(ls.pdf, bsdf_density);
    vec3 term = vec3_scale(vec3_mul(f, ls.radiance), fabsf(wi_local.z) * w / ls.pdf);
    if (s->features & FEATURE_CUTOUT) {
        if (!shading_occluded(s, &sh, len)) *value = term;
        return 0;
    }
    q->r = sh;
    q->len = len;
    q->value = term;
    return 1;
}

/* What a traced shadow query adds to L. */
static inline vec3 shadow_term(const shadow_query *q, int occluded) {
    return vec3_mul(q->beta, occluded ? vec3_splat(0.0f) : q->value);
}

/* What a shadow query adds to L, traced on its own. */
static vec3 shadow_term_alone(const scene *s, const shadow_query *q) {
    return shadow_term(q, accel_occluded(s->accel, s, &q->r, q->len));
}

/* Emission picked up by a ray that hit an emitter after a bounce from
 * prev_p with BSDF density prev_pdf (0 = delta or camera). */
static vec3 hit_emission(const scene *s, const integrator_options *opt, const surface *sf, const ray *r,
                         float t, vec3 prev_p, float prev_pdf) {
    const light *l = &s->lights[sf->info.light];
    vec3 Le = lights_emitted(l, sf->ng, vec3_neg(r->d));
    if (vec3_is_zero(Le) || prev_pdf == 0.0f || opt->no_nee) return Le;
    if (opt->no_mis) return vec3_splat(0.0f); /* light sampling already counted it */
    float light_pdf = lights_pdf(s, l, prev_p, sf->p, sf->ng, t);
    return vec3_scale(Le, mis_power(prev_pdf, light_pdf));
}

vec3 integrator_radiance(const scene *s, const integrator_options *opt, const ray *camera_ray, const sampler_stream *rng,
                         trace_stats *st) {
    vec3 L = vec3_splat(0.0f), beta = vec3_splat(1.0f), prev_p = camera_ray->o;
    float prev_pdf = 0.0f; /* the camera ray counts as a delta event */
    ray r = *camera_ray;
    /* What the scene does not have costs nothing: no light to sample, no sky
     * to add. (Material kinds and area-light MIS cost nothing unused: they
     * are reached only through primitives that have them.) */
    int has_lights = (s->features & (FEATURE_AREA_LIGHTS | FEATURE_POINT_LIGHTS)) != 0;
    const int roulette_depth = s->settings.roulette_depth; /* the first vertex that may roll */
    int passes = 0; /* cut-out surfaces passed through (render/shading.h) */
    /* The product of eta^2 over the refractions so far: beta * eta_scale is
     * the throughput without the radiance scaling (eta_i / eta_t)^2 of
     * refraction, which a path inside glass undoes when it leaves. */
    float eta_scale = 1.0f;
    /* A vertex's shadow ray is traced with the next vertex's ray, the two
     * walks interleaved (accel_intersect_occluded); its term is added to L
     * before anything of the next vertex, as if traced at once. */
    shadow_query shadow;
    int pending = 0;
    /* A vertex's numbers (its light point, direction, lobe and roulette:
     * sampler_get_bounce's three pairs) do not depend on its hit, so they
     * are drawn one vertex ahead, while the vertex before is shaded (below,
     * after its BSDF sample). Their chain of eight dependent multiplications
     * then overlaps the shading instead of sitting in front of the next
     * walk, where nothing behind it could retire until it was done
     * (2026-11-28, paired runs, one thread per core, 128x128x64, median of
     * 6: render CPU -7.5% on the box, -5.6% on the spheres, -1.2% on ico7,
     * +1% on ico5). The same numbers for the same dimensions: the bytes do
     * not change. */
    float u_next[8];
    sampler_get_bounce(rng, INTEGRATOR_CAMERA_DIMS, u_next);
    for (int depth = 0;; depth++) {
        uint32_t dim = INTEGRATOR_CAMERA_DIMS + (uint32_t)depth * INTEGRATOR_DIMS_PER_BOUNCE;
        float u[8];
        memcpy(u, u_next, sizeof u);
        float u_lobe = u[DIM_LOBE], u_roulette = u[DIM_ROULETTE], u1 = u[DIM_BSDF_DIR], u2 = u[DIM_BSDF_DIR + 1];
        hit h;
        st->rays++;
        int found;
        if (pending) { /* the last vertex's shadow ray and this ray, traced side by side */
            int occluded;
            found = accel_intersect_occluded(s->accel, s, &r, INFINITY, &h, &shadow.r, shadow.len, &occluded);
            L = vec3_add(L, shadow_term(&shadow, occluded));
            pending = 0;
        } else {
            found = accel_intersect(s->accel, s, &r, INFINITY, &h);
        }
        if (!found) {
            if (s->features & FEATURE_BACKGROUND) L = vec3_add(L, vec3_mul(beta, s->background));
            break;
        }
        surface sf;
        surface_at(s, &r, &h, &sf);
        if (sf.info.light >= 0)
            L = vec3_add(L, vec3_mul(beta, hit_emission(s, opt, &sf, &r, h.t, prev_p, prev_pdf)));
        const material *m = &s->materials[sf.info.material];
        if (depth >= s->settings.max_depth || m->kind == MATERIAL_NONE) break;

        vec3 wo = vec3_neg(r.d);
        /* Opaque materials reflect on whichever side the ray arrived. */
        vec3 n = (m->kind != MATERIAL_GLASS && vec3_dot(sf.ng, wo) < 0.0f) ? vec3_neg(sf.ng) : sf.ng;
        if (sf.smooth) n = shading_normal_oriented(sf.ng, sf.ns, n, wo);
        material m_hit;
        if (s->corner_uvs && h.prim < s->triangle_count) { /* imported: textures, normal map, cutout */
            /* Into a copy: were n's address taken, n would live on the
             * stack for every bounce and be reloaded by halves that
             * straddle its stores (a store-forwarding stall). */
            vec3 n_resolved = n;
            m = shading_resolve(s, &h, m, n, wo, &m_hit, &n_resolved, &sf.smooth);
            if (!m) {
                if (++passes > 64) break;
                r = spawn(sf.p, sf.ng, h.prim, r.d);
                depth--;
                continue;
            }
            n = n_resolved;
        }
        frame fr = frame_from_normal(n);
        vec3 wo_local = frame_to_local(&fr, wo);
        /* The BSDF's direction before the light sample, which does not
         * depend on it: the direction is a chain of divisions, square roots
         * and a sincos that the next ray waits for, and the CPU completes
         * it while it works on the light sample and its shadow ray, instead
         * of after them. The sums are the same, in the same order. */
        bsdf_sample bs;
        /* The direction from the pair DIM_BSDF_DIR, stratified jointly; the
         * lobe (or glass's reflect-or-refract) from u_lobe. (Until
         * 2026-11-26 the direction took (u_lobe, u1) and the lobe u2, so its
         * two numbers came from different pairs: box relMSE at 64 spp 5%
         * higher, docs/performance.md.) */
        int scattered = bsdf_sample_wi(m, wo_local, u1, u2, u_lobe, &bs);
        if (scattered) sampler_get_bounce(rng, dim + INTEGRATOR_DIMS_PER_BOUNCE, u_next);
        /* Not normalised again: the frame is orthonormal and bs.wi unit, so
         * wi is unit within 1e-6 even 64 bounces down a chain of mirrors
         * (bsdf_path_directions_stay_unit_without_renormalising; the
         * mirror, glass and glossy PBR reflections normalise their own
         * direction for it), and a square root and a division fewer stand
         * between this vertex and the next walk (2026-11-29, paired runs,
         * one thread per core, 128x128x64: ico5 0.976 and 0.957, ico6 0.941,
         * the spheres 0.940, the box 0.981, ico7 1.004). */
        vec3 wi = scattered ? frame_to_world(&fr, bs.wi) : wo;
        if (has_lights && bsdf_is_smooth(m) && !opt->no_nee) {
            vec3 value;
            pending = direct_light(s, opt, m, &sf, h.prim, &fr, wo, wo_local, u[DIM_LIGHT_POINT],
                                   u[DIM_LIGHT_POINT + 1], st, &shadow, &value);
            if (!pending) {
                L = vec3_add(L, vec3_mul(beta, value));
            } else {
                shadow.beta = beta;
                if (opt->no_pair) L = vec3_add(L, shadow_term_alone(s, &shadow)), pending = 0;
            }
        }
        if (!scattered) break;
        if (sf.smooth && !shading_sides_agree(sf.ng, n, wo, wi)) break; /* would leak through the surface */
        beta = vec3_mul(beta, bs.weight);
        prev_pdf = bs.pdf;
        prev_p = sf.p;
        /* Russian roulette: continue with probability min(1, sqrt(max
         * component of beta)), Cycles' rule (the sqrt keeps paths of
         * moderate weight alive longer), where beta leaves out the
         * refraction's (eta_i / eta_t)^2 (pbrt-v4's etaScale: a path inside
         * glass is not dimmer, its radiance is only scaled until it leaves).
         * Never right after a delta bounce (mirror, glass): it hardly lowers
         * the weight, so the roll would only repeat the decision of the last
         * rough vertex, against the caustic paths that carry the largest
         * weights (a path of delta bounces alone, between mirrors, runs to
         * max_depth). From vertex render.roulette_depth on (by default the
         * fifth: SCENE_ROULETTE_DEPTH_DEFAULT). Measured in
         * docs/performance.md (issue 15): on the spheres 33% less variance
         * from the delta rule, then 10% less (box 9%) from the fifth vertex
         * than from the fourth for 9% more rays. */
        eta_scale *= bs.eta * bs.eta;
        if (depth >= roulette_depth && !bs.is_delta) {
            float survive = min_f(1.0f, sqrtf(vec3_max_comp(beta) * eta_scale));
            if (!(u_roulette < survive)) break;
            beta = vec3_scale(beta, 1.0f / survive);
        }
        r = spawn(sf.p, sf.ng, h.prim, wi);
    }
    if (pending) L = vec3_add(L, shadow_term_alone(s, &shadow)); /* the path ended after a light sample */
    st->samples++;
    if (!vec3_is_finite(L) || L.x < 0.0f || L.y < 0.0f || L.z < 0.0f) {
        st->bad_samples++;
        return vec3_splat(0.0f);
    }
    return L;
}
