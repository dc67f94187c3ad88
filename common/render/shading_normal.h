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

/* Triangle prim's three corner normals (scene.h), or NULL when it is
 * outside the scene's range of triangles that may have them. */
static inline const vec3 *shading_corner_normals(const scene *s, uint32_t prim) {
    uint32_t k = prim - s->corner_normals_first; /* wraps below the range */
    return s->corner_normals && k < s->corner_normal_tris ? s->corner_normals + 3 * (size_t)k : NULL;
}

/* Ask for the lines of triangle prim's corner normals, which
 * shading_normal_at will read if prim turns out to be the hit: the wide
 * walk calls it on each new closest candidate, so that they are in cache
 * when the walk ends. Until the twenty-ninth session the normals were
 * indexed: the walk could only ask for the index's line, and the
 * normals' load waited for it after the walk. No effect on results. */
static inline void shading_normal_prefetch(const scene *s, uint32_t prim) {
    const vec3 *c = shading_corner_normals(s, prim);
    if (c) {
        __builtin_prefetch(c);
        __builtin_prefetch((const char *)c + 3 * sizeof *c - 1);
    }
}

/* Shading normal of triangle prim at barycentrics (b0, b1, b2) into *ns, and
 * *ng turned to the side the vertex normals point to (their side wins over
 * the winding, as in pbrt). Returns 1, or 0 (leaving both alone) when the
 * triangle has no vertex normals (zero corners) or they cancel out. */
static inline int shading_normal_at(const scene *s, uint32_t prim, float b0, float b1, float b2, vec3 *ng,
                                    vec3 *ns) {
    const vec3 *c = shading_corner_normals(s, prim);
    if (!c) return 0;
    vec3 n = vec3_add(vec3_add(vec3_scale(c[0], b0), vec3_scale(c[1], b1)), vec3_scale(c[2], b2));
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
