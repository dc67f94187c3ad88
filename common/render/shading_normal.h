/* shading_normal.h - smooth shading from vertex normals, and the two fixes
 * every renderer that uses them needs.
 *
 * The shading normal ns is the vertex normals interpolated with the hit's
 * barycentrics (Phong normal interpolation). It differs from the geometric
 * normal ng, which causes two artefacts:
 *  - black facets: near a silhouette the viewer can be above the real
 *    surface but below the hemisphere of ns, where every BSDF is zero. Then
 *    the vertex falls back to ng (shading_normal_oriented);
 *  - light leaks: a direction above the ns hemisphere can be below the
 *    surface (or the reverse for transmission). Such directions are refused
 *    (shading_sides_agree): the path ends, the light sample counts nothing.
 * Both only remove energy, never add it: a white furnace stays at or below
 * the albedo (tests/test_meshes.c). Radiance (camera-path) transport needs no
 * adjoint correction: f(wo, wi) |wi . ns| is the estimator.
 * Surfaces without vertex normals never reach these functions, so their
 * pictures are unchanged bit for bit. */
#ifndef TESSERA_SHADING_NORMAL_H
#define TESSERA_SHADING_NORMAL_H

#include "scene.h"
#include "vec.h"

/* Ask for the line of triangle prim's vertex-normal indices, which
 * shading_normal_at will read if prim turns out to be the hit: the wide
 * walk calls it on each new closest candidate, so that the index is in
 * cache when the walk ends and only the normals' own load waits (the two
 * were loads in series after the walk). ico7 with normals made from faces
 * (perf, one thread, 128x128x64): the index's load 14.5% of the
 * integrator's samples before, 8.5% after, the integrator 17.9% -> 16.2%
 * of all; bench/pair.sh render CPU 0.925, 0.965, 1.012, 1.002 (10, 10, 10
 * and 16 rounds): about 1%, within this host's noise. No effect on
 * results. */
static inline void shading_normal_prefetch(const scene *s, uint32_t prim) {
    if (s->triangle_vertex_normals) __builtin_prefetch(s->triangle_vertex_normals + 3 * (size_t)prim);
}

/* Shading normal of triangle prim at barycentrics (b0, b1, b2) into *ns, and
 * *ng turned to the side the vertex normals point to (their side wins over
 * the winding, as in pbrt). Returns 1, or 0 (leaving both alone) when the
 * triangle has no vertex normals or they cancel out. */
static inline int shading_normal_at(const scene *s, uint32_t prim, float b0, float b1, float b2, vec3 *ng,
                                    vec3 *ns) {
    if (!s->triangle_vertex_normals) return 0;
    const uint32_t *idx = s->triangle_vertex_normals + 3 * (size_t)prim;
    if (idx[0] == SCENE_NONE) return 0;
    vec3 n = vec3_add(vec3_add(vec3_scale(s->vertex_normals[idx[0]], b0), vec3_scale(s->vertex_normals[idx[1]], b1)),
                      vec3_scale(s->vertex_normals[idx[2]], b2));
    float len = vec3_length(n);
    if (!(len > 1e-6f) || !isfinite(len)) return 0;
    *ns = vec3_scale(n, 1.0f / len);
    if (vec3_dot(*ns, *ng) < 0.0f) *ng = vec3_neg(*ng);
    return 1;
}

/* The normal to shade with, given n, the geometric normal as the caller
 * oriented it (towards wo for opaque materials): ns turned to n's side, or n
 * itself where wo is not on the same side of both (a black facet avoided). */
static inline vec3 shading_normal_oriented(vec3 ng, vec3 ns, vec3 n, vec3 wo) {
    vec3 s = vec3_dot(n, ng) < 0.0f ? vec3_neg(ns) : ns;
    float ds = vec3_dot(wo, s), dn = vec3_dot(wo, n);
    return ds != 0.0f && (ds > 0.0f) == (dn > 0.0f) ? s : n;
}

/* Whether wo and wi are on the same side of the shading normal n exactly
 * when they are on the same side of the surface (ng): reflection stays
 * reflection and transmission transmission. */
static inline int shading_sides_agree(vec3 ng, vec3 n, vec3 wo, vec3 wi) {
    int geo_same = (vec3_dot(wi, ng) > 0.0f) == (vec3_dot(wo, ng) > 0.0f);
    int shade_same = (vec3_dot(wi, n) > 0.0f) == (vec3_dot(wo, n) > 0.0f);
    return geo_same == shade_same;
}

#endif
